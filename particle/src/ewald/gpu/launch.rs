//! The launches of `kernels.cu` (with `binned.rs` and `step/gpu`, the crate's only unsafe
//! code). Each states why every index the kernel touches lies inside the buffers it is given;
//! the arguments' number, order and types are the declarations' of `signatures.rs` (checked
//! against `kernels.cu`).
#![allow(unsafe_code)]

use crate::ewald::gpu::signatures::{
    Gather, RpyModes, RpyReal, Spread, StressletModes, StressletReal, StressletRealPoints,
};
use crate::ewald::window::Window;
use motile_gpu::{Buffer, Device, GpuError};

/// Values of one field of a sum's grid in the in-place layout: `m m` rows of `2 (m/2 + 1)`
/// real values (the last `2 (m/2 + 1) - m` unused), or the half spectrum over them.
pub(crate) fn padded_field(m: usize) -> usize {
    2 * m * m * (m / 2 + 1)
}

/// The window and box of one sum.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Geometry {
    pub(crate) window: Window,
    pub(crate) m: usize,
    pub(crate) l: f64,
    pub(crate) xi: f64,
}

use motile_gpu::{check_len as check, kernel_int as int};

/// Grid indices must fit the kernels' `int`s (and `long long` products).
fn ints(geo: &Geometry, n: usize) -> Result<(i32, i32, i32), GpuError> {
    Ok((
        int(geo.m, "grid size")?,
        int(geo.window.p, "support")?,
        int(12 * n, "12 x points")? / 12,
    ))
}

pub(super) fn spread(
    dev: &Device,
    geo: &Geometry,
    pts: &Buffer,
    vals: &Buffer,
    grid: &mut Buffer,
    n: usize,
    nf: usize,
) -> Result<(), GpuError> {
    let (m, p, ni) = ints(geo, n)?;
    assert!(
        nf <= 6 && geo.window.p <= 24,
        "at most six fields, support 24"
    );
    check("points", pts, 3 * n)?;
    check("values", vals, nf * n)?;
    check("grid", grid, nf * padded_field(geo.m))?;
    let w = &geo.window;
    // SAFETY: thread i < n reads pts[3 i..3 i + 3] (3 n checked) and vals[c n + i] for c < nf
    // (nf n checked), and adds to grid[c F + idx] with F = padded_field(m) and idx the padded
    // index of a cell whose indices are reduced into 0..m per axis (idx < F; nf F checked: a
    // support p <= m, asserted, wraps at most once); p <= MAX_SUPPORT = 24 (the window's
    // clamp, asserted) sizes its local arrays.
    unsafe {
        dev.launch(
            n,
            Spread {
                pts,
                vals,
                grid,
                n: ni,
                nf: nf as i32,
                m,
                p,
                l: geo.l,
                h: w.h,
                alpha: w.alpha,
                norm: w.norm,
            },
        )
    }
}

/// The Fourier-space multiplication of a sum.
#[derive(Clone, Copy, Debug)]
pub(super) enum Modes {
    /// RPY velocities of three force spectra (radius `a`).
    Rpy { a: f64 },
    /// Point-force velocities of the force density of [`STRESSLET_FIELDS`] trace-free
    /// stresslet spectra.
    Stresslet,
}

/// The fields a stresslet sum spreads: the trace-free components `xx, yy, xy, xz, yz` (`zz` is
/// `-(xx + yy)`). The trace's flow is zero (its force density `-i s k` is parallel to `k`,
/// which the Stokes projection removes), so a sum holds five grids, not six.
pub const STRESSLET_FIELDS: usize = 5;

/// The Fourier-space multiplication in place: the velocity spectra replace the first three
/// input spectra.
pub(super) fn modes(
    dev: &Device,
    geo: &Geometry,
    which: Modes,
    spectra: &mut Buffer,
) -> Result<(), GpuError> {
    let m = int(geo.m, "grid size")?;
    let slen = geo.m * geo.m * (geo.m / 2 + 1);
    let inputs = match which {
        Modes::Rpy { .. } => 3,
        Modes::Stresslet => STRESSLET_FIELDS,
    };
    check("spectra", spectra, 2 * inputs * slen)?;
    let (l, xi, eta, h) = (geo.l, geo.xi, geo.window.eta, geo.window.h);
    // SAFETY: thread s < S = m m (m/2 + 1) reads the pairs 2 (c S + s), +1 for c < 3 (RPY) or
    // 5 (stresslets) (2 inputs S values checked), then writes them for c < 3: every thread
    // touches only its own mode s.
    unsafe {
        match which {
            Modes::Rpy { a } => dev.launch(
                slen,
                RpyModes {
                    spectra,
                    m,
                    l,
                    xi,
                    a,
                    eta,
                    h,
                },
            ),
            Modes::Stresslet => dev.launch(
                slen,
                StressletModes {
                    spectra,
                    m,
                    l,
                    xi,
                    eta,
                    h,
                },
            ),
        }
    }
}

