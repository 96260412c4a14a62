//! The particle step shared by several ranks (`motile_particle::step::distributed`) against the
//! single-process step: ranks as threads ([`ThreadRanks`]), so this runs everywhere; the MPI
//! driver is the same code over another [`motile_particle::parallel::comm::Comm`].

use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::units::DEFAULT_DIAMETER;
use motile_particle::parallel::comm::ThreadRanks;
use motile_particle::prelude::*;
use motile_particle::step::distributed::Distributed;

const STEPS: usize = 20;
const DT: f64 = 0.002;

fn stepper() -> Stepper {
    Stepper::new(
        Box::new(LocalDrag::new(DEFAULT_DIAMETER)),
        ContactParams::default(),
    )
}

/// Rods and velocities `(v, w)` after `STEPS` steps on `ranks` ranks, and each step's report
/// (rank 0's: the whole box's).
fn on_ranks(r0: &RodSet, ranks: usize) -> (RodSet, Vec<[f64; 6]>, Vec<StepReport>, Vec<usize>) {
    on_ranks_with(r0, ranks, shared_stepper, DT)
}

/// A stepper for the given rank count (the one for one process on one rank), stepping by `dt`.
type Make = fn(usize) -> Stepper;

fn shared_stepper(_ranks: usize) -> Stepper {
    stepper()
}

fn on_ranks_with(
    r0: &RodSet,
    ranks: usize,
    make: Make,
    dt: f64,
) -> (RodSet, Vec<[f64; 6]>, Vec<StepReport>, Vec<usize>) {
    let handles: Vec<_> = ThreadRanks::group(ranks)
        .into_iter()
        .map(|comm| {
            let r0 = r0.clone();
            std::thread::spawn(move || {
                let mut d = Distributed::new(comm, make(ranks), &r0);
                let mut reports = Vec::new();
                let mut copies = Vec::new();
                for _ in 0..STEPS {
                    reports.push(d.step(dt).expect("step"));
                    copies.push(d.last_halo());
                }
                (d.gather(&d.velocity_rows()), reports, copies)
            })
        })
        .collect();
    let mut results: Vec<_> = handles.into_iter().map(|h| h.join().unwrap()).collect();
    let copies = results.iter().map(|r| r.2.iter().sum()).collect();
    let (gathered, reports, _) = results.swap_remove(0);
    let (rods, vel) = gathered.expect("rank 0 gathers");
    (rods, vel, reports, copies)
}

fn single(r0: &RodSet) -> (RodSet, Vec<[f64; 6]>, Vec<StepReport>) {
    single_with(r0, stepper(), DT)
}

fn single_with(r0: &RodSet, mut s: Stepper, dt: f64) -> (RodSet, Vec<[f64; 6]>, Vec<StepReport>) {
    let mut r = r0.clone();
    let reports = (0..STEPS).map(|_| s.step(&mut r, dt).unwrap()).collect();
    let v = s.velocities();
    let rows =
        v.v.iter()
            .zip(&v.w)
            .map(|(a, b)| [a[0], a[1], a[2], b[0], b[1], b[2]])
            .collect();
    (r, rows, reports)
}

/// Positions and axes within `bound_x`, velocities within `bound_v`.
fn within(ranks: usize, [dx, dp, dv]: [f64; 3], bound_x: f64, bound_v: f64) {
    assert!(
        dx <= bound_x && dp <= bound_x,
        "{ranks} ranks: positions differ by {dx:.2e}, axes by {dp:.2e} (bound {bound_x:.1e})"
    );
    assert!(
        dv <= bound_v,
        "{ranks} ranks: velocities differ by {dv:.2e} (bound {bound_v:.1e})"
    );
}

/// Largest difference of centres (unwrapped), axes and velocities.
fn difference(a: &RodSet, va: &[[f64; 6]], b: &RodSet, vb: &[[f64; 6]]) -> [f64; 3] {
    let (ua, ub) = (a.unwrapped(), b.unwrapped());
    let mut d = [0.0f64; 3];
    for k in 0..a.len() {
        let (pa, pb) = (a.p(k), b.p(k));
        for c in 0..3 {
            d[0] = d[0].max((ua[k][c] - ub[k][c]).abs());
            d[1] = d[1].max((pa[c] - pb[c]).abs());
        }
        for c in 0..6 {
            d[2] = d[2].max((va[k][c] - vb[k][c]).abs());
        }
    }
    d
}

