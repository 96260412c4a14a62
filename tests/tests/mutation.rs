//! Mutation campaigns over the files a user hands motile (docs/faults.md): a short seeded
//! campaign over every reader family, and each defect an earlier campaign found, rebuilt by
//! hand, refused with a message naming the file.

use hdf5_pure::AttrValue;
use motile_experiments::campaign::mutation::mutate::Content;
use motile_experiments::campaign::mutation::readers::{self, Seeds, Verdict};
use motile_experiments::campaign::mutation::{CampaignOptions, Family, Outcome, run_campaign};
use std::time::Duration;

#[test]
fn short_campaign_finds_no_panic_hang_or_inconsistent_acceptance() {
    let dir = tempfile::tempdir().unwrap();
    let opts = CampaignOptions {
        seed: 11,
        per_family: 60,
        time_limit: Duration::from_secs(60),
        families: Family::ALL.to_vec(),
        scratch: dir.path().to_path_buf(),
    };
    let report = run_campaign(&opts, |_| {}).unwrap();
    let listed: Vec<String> = report.findings.iter().map(|f| f.to_string()).collect();
    assert!(
        listed.is_empty(),
        "seed 11: {} defects:\n{}\n{}",
        listed.len(),
        listed.join("\n"),
        report.markdown()
    );
    // Every family met both refusals and acceptances: the mutations reach the readers' checks
    // and leave some files valid.
    let clear = Outcome::ALL
        .iter()
        .position(|o| *o == Outcome::ClearError)
        .unwrap();
    let accepted = Outcome::ALL
        .iter()
        .position(|o| *o == Outcome::Accepted)
        .unwrap();
    for r in &report.rows {
        assert!(
            r.counts[clear] > 0 && r.counts[accepted] > 0,
            "{}: {:?}\n{}",
            r.family.name(),
            r.counts,
            report.markdown()
        );
    }
}

/// A damaged file of `family`: the seed file with `edit` applied.
fn edited(seeds: &Seeds, family: Family, edit: impl FnOnce(&mut Content)) -> Vec<u8> {
    let (bytes, _) = seeds.file(family).unwrap();
    let mut c = Content::read(&bytes).unwrap();
    edit(&mut c);
    c.build().unwrap()
}