pub(super) fn gather(
    dev: &Device,
    geo: &Geometry,
    pts: &Buffer,
    grid: &Buffer,
    out: &mut Buffer,
    n: usize,
    gradient: bool,
) -> Result<(), GpuError> {
    let (m, p, ni) = ints(geo, n)?;
    assert!(
        geo.window.p <= 24 && geo.window.p <= geo.m,
        "a support of at most 24 and at most the grid"
    );
    let outputs = if gradient { 12 } else { 3 };
    check("points", pts, 3 * n)?;
    check("grid", grid, 3 * padded_field(geo.m))?;
    check("gathered values", out, outputs * n)?;
    let w = &geo.window;
    // SAFETY: thread i < n reads pts[3 i..3 i + 3] (3 n checked), grid[c F + idx] for c < 3 with
    // F = padded_field(m) and idx the padded index of a cell reduced into 0..m per axis (p <= m
    // asserted; 3 F checked), and writes out[c n + i] for c < 3, or 12 with gradient
    // (checked); it keeps no local arrays.
    unsafe {
        dev.launch(
            n,
            Gather {
                pts,
                grid,
                out,
                n: ni,
                gradient: i32::from(gradient),
                m,
                p,
                l: geo.l,
                h: w.h,
                alpha: w.alpha,
                norm: w.norm,
            },
        )
    }
}

/// A real-space sum's inputs in cell order (per point: position, then the kernel's values).
pub(super) struct RealSpace<'a> {
    pub(super) pos: &'a Buffer,
    pub(super) group: &'a Buffer<i32>,
    pub(super) start: &'a Buffer<i32>,
    pub(super) table: &'a Buffer,
    pub(super) npts: usize,
    pub(super) ncell: usize,
    pub(super) nodes: usize,
    /// Box side, cutoff and the table's `1/h`.
    pub(super) l: f64,
    pub(super) cutoff: f64,
    pub(super) inv_h: f64,
    /// The error model's squared range.
    pub(super) r0sq: f64,
}

/// Which real-space sum, with its own values and constants.
#[derive(Clone, Copy, Debug)]
pub(super) enum Real<'a> {
    /// RPY: forces (3 per point), the table's constants `c, ca, cb` and the radius `a`.
    Rpy {
        force: &'a Buffer,
        c: f64,
        ca: f64,
        cb: f64,
        a: f64,
    },
    /// Stresslets: orientations (3 per point), strengths, the splitting `xi` and the direct
    /// range.
    Stresslet {
        orient: &'a Buffer,
        sigma: &'a Buffer,
        xi: f64,
        r_direct: f64,
    },
}

/// The stresslet sum's real-space outputs in the points' own order: the point
/// `i = members[t]` (the `t`-th in cell order) gets its velocity at `u[3 i..3 i + 3]`, its
/// gradient at `grad[9 i..9 i + 9]` and its weighted strengths at `weighted[i]`.
pub(super) struct PointOutputs<'a> {
    pub(super) members: &'a Buffer<i32>,
    pub(super) u: &'a mut Buffer,
    pub(super) grad: &'a mut Buffer,
    pub(super) weighted: &'a mut Buffer,
}

/// Stresslets of one strength for [`stresslet_real_points`]: their orientations (3 per point,
/// cell order), the strength, and the table's splitting and direct range.
#[derive(Clone, Copy, Debug)]
pub(super) struct OneStrength<'a> {
    /// Orientations, 3 per point in cell order.
    pub(super) orient: &'a Buffer,
    /// The strength of every stresslet.
    pub(super) sigma: f64,
    /// The splitting parameter.
    pub(super) xi: f64,
    /// The direct range of the table.
    pub(super) r_direct: f64,
}

/// The real-space sum of stresslets of one strength `sigma` with orientations `orient` (cell
/// order), the splitting `xi` and the direct range `r_direct`, written straight to the points'
/// order (no 13-value copy in cell order and no permutation after it, no strength per point).
pub(super) fn stresslet_real_points(
    dev: &Device,
    stresslets: OneStrength<'_>,
    r: &RealSpace<'_>,
    out: PointOutputs<'_>,
) -> Result<(), GpuError> {
    let OneStrength {
        orient,
        sigma,
        xi,
        r_direct,
    } = stresslets;
    let n = r.npts;
    let (npts, ncell, nt) = check_real(5, r, 13)?;
    check("orientations", orient, 3 * n)?;
    check("members", out.members, n)?;
    check("velocities", out.u, 3 * n)?;
    check("gradients", out.grad, 9 * n)?;
    check("weighted strengths", out.weighted, n)?;
    let (pos, group, start, table) = (r.pos, r.group, r.start, r.table);
    // SAFETY: as `real_space`'s stresslet sum (the reads checked above, no strengths read),
    // and thread t then reads members[t] (n checked), a permutation of 0..n (the cells'
    // members: every point once), and writes its point's u (3), grad (9) and weighted (1)
    // values (3 n, 9 n, n checked): no two threads write the same place.
    unsafe {
        dev.launch(
            n,
            StressletRealPoints {
                pos,
                orient,
                sigma,
                group,
                start,
                table,
                members: out.members,
                u: out.u,
                grad: out.grad,
                weighted: out.weighted,
                npts,
                ncell,
                nt,
                l: r.l,
                cutoff: r.cutoff,
                inv_h: r.inv_h,
                xi,
                r_direct,
                r0sq: r.r0sq,
            },
        )
    }
}

