//! `mpirun -n P motile particle run`: the same configs (contacts only; the dipole and
//! slender-body levels) on 1, 2 and 3 ranks against one process
//! (feature `mpi`; scripts/test.sh builds it and has OpenMPI). Without the feature, a launch
//! under mpirun is refused.

mod support;

use std::process::Command;

#[cfg(feature = "mpi")]
mod with_mpi {
    use super::support::copy_dir;
    use super::*;

    /// A dilute dipole-level run: 1000 rods, nu = 1, 20 steps of 0.01.
    const DIPOLE: &str = "box_length = 10.0
    volume_fraction = 1.0
    dt = 0.01
    t_end = 0.2
    hydrodynamics = \"dipole\"
    diagnostic_interval = 0.01
    snapshot_interval = 0.2
    checkpoint_interval = 0.1
    vtk = false
    ";

    const CONFIG: &str = "box_length = 8.0
    volume_fraction = 5.0
    dt = 0.002
    t_end = 0.04
    hydrodynamics = \"none\"
    diagnostic_interval = 0.002
    snapshot_interval = 0.04
    checkpoint_interval = 0.02
    vtk = false
    ";
    use std::path::Path;
    use std::process::Output;

    /// Run `motile args` (under `mpirun -n ranks` when given), one rayon thread per rank, killed
    /// after two minutes (a deadlock fails the test instead of hanging the suite).
    fn motile(ranks: Option<usize>, args: &[&str]) -> Output {
        let bin = env!("CARGO_BIN_EXE_motile");
        let mut cmd = match ranks {
            Some(n) => {
                let mut c = Command::new("mpirun");
                c.args([
                    "--allow-run-as-root",
                    "--oversubscribe",
                    "-n",
                    &n.to_string(),
                    bin,
                ]);
                c
            }
            None => Command::new(bin),
        };
        cmd.arg("--threads").arg("1").args(args);
        // Open MPI keeps a session directory under TMPDIR named by host and user only; two
        // runs starting at once (the tests run in parallel) race to create it and one aborts
        // in MPI_Init ("File exists"). Each run gets its own.
        let session = tempfile::tempdir().expect("a temporary folder for Open MPI's session");
        cmd.env("TMPDIR", session.path())
            .env("OMPI_MCA_orte_tmpdir_base", session.path());
        cmd.stdout(std::process::Stdio::piped());
        cmd.stderr(std::process::Stdio::piped());
        let mut child = cmd.spawn().expect("start motile (is mpirun installed?)");
        let start = std::time::Instant::now();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed().as_secs() > 120 {
                child.kill().unwrap();
                panic!("motile {args:?} on {ranks:?} ranks did not finish in 120 s");
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        child.wait_with_output().unwrap()
    }
    use motile_experiments::io::snapshot::{Snapshot, read_snapshot};
    use motile_experiments::run::particle::ParticleCheckpoint;
    use motile_particle::step::contact::ContactParams;

    /// Final rods, velocities and time-series rows of a finished run in `dir`.
    fn outcome(dir: &Path) -> Outcome {
        let ckpt = ParticleCheckpoint::read(&dir.join("checkpoints/ckpt_000000020.h5"), 0.2)
            .expect("final checkpoint");
        let Snapshot::Particle(s) = read_snapshot(&dir.join("snapshots/snap_000001.h5")).unwrap()
        else {
            panic!("not a particle snapshot")
        };
        let v = s.kinematics.expect("kinematics").velocities;
        let text = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
        let rows = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect();
        (ckpt, v, rows)
    }

    /// Largest differences: centres (unwrapped), quaternions, velocities, time-series columns
    /// other than the rate.
    fn differences(a: &Outcome, b: &Outcome) -> [f64; 4] {
        let (ua, ub) = (a.0.rods.unwrapped(), b.0.rods.unwrapped());
        let mut d = [0.0f64; 4];
        for k in 0..ua.len() {
            for c in 0..3 {
                d[0] = d[0].max((ua[k][c] - ub[k][c]).abs());
                d[2] = d[2].max((a.1[k][c] - b.1[k][c]).abs());
            }
            for c in 0..4 {
                d[1] = d[1].max((a.0.rods.q[k][c] - b.0.rods.q[k][c]).abs());
            }
        }
        assert_eq!(a.2.len(), b.2.len(), "time-series rows");
        for (ra, rb) in a.2.iter().zip(&b.2) {
            for (c, (x, y)) in ra.iter().zip(rb).enumerate() {
                if c != 1 {
                    d[3] = d[3].max((x - y).abs());
                }
            }
        }
        d
    }

    type Outcome = (ParticleCheckpoint, Vec<[f64; 3]>, Vec<Vec<f64>>);

    /// One rank: the single process bit for bit; more: positions and axes within
    /// `bounds.0`, velocities within `bounds.1`.
    fn agree(what: &str, ranks: usize, single: &Outcome, shared: &Outcome, bounds: (f64, f64)) {
        let [dx, dq, dv, dts] = differences(single, shared);
        eprintln!(
            "{what}, {ranks} rank(s): |dx| {dx:.2e}, |dq| {dq:.2e}, |dv| {dv:.2e}, time series {dts:.2e}"
        );
        if ranks == 1 {
            assert_eq!(
                [dx, dq, dv, dts],
                [0.0; 4],
                "one rank must be the single process"
            );
        } else {
            assert!(
                dx <= bounds.0 && dq <= bounds.0 && dv <= bounds.1,
                "{what}, {ranks} ranks: |dx| {dx:.2e}, |dq| {dq:.2e} (bound {:.1e}), |dv| {dv:.2e} (bound {:.1e})",
                bounds.0,
                bounds.1
            );
        }
    }

    fn run_in(dir: &Path, name: &str, ranks: Option<usize>) -> std::path::PathBuf {
        let out = dir.join(name);
        let o = motile(
            ranks,
            &[
                "particle",
                "run",
                dir.join("dense.toml").to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
        );
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        out
    }

    /// 20 steps of a dense suspension (nu = 5, contacts active every step). One rank is the
    /// single process bit for bit; 2 and 3 ranks agree within what the contact solver's
    /// residual tolerance allows (its multipliers' sums are added per rank): 20 steps of
    /// `tolerance` in positions, over `dt` in velocities, times 10.
    #[test]
    fn one_two_and_three_ranks_agree_with_one_process_after_20_steps() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("dense.toml"), CONFIG).unwrap();
        let single = outcome(&run_in(dir.path(), "single", None));
        let tol = ContactParams::default().tolerance;
        let bound = 10.0 * 20.0 * tol;
        for ranks in [1, 2, 3] {
            let shared = outcome(&run_in(dir.path(), &format!("p{ranks}"), Some(ranks)));
            assert_eq!(
                single.0.contact_warm_start.len(),
                shared.0.contact_warm_start.len(),
                "{ranks} ranks: the warm start has every active pair once"
            );
            agree("contacts", ranks, &single, &shared, (bound, bound / 0.002));
        }
    }