#[test]
fn defects_found_by_earlier_campaigns_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let seeds = Seeds::make(dir.path()).unwrap();
    let set = |name: &'static str, i: usize, v: f64| {
        move |c: &mut Content| assert!(c.set_value(name, i, v), "no {name}[{i}]")
    };
    let timeseries = {
        let (bytes, _) = seeds.file(Family::RunDirectory).unwrap();
        let mut lines: Vec<&str> = std::str::from_utf8(&bytes).unwrap().lines().collect();
        lines.swap(2, 3);
        lines.join("\n").into_bytes()
    };
    let lines_of = |family: Family, edit: &dyn Fn(&mut Vec<String>)| {
        let (bytes, _) = seeds.file(family).unwrap();
        let mut lines: Vec<String> = std::str::from_utf8(&bytes)
            .unwrap()
            .lines()
            .map(String::from)
            .collect();
        edit(&mut lines);
        (lines.join("\n") + "\n").into_bytes()
    };
    let repeated_row = lines_of(Family::CompactTrajectories, &|l| {
        let row = l[2].clone();
        l.insert(3, row);
    });
    let negative_length = lines_of(Family::CompactLengths, &|l| {
        let mut fields: Vec<String> = l[1].split(',').map(String::from).collect();
        let k = fields.len() - 2;
        fields[k] = "-1".into();
        l[1] = fields.join(",");
    });
    let huge_box = lines_of(Family::SeriesTable, &|l| {
        let mut fields: Vec<String> = l[1].split(',').map(String::from).collect();
        fields[2] = "1e308".into();
        l[1] = fields.join(",");
    });
    // (what it was, family, file, the message's phrase)
    let cases: Vec<(&str, Family, Vec<u8>, &str)> = vec![
        (
            "box_length u64::MAX: panicked (capacity overflow)",
            Family::ParticleSnapshot,
            edited(&seeds, Family::ParticleSnapshot, |c| {
                c.set_attr("box_length", AttrValue::U64(u64::MAX))
            }),
            "box_length",
        ),
        (
            "a centre at -1e300: hung",
            Family::ParticleCheckpoint,
            edited(
                &seeds,
                Family::ParticleCheckpoint,
                set("positions", 4, -1e300),
            ),
            "rod 1 at",
        ),
        (
            "a NaN quaternion: GMRES failed without naming the file",
            Family::ParticleCheckpoint,
            edited(
                &seeds,
                Family::ParticleCheckpoint,
                set("quaternions", 54, f64::NAN),
            ),
            "quaternion",
        ),
        (
            "a quaternion 1e-6 off unit: accepted, the run not unit",
            Family::ParticleCheckpoint,
            edited(&seeds, Family::ParticleCheckpoint, |c| {
                let (bytes, _) = seeds.file(Family::ParticleCheckpoint).unwrap();
                let q0 = Content::read(&bytes)
                    .unwrap()
                    .value("quaternions", 0)
                    .unwrap();
                assert!(c.set_value("quaternions", 0, q0 * (1.0 + 1e-6)));
            }),
            "quaternion",
        ),
        (
            "two rods at one place: the contact solver failed without naming the file",
            Family::ParticleCheckpoint,
            edited(&seeds, Family::ParticleCheckpoint, |c| {
                for k in 0..3 {
                    let v = c.value("positions", k).unwrap();
                    assert!(c.set_value("positions", 3 + k, v));
                }
            }),
            "overlap",
        ),
        (
            "a NaN GMRES warm start: GMRES failed without naming the file",
            Family::ParticleCheckpoint,
            edited(
                &seeds,
                Family::ParticleCheckpoint,
                set("gmres_warm_start", 7, f64::NAN),
            ),
            "gmres_warm_start",
        ),
        (
            "a GMRES warm start of -1.6e306: the fast sum refined its grid without end (hung)",
            Family::ParticleCheckpoint,
            edited(
                &seeds,
                Family::ParticleCheckpoint,
                set("gmres_warm_start", 12, -1.6e306),
            ),
            "its forces overflow it",
        ),
        (
            "a GMRES warm start of 8.2e107: a rod moved 1e100 box lengths, wrapped one box per turn (hung)",
            Family::ParticleCheckpoint,
            edited(
                &seeds,
                Family::ParticleCheckpoint,
                set("gmres_warm_start", 249, 8.2e107),
            ),
            "crosses the box in one step",
        ),
        (
            "Q's mean set negative: the fixed point failed without naming the file",
            Family::MeanFieldCheckpoint,
            edited(&seeds, Family::MeanFieldCheckpoint, set("q_hat", 0, -1e3)),
            "orientation tensor",
        ),
        (
            "a zero time step in the clock: the step failed without naming the file",
            Family::MeanFieldCheckpoint,
            edited(&seeds, Family::MeanFieldCheckpoint, set("clock", 0, 0.0)),
            "clock",
        ),
        (
            "u's warm start at 1e300: the fixed point failed without naming the file",
            Family::MeanFieldCheckpoint,
            edited(&seeds, Family::MeanFieldCheckpoint, set("u_hat", 40, 1e300)),
            "the first step after resuming from",
        ),
        (
            "two rows of the time series swapped: accepted",
            Family::RunDirectory,
            timeseries,
            "increasing",
        ),
        (
            "a force point at 6.6e286: check-accuracy measured NaN errors",
            Family::RunSnapshot,
            edited(
                &seeds,
                Family::RunSnapshot,
                set("force_points", 61, 6.6e286),
            ),
            "force_points",
        ),
        (
            "a point force of -4e307: check-accuracy measured NaN errors",
            Family::RunSnapshot,
            edited(&seeds, Family::RunSnapshot, set("point_forces", 27, -4e307)),
            "overflow",
        ),
        (
            "a snapshot's box_length 1e300: check-accuracy audited another box",
            Family::RunSnapshot,
            edited(&seeds, Family::RunSnapshot, |c| {
                c.set_attr("box_length", AttrValue::F64(1e300))
            }),
            "box_length",
        ),
        (
            "a snapshot's time NaN: check-accuracy reported t = NaN",
            Family::RunSnapshot,
            edited(&seeds, Family::RunSnapshot, |c| {
                c.set_attr("time", AttrValue::F64(f64::NAN))
            }),
            "time NaN",
        ),
        (
            "a compact run's MSD row repeated: drawn as given",
            Family::CompactTrajectories,
            repeated_row,
            "increasing",
        ),
        (
            "a compact run's correlation length -1: drawn as given",
            Family::CompactLengths,
            negative_length,
            "correlation length -1",
        ),
        (
            "a series table's L/l of 1e308: drawn at a density of 0",
            Family::SeriesTable,
            huge_box,
            "L/l 1e308,",
        ),
    ];
    for (k, (what, family, bytes, phrase)) in cases.into_iter().enumerate() {
        let (_, name) = seeds.file(family).unwrap();
        let work = dir.path().join(format!("case-{k}"));
        match readers::read(family, &seeds, &bytes, &work, name) {
            Verdict::Refused(m) => {
                let stem = name.split('.').next().unwrap();
                assert!(
                    m.contains(phrase) && m.contains(stem),
                    "{what}: the message names neither `{phrase}` nor the file `{stem}`: {m}"
                );
            }
            Verdict::Accepted(r) => panic!("{what}: accepted ({r:?})"),
        }
    }
}