#[test]
fn one_rank_is_the_single_process_step_bit_for_bit() {
    let r0 = random_nonoverlapping(1500, 7.0, DEFAULT_DIAMETER, 3, 100_000).unwrap();
    let (rs, vs, reps) = single(&r0);
    let (rd, vd, repd, _) = on_ranks(&r0, 1);
    assert!(rs == rd, "one rank moved the rods differently");
    assert!(vs == vd, "one rank's velocities differ");
    assert_eq!(
        reps.iter().map(|r| &r.contact).collect::<Vec<_>>(),
        repd.iter().map(|r| &r.contact).collect::<Vec<_>>()
    );
}

/// A dense suspension (nu = 5, every step with active contacts) on 2 and 3 ranks against one
/// process. The multipliers agree to the solver's residual tolerance (1e-7 l) rather than bit
/// for bit (per-rank sums), so each step's positions can differ by about `tolerance` and
/// velocities by `tolerance / dt`; allowed: 20 steps of that, times 10.
#[test]
fn two_and_three_ranks_agree_with_one_process_within_the_solver_tolerance() {
    let r0 = random_nonoverlapping(2560, 8.0, DEFAULT_DIAMETER, 7, 100_000).unwrap();
    let (rs, vs, reps) = single(&r0);
    let active: usize = reps.iter().map(|r| r.contact.active).sum();
    assert!(active > 20, "the test needs contacts ({active} active)");
    let tol = ContactParams::default().tolerance;
    let bound_x = 10.0 * STEPS as f64 * tol;
    let bound_v = bound_x / DT;
    for ranks in [2, 3] {
        let (rd, vd, repd, copies) = on_ranks(&r0, ranks);
        let [dx, dp, dv] = difference(&rs, &vs, &rd, &vd);
        eprintln!(
            "{ranks} ranks: |dx| {dx:.2e}, |dp| {dp:.2e}, |dv| {dv:.2e} after {STEPS} steps ({active} active contacts in all; copies per rank per step {:?})",
            copies.iter().map(|c| c / STEPS).collect::<Vec<_>>()
        );
        assert!(
            copies.iter().all(|&c| c > 0),
            "every rank must hold copies: {copies:?}"
        );
        within(ranks, [dx, dp, dv], bound_x, bound_v);
        for (k, (a, b)) in reps.iter().zip(&repd).enumerate() {
            assert_eq!(
                a.contact.constraints, b.contact.constraints,
                "step {k}: every pair is some rank's constraint, once"
            );
            assert!(
                (a.mean_speed - b.mean_speed).abs() <= bound_v,
                "step {k}: mean speed {} vs {}",
                a.mean_speed,
                b.mean_speed
            );
        }
    }
}

const SUM_TOLERANCE: f64 = 1e-4;

fn dipole_stepper(ranks: usize) -> Stepper {
    let sum = Box::new(SpectralEwald::new(SUM_TOLERANCE).unwrap());
    let mut mobility = Dipole::new(sum, DEFAULT_DIAMETER);
    if ranks > 1 {
        mobility = mobility.shared(SUM_TOLERANCE).unwrap();
    }
    Stepper::new(Box::new(mobility), ContactParams::default())
}

/// The dipole level (point stresslets through the spectral Ewald sum, shared among ranks with
/// a distributed FFT) on 2 and 3 ranks against one process: each process's flow is within the
/// sum's tolerance of the exact flow, so velocities may differ by `2 tol max|u_flow|` and
/// positions by that times `dt` per step; allowed: 20 steps of that, times 10.
#[test]
fn the_dipole_level_on_two_and_three_ranks_agrees_with_one_process_within_the_sum_tolerance() {
    let dt = 0.01;
    let r0 = random_nonoverlapping(1000, 10.0, DEFAULT_DIAMETER, 5, 100_000).unwrap(); // nu = 1
    let (rs, vs, reps) = single_with(&r0, dipole_stepper(1), dt);
    // The flow's size: speeds beyond swimming (U = 1).
    let flow = vs
        .iter()
        .map(|v| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - 1.0).abs())
        .fold(0.0, f64::max)
        .max(1e-3);
    let bound_v = 10.0 * 2.0 * SUM_TOLERANCE * flow;
    let bound_x = STEPS as f64 * dt * bound_v;
    for ranks in [2, 3] {
        let (rd, vd, repd, _) = on_ranks_with(&r0, ranks, dipole_stepper, dt);
        let [dx, dp, dv] = difference(&rs, &vs, &rd, &vd);
        eprintln!(
            "dipole, {ranks} ranks: |dx| {dx:.2e}, |dp| {dp:.2e}, |dv| {dv:.2e} after {STEPS} steps (flow up to {flow:.2e}; bounds {bound_x:.1e}, {bound_v:.1e}); sum levels {:?}",
            repd.iter().map(|r| r.hydro.sum_level).collect::<Vec<_>>()
        );
        assert!(
            repd.iter()
                .all(|r| r.hydro.sums > 0 && r.hydro.sum_tolerance_met),
            "{ranks} ranks: every shared sum met its tolerance"
        );
        within(ranks, [dx, dp, dv], bound_x, bound_v);
        assert_eq!(
            reps.iter()
                .map(|r| r.contact.constraints)
                .collect::<Vec<_>>(),
            repd.iter()
                .map(|r| r.contact.constraints)
                .collect::<Vec<_>>(),
        );
    }
}

