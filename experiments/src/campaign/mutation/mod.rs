//! Mutation campaigns: valid files motile writes (run configs, scenes, snapshots and
//! checkpoints of both models, a run's time series), damaged in seeded ways ([`mutate`]) and
//! fed to the reader a user reaches with each ([`readers`]). Every outcome is classified: a
//! clear error (it names the file), accepted and consistent, an error that does not name the
//! file, accepted but inconsistent, a panic, or a hang (past the time limit). Input `i` of a
//! family is reproducible from `(seed, family, i)` alone.

pub mod family;
pub mod mutate;
pub mod readers;

pub use family::{Family, Outcome};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use readers::{Seeds, Verdict};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What a campaign runs.
#[derive(Clone, Debug)]
pub struct CampaignOptions {
    /// Seed of every mutation.
    pub seed: u64,
    /// Damaged inputs per family.
    pub per_family: usize,
    /// A reader still running after this is a hang.
    pub time_limit: Duration,
    /// The families.
    pub families: Vec<Family>,
    /// Scratch directory: the seed runs, each input's files, and copies of the inputs behind
    /// defects (`findings/`).
    pub scratch: PathBuf,
}

/// One defect: enough to reproduce and read it.
#[derive(Clone, Debug)]
pub struct Finding {
    /// The family.
    pub family: Family,
    /// The input's index (with the campaign's seed, it reproduces the input).
    pub index: usize,
    /// What the mutation did.
    pub mutation: String,
    /// How the reader met it.
    pub outcome: Outcome,
    /// The reader's message, the panic's, or what is inconsistent.
    pub message: String,
    /// A copy of the input.
    pub input: PathBuf,
}

impl std::fmt::Display for Finding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} #{} ({}): {}: {} [{}]",
            self.family.name(),
            self.index,
            self.mutation,
            self.outcome.name(),
            self.message,
            self.input.display()
        )
    }
}

/// Outcome counts of one family.
#[derive(Clone, Debug)]
pub struct FamilyCounts {
    /// The family.
    pub family: Family,
    /// Counts in [`Outcome::ALL`]'s order.
    pub counts: [usize; 6],
    /// Wall seconds.
    pub seconds: f64,
}

/// A campaign's table and its defects.
#[derive(Clone, Debug)]
pub struct CampaignReport {
    /// The seed.
    pub seed: u64,
    /// One row per family.
    pub rows: Vec<FamilyCounts>,
    /// Every defect found.
    pub findings: Vec<Finding>,
}

impl CampaignReport {
    /// The table as Markdown: family, reader, inputs, then the outcome counts.
    pub fn markdown(&self) -> String {
        let mut s = String::from("| family | reader | inputs |");
        for o in Outcome::ALL {
            let _ = write!(s, " {} |", o.name());
        }
        s.push_str(" wall (s) |\n|---|---|---|");
        s.push_str(&"---|".repeat(Outcome::ALL.len() + 1));
        s.push('\n');
        for r in &self.rows {
            let n: usize = r.counts.iter().sum();
            let _ = write!(s, "| {} | {} | {n} |", r.family.name(), r.family.reader());
            for c in r.counts {
                let _ = write!(s, " {c} |");
            }
            let _ = writeln!(s, " {:.0} |", r.seconds);
        }
        s
    }
}

/// Run a campaign: make the seed runs, then damage and read `per_family` inputs of each family
/// (fewer where a hang ends the family).
pub fn run_campaign(
    opts: &CampaignOptions,
    mut on_row: impl FnMut(&FamilyCounts),
) -> anyhow::Result<CampaignReport> {
    let seeds = Arc::new(Seeds::make(&opts.scratch)?);
    let findings_dir = opts.scratch.join("findings");
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut report = CampaignReport {
        seed: opts.seed,
        rows: Vec::new(),
        findings: Vec::new(),
    };
    let result = (|| {
        for &family in &opts.families {
            let row = run_family(family, &seeds, opts, &findings_dir, &mut report.findings)?;
            on_row(&row);
            report.rows.push(row);
        }
        anyhow::Ok(())
    })();
    std::panic::set_hook(hook);
    result.map(|()| report)
}

fn run_family(
    family: Family,
    seeds: &Arc<Seeds>,
    opts: &CampaignOptions,
    findings_dir: &Path,
    findings: &mut Vec<Finding>,
) -> anyhow::Result<FamilyCounts> {
    let start = Instant::now();
    let (seed_bytes, name) = seeds.file(family)?;
    let mut counts = [0; 6];
    for index in 0..opts.per_family {
        let mut rng = ChaCha8Rng::seed_from_u64(input_seed(opts.seed, family, index));
        let m = if family.is_text() {
            mutate::text(&seed_bytes, &mut rng)
        } else {
            mutate::hdf5(&seed_bytes, &mut rng)
        };
        let work = opts
            .scratch
            .join("work")
            .join(format!("{}-{index}", family.name()));
        let (outcome, message) = read_one(family, seeds, m.bytes.clone(), &work, name, opts);
        counts[Outcome::ALL.iter().position(|o| *o == outcome).unwrap_or(0)] += 1;
        if outcome.is_defect() {
            std::fs::create_dir_all(findings_dir)?;
            let input = findings_dir.join(format!("{}-{index}-{name}", family.name()));
            std::fs::write(&input, &m.bytes)?;
            findings.push(Finding {
                family,
                index,
                mutation: m.what,
                outcome,
                message,
                input,
            });
        }
        // A hung reader keeps its thread, and whatever it holds (the thread pool, locks): the
        // family's later inputs would wait on it, so a hang ends the family.
        if outcome == Outcome::Hang {
            break;
        }
        let _ = std::fs::remove_dir_all(&work);
    }
    Ok(FamilyCounts {
        family,
        counts,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The seed of input `index` of `family`: a reproducible stream per input.
fn input_seed(seed: u64, family: Family, index: usize) -> u64 {
    let f = Family::ALL.iter().position(|x| *x == family).unwrap_or(0) as u64;
    seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ (f << 56) ^ index as u64
}

/// Read one input on a thread of its own, so that a panic is caught and a hang timed out.
fn read_one(
    family: Family,
    seeds: &Arc<Seeds>,
    bytes: Vec<u8>,
    work: &Path,
    name: &'static str,
    opts: &CampaignOptions,
) -> (Outcome, String) {
    let (tx, rx) = std::sync::mpsc::channel();
    let seeds = Arc::clone(seeds);
    let work_dir = work.to_path_buf();
    std::thread::spawn(move || {
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            readers::read(family, &seeds, &bytes, &work_dir, name)
        }));
        let _ = tx.send(r);
    });
    match rx.recv_timeout(opts.time_limit) {
        Err(_) => (Outcome::Hang, format!("no answer in {:?}", opts.time_limit)),
        Ok(Err(payload)) => (Outcome::Panic, panic_message(payload.as_ref())),
        Ok(Ok(Verdict::Accepted(Ok(())))) => (Outcome::Accepted, String::new()),
        Ok(Ok(Verdict::Accepted(Err(why)))) => (Outcome::Inconsistent, why),
        Ok(Ok(Verdict::Refused(m))) => {
            let file = Path::new(name)
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let named = m.contains(&file);
            let outcome = if named {
                Outcome::ClearError
            } else {
                Outcome::UnclearError
            };
            (outcome, m)
        }
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "a panic without a message".into())
}