    /// A run checkpointed on one rank count continues on another (and on one process) to
    /// the same state within the same bound.
    #[test]
    fn checkpoints_restart_on_another_rank_count() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("dense.toml"), CONFIG).unwrap();
        let single = outcome(&run_in(dir.path(), "single", None));
        let bound = 10.0 * 20.0 * ContactParams::default().tolerance;
        for (first, then) in [(2, Some(3)), (3, None), (1, Some(2))] {
            let src = run_in(dir.path(), &format!("from{first}"), Some(first));
            back_to_middle(&src);
            let what = format!("contacts, {first} ranks");
            resumed_within(&what, &single, &src, then, (bound, bound / 0.002));
        }
    }

    /// Drop a finished run's last checkpoint: a resume continues from step 10.
    fn back_to_middle(run: &Path) {
        for f in ["ckpt_000000020.h5", "ckpt_000000020.h5.crc32"] {
            std::fs::remove_file(run.join("checkpoints").join(f)).unwrap();
        }
    }

    /// Resume `run` on `ranks` (none: one process) and check its end against `single`:
    /// positions and axes within `bounds.0`, velocities within `bounds.1`.
    fn resumed_within(
        what: &str,
        single: &Outcome,
        run: &Path,
        ranks: Option<usize>,
        bounds: (f64, f64),
    ) {
        let o = motile(ranks, &["resume", run.to_str().unwrap()]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let [dx, dq, dv, _] = differences(single, &outcome(run));
        eprintln!("{what}, resumed on {ranks:?}: |dx| {dx:.2e}, |dq| {dq:.2e}, |dv| {dv:.2e}");
        assert!(
            dx <= bounds.0 && dq <= bounds.0 && dv <= bounds.1,
            "{what}, resumed on {ranks:?}: |dx| {dx:.2e}, |dq| {dq:.2e} (bound {:.1e}), |dv| {dv:.2e} (bound {:.1e})",
            bounds.0,
            bounds.1
        );
    }

    /// The dipole level (the stresslet sum shared with a distributed FFT): each process's flow
    /// is within the sum's tolerance (1e-4) of the exact one, so velocities may differ by
    /// `2 tol U` (flows are below the swimming speed U = 1) and positions by that times `dt`
    /// per step; allowed: 20 steps of that, times 10. One rank is the single process bit for
    /// bit.
    #[test]
    fn the_dipole_level_on_one_two_and_three_ranks_agrees_with_one_process() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("dense.toml"), DIPOLE).unwrap();
        let single = outcome(&run_in(dir.path(), "single", None));
        let bound_v = 10.0 * 2.0 * 1e-4;
        let bound_x = 20.0 * 0.01 * bound_v;
        for ranks in [1, 2, 3] {
            let shared = outcome(&run_in(dir.path(), &format!("p{ranks}"), Some(ranks)));
            agree("dipole", ranks, &single, &shared, (bound_x, bound_v));
            if ranks > 1 {
                // The velocity norms of the time series (columns 11 and 18) come from the
                // gathered state: within the sum's tolerance of one process's.
                for (ra, rb) in single.2.iter().zip(&shared.2) {
                    for c in [11, 18] {
                        assert!(
                            (ra[c] - rb[c]).abs() <= 1e-4 * ra[c].abs(),
                            "{ranks} ranks: column {c} at t = {}: {} vs {}",
                            ra[0],
                            ra[c],
                            rb[c]
                        );
                    }
                }
            }
        }
    }

    /// A dilute slender-body run: 512 rods, nu = 1, 20 steps of 0.01; a tight sum and GMRES so
    /// that ranks differ by little more than the tolerances.
    const SBT: &str = "box_length = 8.0
    volume_fraction = 1.0
    dt = 0.01
    t_end = 0.2
    hydrodynamics = \"sbt\"
    diagnostic_interval = 0.01
    snapshot_interval = 0.2
    checkpoint_interval = 0.1
    vtk = false
    [hydro]
    sum_tolerance = 1e-6
    gmres_tolerance = 1e-10
    ";

    /// The slender-body level ((P4) by GMRES over ranks on the shared RPY sum): each process
    /// solves to the GMRES tolerance with sums within the sum tolerance, so velocities may
    /// differ by `2 (tol_sum + tol_gmres) U` and positions by that times `dt` per step;
    /// allowed: 20 steps of that, times 10. One rank is the single process bit for bit. A run
    /// checkpointed on 2 ranks resumes on 3 and on one process (the GMRES warm start and flow
    /// prediction travel in the single-process checkpoint) within the same bounds.
    #[test]
    fn the_slender_body_level_on_one_two_and_three_ranks_agrees_with_one_process() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("dense.toml"), SBT).unwrap();
        let single = outcome(&run_in(dir.path(), "single", None));
        let bound_v = 10.0 * 2.0 * (1e-6 + 1e-10);
        let bound_x = 20.0 * 0.01 * bound_v;
        for ranks in [1, 2, 3] {
            let shared = outcome(&run_in(dir.path(), &format!("p{ranks}"), Some(ranks)));
            agree("sbt", ranks, &single, &shared, (bound_x, bound_v));
            // The velocity norms (columns 11 and 18, from the gathered force density) and the
            // GMRES iterations (column 9) as one process's.
            for (ra, rb) in single.2.iter().zip(&shared.2) {
                for c in [11, 18] {
                    assert!(
                        (ra[c] - rb[c]).abs() <= 10.0 * 1e-6 * ra[c].abs(),
                        "{ranks} ranks: column {c} at t = {}: {} vs {}",
                        ra[0],
                        ra[c],
                        rb[c]
                    );
                }
                assert!(
                    (ra[9] - rb[9]).abs() <= 1.0,
                    "{ranks} ranks: {} GMRES iterations at t = {}, one process {}",
                    rb[9],
                    ra[0],
                    ra[9]
                );
            }
        }
        let src = run_in(dir.path(), "from2", Some(2));
        back_to_middle(&src);
        let middle = src.join("checkpoints/ckpt_000000010.h5");
        let saved = ParticleCheckpoint::read(&middle, 0.2).unwrap();
        assert_eq!(
            saved.gmres_warm_start.len(),
            512 * (3 * 4 + 6),
            "the checkpoint written on 2 ranks carries every rod's warm start"
        );
        for then in [Some(3), None] {
            let run = dir.path().join(format!("resumed{then:?}"));
            copy_dir(&src, &run);
            resumed_within("sbt, 2 ranks", &single, &run, then, (bound_x, bound_v));
        }
    }
}

/// Without the feature, a binary started as one of several MPI ranks refuses to run (each rank
/// would run the whole command into one directory).
#[cfg(not(feature = "mpi"))]
#[test]
fn a_build_without_mpi_refuses_to_run_as_one_of_several_ranks() {
    let bin = env!("CARGO_BIN_EXE_motile");
    let o = Command::new(bin)
        .args(["particle", "run", "--dry-run"])
        .env("OMPI_COMM_WORLD_SIZE", "2")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("built without the mpi feature") && err.contains("--features mpi"),
        "{err}"
    );
}