/// The checks of a real-space sum's common inputs (a table of `per_node` values per node,
/// `outputs` values per point): the kernel's point, cell and node counts.
fn check_real(
    per_node: usize,
    r: &RealSpace<'_>,
    outputs: usize,
) -> Result<(i32, i32, i32), GpuError> {
    let n = r.npts;
    let counts = (
        int(n, "points")?,
        int(r.ncell, "cells")?,
        int(r.nodes, "nodes")?,
    );
    int(outputs * n, "outputs")?;
    assert!(r.nodes >= 3, "a table of 4 nodes or more");
    check("positions", r.pos, 3 * n)?;
    check("groups", r.group, n)?;
    check("cell starts", r.start, r.ncell.pow(3) + 1)?;
    check("table", r.table, per_node * (r.nodes + 1))?;
    Ok(counts)
}

pub(super) fn real_space(
    dev: &Device,
    which: Real<'_>,
    r: &RealSpace<'_>,
    out: &mut Buffer,
) -> Result<(), GpuError> {
    let n = r.npts;
    let (per_node, outputs) = match which {
        Real::Rpy { .. } => (2, 4),
        Real::Stresslet { .. } => (5, 13),
    };
    let (npts, ncell, nt) = check_real(per_node, r, outputs)?;
    match which {
        Real::Rpy { force, .. } => check("forces", force, 3 * n)?,
        Real::Stresslet { orient, sigma, .. } => {
            check("orientations", orient, 3 * n)?;
            check("strengths", sigma, n)?;
        }
    }
    check("real-space sums", out, outputs * n)?;
    let (pos, group, start, table) = (r.pos, r.group, r.start, r.table);
    let (l, cutoff, inv_h, r0sq) = (r.l, r.cutoff, r.inv_h, r.r0sq);
    // SAFETY: thread t < npts reads pos and the forces or orientations at 3 j..3 j + 3,
    // sigma[j] and group[j] for j < npts (3 n, 3 n, n, n checked); cell indices are clamped
    // into 0..ncell per axis (both ends) and wrapped per neighbour, so start is read at cc and
    // cc + 1 <= ncell^3 (checked), and j runs between two of its entries with the upper one
    // clamped to npts in the kernel (for PointCells' starts, which are non-decreasing and end
    // at npts, the clamp never acts); the table index i is clamped to 0..=nt - 3 and reads
    // per_node (i + 3) + per_node - 1 < per_node (nt + 1) (checked); it writes
    // out[outputs t..outputs (t + 1)] (outputs n checked).
    unsafe {
        match which {
            Real::Rpy {
                force,
                c,
                ca,
                cb,
                a,
            } => dev.launch(
                n,
                RpyReal {
                    pos,
                    force,
                    group,
                    start,
                    table,
                    out,
                    npts,
                    ncell,
                    nt,
                    l,
                    cutoff,
                    inv_h,
                    c,
                    ca,
                    cb,
                    a,
                    r0sq,
                },
            ),
            Real::Stresslet {
                orient,
                sigma,
                xi,
                r_direct,
            } => dev.launch(
                n,
                StressletReal {
                    pos,
                    orient,
                    sigma,
                    group,
                    start,
                    table,
                    out,
                    npts,
                    ncell,
                    nt,
                    l,
                    cutoff,
                    inv_h,
                    xi,
                    r_direct,
                    r0sq,
                },
            ),
        }
    }
}

/// `n` points on the device (triples).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Points<'a> {
    /// The positions, `3 n` values.
    pub(crate) pos: &'a Buffer,
    /// How many points.
    pub(crate) n: usize,
}

/// Values spread from the points: `nf` fields, field-major (`nf n` values).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fields<'a> {
    /// The values.
    pub(crate) vals: &'a Buffer,
    /// How many fields.
    pub(crate) nf: usize,
}

/// Which Fourier part a sum takes: the multiplication of the spectra, and whether the gather
/// adds the gradients (12 values per point instead of 3).
#[derive(Clone, Copy, Debug)]
pub(super) struct FourierKind {
    /// The multiplication of the spectra.
    pub(super) modes: Modes,
    /// Whether the gather adds the gradients.
    pub(super) gradient: bool,
}

/// Points with axes on the device, triples: stresslets at `centres` oriented along `axes`, or
/// rods' centres and axes.
#[derive(Clone, Copy, Debug)]
pub struct OrientedPoints<'a> {
    /// The points (rods' centres), 3 per point.
    pub centres: &'a Buffer,
    /// The unit axes, 3 per point.
    pub axes: &'a Buffer,
}

/// Points and the forces on them on the device: the forces as triples, and again field-major.
#[derive(Clone, Copy, Debug)]
pub struct PointForces<'a> {
    /// The points, 3 per point.
    pub points: &'a Buffer,
    /// The forces, 3 per point.
    pub forces: &'a Buffer,
    /// The forces field-major: each component's `n` values in turn.
    pub fields: &'a Buffer,
}
