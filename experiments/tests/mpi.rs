//! `mpirun -n P motile particle run`: the same config on 1, 2 and 3 ranks against one process
//! (feature `mpi`; scripts/test.sh builds it and has OpenMPI). Without the feature, a launch
//! under mpirun is refused.

use std::process::Command;

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

#[cfg(feature = "mpi")]
mod with_mpi {
    use super::*;
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
    use motile_experiments::particle_run::ParticleCheckpoint;
    use motile_experiments::snapshot::{Snapshot, read_snapshot};
    use motile_particle::ContactParams;

    /// Final rods, velocities and time-series rows of a finished run in `dir`.
    fn outcome(dir: &Path) -> (ParticleCheckpoint, Vec<[f64; 3]>, Vec<Vec<f64>>) {
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
    fn differences(
        a: &(ParticleCheckpoint, Vec<[f64; 3]>, Vec<Vec<f64>>),
        b: &(ParticleCheckpoint, Vec<[f64; 3]>, Vec<Vec<f64>>),
    ) -> [f64; 4] {
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
            let [dx, dq, dv, dts] = differences(&single, &shared);
            eprintln!(
                "{ranks} rank(s): |dx| {dx:.2e}, |dq| {dq:.2e}, |dv| {dv:.2e}, time series {dts:.2e}"
            );
            assert_eq!(
                single.0.contact_warm_start.len(),
                shared.0.contact_warm_start.len(),
                "{ranks} ranks: the warm start has every active pair once"
            );
            if ranks == 1 {
                assert_eq!(
                    [dx, dq, dv, dts],
                    [0.0; 4],
                    "one rank must be the single process bit for bit"
                );
            } else {
                assert!(
                    dx <= bound && dq <= bound && dv <= bound / 0.002,
                    "{ranks} ranks: |dx| {dx:.2e}, |dq| {dq:.2e} (bound {bound:.1e}), |dv| {dv:.2e} (bound {:.1e})",
                    bound / 0.002
                );
            }
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
            // Back to the middle: the last checkpoint goes, the run resumes from step 10.
            for f in ["ckpt_000000020.h5", "ckpt_000000020.h5.crc32"] {
                std::fs::remove_file(src.join("checkpoints").join(f)).unwrap();
            }
            let o = motile(then, &["resume", src.to_str().unwrap()]);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let [dx, dq, dv, _] = differences(&single, &outcome(&src));
            eprintln!(
                "{first} ranks, resumed on {then:?}: |dx| {dx:.2e}, |dq| {dq:.2e}, |dv| {dv:.2e}"
            );
            assert!(
                dx <= bound && dq <= bound && dv <= bound / 0.002,
                "{first} -> {then:?} ranks: |dx| {dx:.2e}, |dq| {dq:.2e}, |dv| {dv:.2e}"
            );
        }
    }

    /// Levels with a flow are not shared yet: a clear error on every rank count above one,
    /// and no hang.
    #[test]
    fn flow_levels_on_several_ranks_are_refused_with_the_reason() {
        let dir = tempfile::tempdir().unwrap();
        let cfg = CONFIG.replace("\"none\"", "\"dipole\"");
        std::fs::write(dir.path().join("dense.toml"), cfg).unwrap();
        let out = dir.path().join("run");
        let o = motile(
            Some(2),
            &[
                "particle",
                "run",
                dir.path().join("dense.toml").to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "a dipole run on 2 ranks must fail");
        assert!(
            err.contains("hydrodynamics = \"dipole\" runs on one process only"),
            "{err}"
        );
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
