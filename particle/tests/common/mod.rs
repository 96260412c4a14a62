//! Inputs and error measures shared by the tests of the periodic sums: rods as the simulations
//! place them (swimming, force-free, or with random forces; touching in pairs), and the
//! contract's two error metrics.
#![allow(dead_code)]

#[cfg(feature = "gpu")]
use motile_gpu::Backend;
#[cfg(feature = "gpu")]
use motile_particle::ewald::gpu::GpuFourier;
use motile_particle::hydro::slender::half_rod_rule;
use motile_particle::model::geometry::{Vec3, dot, sub};
use motile_particle::model::units::{DEFAULT_DIAMETER, eta};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub fn unit(rng: &mut ChaCha8Rng) -> Vec3 {
    loop {
        let v: Vec3 = [0, 1, 2].map(|_| rng.random_range(-1.0..1.0));
        let n = dot(v, v).sqrt();
        if n > 0.1 && n < 1.0 {
            return v.map(|c| c / n);
        }
    }
}

/// Rod centres and orientations: `n` rods at random, or (`touching`) in pairs of parallel
/// rods whose axes are one diameter (0.2) apart.
pub fn rods(n: usize, l: f64, touching: bool, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut x, mut p) = (Vec::new(), Vec::new());
    while x.len() < n {
        let c: Vec3 = [0, 1, 2].map(|_| rng.random_range(0.0..l));
        let q = unit(&mut rng);
        x.push(c);
        p.push(q);
        if touching && x.len() < n {
            let r = unit(&mut rng);
            let o = sub(r, q.map(|v| v * dot(q, r)));
            let on = dot(o, o).sqrt();
            x.push([0, 1, 2].map(|d| c[d] + 0.2 * o[d] / on));
            p.push(q);
        }
    }
    (x, p)
}

/// What the RPY sum sees for rods: the four half-rod Gauss nodes of each, with the isolated
/// pusher's force density `(U/2 eta) sign(s) p w` (force-free: net force and torque zero) or
/// random forces.
pub fn rod_points(x: &[Vec3], p: &[Vec3], swimming: bool, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let (s, w) = half_rod_rule(4, 1.0);
    let c = 1.0 / (2.0 * eta(DEFAULT_DIAMETER));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut y, mut f) = (Vec::new(), Vec::new());
    for (xn, pn) in x.iter().zip(p) {
        for (sj, wj) in s.iter().zip(&w) {
            y.push([0, 1, 2].map(|d| xn[d] + sj * pn[d]));
            f.push(if swimming {
                pn.map(|v| c * sj.signum() * wj * v)
            } else {
                [0, 1, 2].map(|_| rng.random_range(-1.0..1.0))
            });
        }
    }
    (y, f)
}

/// Max-relative and relative-L2 errors of `fast` against `exact`, each relative to the larger
/// of the exact output's norm and the floor (`floor` per target).
pub fn errors(fast: &[Vec<f64>], exact: &[Vec<f64>], floor: f64) -> (f64, f64) {
    let (mut e2, mut x2, mut emax, mut xmax): (f64, f64, f64, f64) = (0.0, 0.0, 0.0, 0.0);
    for (a, b) in fast.iter().zip(exact) {
        let d: f64 = a.iter().zip(b).map(|(u, v)| (u - v) * (u - v)).sum();
        let n: f64 = b.iter().map(|v| v * v).sum();
        e2 += d;
        x2 += n;
        emax = emax.max(d.sqrt());
        xmax = xmax.max(n.sqrt());
    }
    let count = exact.len() as f64;
    (
        emax / xmax.max(floor),
        e2.sqrt() / x2.sqrt().max(floor * count.sqrt()),
    )
}

pub fn vectors(v: &[Vec3]) -> Vec<Vec<f64>> {
    v.iter().map(|x| x.to_vec()).collect()
}

pub fn matrices(g: &[[Vec3; 3]]) -> Vec<Vec<f64>> {
    g.iter()
        .map(|m| m.iter().flatten().copied().collect())
        .collect()
}

/// The sums' device on `backend`, or `None` after saying why the test is skipped
/// ([`motile_gpu::open_or_skip`]).
#[cfg(feature = "gpu")]
pub fn device(backend: Backend) -> Option<GpuFourier> {
    let d = motile_gpu::open_or_skip(GpuFourier::open(backend), backend)?;
    eprintln!("{backend:?}: {}", d.describe());
    Some(d)
}

/// The host emulation, or `None` after saying why not.
#[cfg(feature = "gpu")]
pub fn emulation() -> Option<GpuFourier> {
    device(Backend::HostEmulation)
}

/// The rods of a resident stepper after `steps` steps against the CPU stepper's `cpu`: the
/// centres and quaternions within 10 times the contact solver's tolerance per step (the device
/// orders its constraints by pair, the CPU by cell) and the same periodic images; returns the
/// largest differences (centres, quaternions). `what` names the case in the messages.
#[cfg(feature = "gpu")]
pub fn assert_device_rods_near(
    device: &motile_particle::step::gpu::DeviceStepper,
    cpu: &motile_particle::model::rods::RodSet,
    (steps, tolerance): (usize, f64),
    what: &str,
) -> (f64, f64) {
    let mut on_device = cpu.clone();
    device.download(&mut on_device).unwrap();
    let (dx, dq) = rods_difference(&on_device, cpu);
    let bound = 10.0 * steps as f64 * tolerance;
    assert!(
        dx <= bound && dq <= bound,
        "{what}: after {steps} steps the centres differ by {dx:.1e} l, the quaternions by \
         {dq:.1e} (bound {bound:.0e})"
    );
    assert_eq!(on_device.image, cpu.image, "{what}: images crossed");
    (dx, dq)
}

/// The largest difference of two copies of the same rods after steps: of the centres (the
/// nearest image, rod lengths) and of the quaternions' components.
pub fn rods_difference(
    a: &motile_particle::model::rods::RodSet,
    b: &motile_particle::model::rods::RodSet,
) -> (f64, f64) {
    let l = a.box_length;
    let dx = (0..a.len())
        .map(|i| {
            let d = motile_particle::model::geometry::min_image(sub(a.x[i], b.x[i]), l);
            dot(d, d).sqrt()
        })
        .fold(0.0, f64::max);
    let dq = (0..a.len())
        .flat_map(|i| (0..4).map(move |d| (i, d)))
        .map(|(i, d)| (a.q[i][d] - b.q[i][d]).abs())
        .fold(0.0, f64::max);
    (dx, dq)
}