/// A non-finite point on one rank stops the shared sums on every rank with an error (a rank
/// that returned alone would leave the others waiting forever).
#[test]
fn a_non_finite_point_on_one_rank_fails_the_shared_sums_on_every_rank() {
    use motile_particle::ewald::shared::{RankShare, SharedEwald};
    let handles: Vec<_> = ThreadRanks::group(2)
        .into_iter()
        .map(|comm| {
            std::thread::spawn(move || {
                let r = motile_particle::parallel::comm::Comm::rank(&comm);
                let mut x: Vec<[f64; 3]> = (0..20)
                    .map(|k| [0.3 * k as f64, 1.0 + r as f64 * 4.0, 2.0 + r as f64 * 4.0])
                    .collect();
                if r == 0 {
                    x[3][1] = f64::NAN;
                }
                let p = vec![[0.0, 0.0, 1.0]; x.len()];
                let sigma = vec![1.0; x.len()];
                let mut sum = SharedEwald::new(1e-4).unwrap();
                let share = RankShare {
                    owned: x.len(),
                    total: 40,
                    reach: 1.3,
                };
                sum.stresslets(&comm, share, 8.0, &x, &p, &sigma)
                    .map(|_| ())
                    .map_err(|e| e.to_string())
            })
        })
        .collect();
    let results: Vec<_> = handles.into_iter().map(|h| h.join().unwrap()).collect();
    assert!(
        results[0]
            .as_ref()
            .is_err_and(|e| e.contains("point 3 of rank 0 has a non-finite coordinate")),
        "{results:?}"
    );
    assert!(
        results[1]
            .as_ref()
            .is_err_and(|e| e.contains("another rank has a point with a non-finite coordinate")),
        "{results:?}"
    );
}

/// Settings of the slender-body comparison: a tight sum and GMRES, so that the ranks' answers
/// differ by little more than the tolerances.
const SBT_SUM_TOLERANCE: f64 = 1e-6;
const SBT_GMRES_TOLERANCE: f64 = 1e-10;

fn sbt_stepper(ranks: usize) -> Stepper {
    let mut params = SlenderParams::for_diameter(DEFAULT_DIAMETER);
    params.gmres.tol = SBT_GMRES_TOLERANCE;
    let sum = Box::new(SpectralEwald::new(SBT_SUM_TOLERANCE).unwrap());
    let mut mobility = SlenderBody::new(params, sum);
    if ranks > 1 {
        mobility = mobility.shared(SBT_SUM_TOLERANCE).unwrap();
    }
    Stepper::new(Box::new(mobility), ContactParams::default())
}

/// The slender-body level ((P4) by GMRES with distributed dot products; the RPY sum shared
/// among ranks; each rod's GMRES warm start and flow prediction moving with it between slabs)
/// on 2 and 3 ranks against one process. Both solve (P4) to the GMRES tolerance with sums within
/// the sum tolerance, so their flows differ by about `(tol_sum + tol_gmres) max|u_flow|`
/// times the conditioning of (P4); allowed: 10 x 2 x that per step, velocities and, times
/// `dt`, positions, over 20 steps.
#[test]
fn the_slender_body_level_on_two_and_three_ranks_agrees_with_one_process() {
    let dt = 0.01;
    // nu = 0.46 in a box wide enough that copies (within the cutoff plus a rod length of a
    // slab, about 4 l) cover only part of it on 3 ranks.
    let r0 = random_nonoverlapping(1000, 13.0, DEFAULT_DIAMETER, 11, 100_000).unwrap();
    let (rs, vs, reps) = single_with(&r0, sbt_stepper(1), dt);
    let flow = vs
        .iter()
        .map(|v| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - 1.0).abs())
        .fold(0.0, f64::max)
        .max(1e-3);
    let bound_v = 10.0 * 2.0 * (SBT_SUM_TOLERANCE + SBT_GMRES_TOLERANCE) * flow;
    let bound_x = STEPS as f64 * dt * bound_v;
    for ranks in [1, 2, 3] {
        let (rd, vd, repd, copies) = on_ranks_with(&r0, ranks, sbt_stepper, dt);
        let [dx, dp, dv] = difference(&rs, &vs, &rd, &vd);
        eprintln!(
            "sbt, {ranks} ranks: |dx| {dx:.2e}, |dp| {dp:.2e}, |dv| {dv:.2e} after {STEPS} steps (flow up to {flow:.2e}; bounds {bound_x:.1e}, {bound_v:.1e}); GMRES iterations {:?} vs {:?}; copies per rank per step {:?}",
            reps.iter()
                .map(|r| r.hydro.gmres_iterations)
                .collect::<Vec<_>>(),
            repd.iter()
                .map(|r| r.hydro.gmres_iterations)
                .collect::<Vec<_>>(),
            copies.iter().map(|c| c / STEPS).collect::<Vec<_>>()
        );
        if ranks == 1 {
            assert!(rs == rd && vs == vd, "one rank is the single-process step");
            continue;
        }
        assert!(
            repd.iter()
                .all(|r| r.hydro.sums > 0 && r.hydro.sum_tolerance_met),
            "{ranks} ranks: every shared sum met its tolerance"
        );
        within(ranks, [dx, dp, dv], bound_x, bound_v);
        // The warm starts moved with their rods: a rank that lost them would start GMRES from
        // the right-hand side and need more iterations than one process.
        for (k, (a, b)) in reps.iter().zip(&repd).enumerate() {
            assert!(
                a.hydro.gmres_iterations.abs_diff(b.hydro.gmres_iterations) <= 1,
                "step {k}: {} GMRES iterations on {ranks} ranks, {} on one process",
                b.hydro.gmres_iterations,
                a.hydro.gmres_iterations
            );
        }
    }
}

/// The shared grid's distributed FFT (the benchmark entry point BENCHMARKS.md compares with
/// FFTW): a forward and inverse round trip returns the fields to round-off on 1, 2 and 3
/// ranks, for grid sizes that do and do not divide among the ranks. (A wrong transform that
/// undid itself would pass here; the shared sums' tests against the direct Ewald sum in
/// accuracy_contract.rs are what check the transform itself.)
#[test]
fn the_distributed_fft_round_trip_returns_the_fields() {
    for m in [12, 16, 20] {
        for ranks in [1, 2, 3] {
            let handles: Vec<_> = ThreadRanks::group(ranks)
                .into_iter()
                .map(|comm| {
                    std::thread::spawn(move || {
                        motile_particle::parallel::slab_fft::fft_round_trip(&comm, m, 3, 1).1
                    })
                })
                .collect();
            let worst = handles
                .into_iter()
                .map(|h| h.join().unwrap())
                .fold(0.0, f64::max);
            assert!(
                worst < 1e-13,
                "M = {m}, {ranks} ranks: round-trip error {worst:.1e}"
            );
        }
    }
}

/// A step that fails on ranks fails on every rank, and each keeps its state from before it:
/// rods, and the slender-body level's per-rod GMRES warm start and flow prediction, gathered to
/// rank 0 exactly as before the failed step. The failure comes at the end of a whole step (solves
/// done, state changed): after two good steps the overlap tolerance is set below zero, which no
/// step can meet.
#[test]
fn a_failed_shared_step_keeps_the_state_before_it_on_every_rank() {
    let r0 = random_nonoverlapping(300, 8.0, DEFAULT_DIAMETER, 17, 100_000).unwrap();
    let handles: Vec<_> = ThreadRanks::group(2)
        .into_iter()
        .map(|comm| {
            let r0 = r0.clone();
            std::thread::spawn(move || {
                let mut d = Distributed::new(comm, sbt_stepper(2), &r0);
                for _ in 0..2 {
                    d.step(0.01).expect("a good step");
                }
                let before = (d.gather(&d.velocity_rows()), d.gather_rod_state());
                d.stepper_mut().contact.overlap_tolerance = -1.0;
                let failed = d.step(0.01).map(|_| ()).map_err(|e| e.to_string());
                let after = (d.gather(&d.velocity_rows()), d.gather_rod_state());
                (failed, before, after)
            })
        })
        .collect();
    let results: Vec<_> = handles.into_iter().map(|h| h.join().unwrap()).collect();
    for (rank, (failed, _, _)) in results.iter().enumerate() {
        assert!(
            failed.is_err(),
            "rank {rank}: the step must fail: {failed:?}"
        );
    }
    let (_, before, after) = &results[0];
    let (rods_before, state_before) = (&before.0.as_ref().unwrap().0, &before.1);
    let (rods_after, state_after) = (&after.0.as_ref().unwrap().0, &after.1);
    assert!(rods_before == rods_after, "the rods moved in a failed step");
    let state = state_before.as_ref().unwrap();
    assert_eq!(
        state.len(),
        300 * (3 * 4 + 6),
        "every rod's state was gathered"
    );
    assert!(
        Some(state) == state_after.as_ref(),
        "the per-rod state changed in a failed step"
    );
}
