//! The launches of `kernels.cu`: the only unsafe code of the crate. Each states why its
//! arguments match the kernel's parameters and why every index the kernel touches lies inside
//! the buffers it is given (the host emulation also checks the parameter types at run time).
#![allow(unsafe_code)]

use super::Geometry;
use motile_gpu::{Arg, Buffer, Device, GpuError};

fn check(what: &str, buf: &Buffer, at_least: usize) -> Result<(), GpuError> {
    if buf.len() < at_least {
        return Err(GpuError::Input(format!(
            "{what}: {} values where the kernel reads or writes {at_least}",
            buf.len()
        )));
    }
    Ok(())
}

/// Grid indices must fit the kernels' `int`s (and `long long` products).
fn ints(geo: &Geometry, n: usize) -> Result<(i32, i32, i32), GpuError> {
    let to = |v: usize, what: &str| {
        i32::try_from(v).map_err(|_| GpuError::Input(format!("{what} {v} exceeds an int")))
    };
    Ok((
        to(geo.m, "grid size")?,
        to(geo.window.p, "support")?,
        to(12 * n, "12 x points")? / 12,
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
    check("grid", grid, nf * geo.m.pow(3))?;
    let w = &geo.window;
    // SAFETY: spread(const double* pts, const double* vals, double* grid, int n, int nf,
    // int m, int p, double l, double h, double alpha, double norm). Thread i < n reads
    // pts[3 i..3 i + 3] (3 n checked) and vals[c n + i] for c < nf (nf n checked), and adds to
    // grid[c m^3 + idx] with idx < m^3 (every index is reduced into 0..m per axis; nf m^3
    // checked: a support p <= m, asserted, wraps at most once); p <= MAX_SUPPORT = 24 (the
    // window's clamp, asserted) sizes its local arrays.
    unsafe {
        dev.launch(
            "spread",
            n,
            &mut [
                Arg::In(pts),
                Arg::In(vals),
                Arg::Out(grid),
                Arg::Int(ni),
                Arg::Int(nf as i32),
                Arg::Int(m),
                Arg::Int(p),
                Arg::Real(geo.l),
                Arg::Real(w.h),
                Arg::Real(w.alpha),
                Arg::Real(w.norm),
            ],
        )
    }
}

/// The Fourier-space multiplication of a sum.
#[derive(Clone, Copy, Debug)]
pub(super) enum Modes {
    /// RPY velocities of three force spectra (radius `a`).
    Rpy { a: f64 },
    /// Point-force velocities of the force density of six stresslet spectra.
    Stresslet,
}

pub(super) fn modes(
    dev: &Device,
    geo: &Geometry,
    which: Modes,
    input: &Buffer,
    out: &mut Buffer,
) -> Result<(), GpuError> {
    let (m, _, _) = ints(geo, 0)?;
    let slen = geo.m * geo.m * (geo.m / 2 + 1);
    let (kernel, inputs) = match which {
        Modes::Rpy { .. } => ("rpy_modes", 3),
        Modes::Stresslet => ("stresslet_modes", 6),
    };
    check("input spectra", input, 2 * inputs * slen)?;
    check("velocity spectra", out, 6 * slen)?;
    let mut args = vec![
        Arg::In(input),
        Arg::Out(out),
        Arg::Int(m),
        Arg::Real(geo.l),
        Arg::Real(geo.xi),
    ];
    if let Modes::Rpy { a } = which {
        args.push(Arg::Real(a));
    }
    args.extend([Arg::Real(geo.window.eta), Arg::Real(geo.window.h)]);
    // SAFETY: rpy_modes(const double* in, double* out, int m, double l, double xi, double a,
    // double eta, double h) and stresslet_modes(the same without a). Thread s < S =
    // m m (m/2 + 1) reads the pairs 2 (c S + s), +1 of `in` for c < 3 (RPY) or 6 (stresslets)
    // (2 inputs S values checked) and writes them in `out` for c < 3 (6 S checked).
    unsafe { dev.launch(kernel, slen, &mut args) }
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
    check("grid", grid, 3 * geo.m.pow(3))?;
    check("gathered values", out, outputs * n)?;
    let w = &geo.window;
    // SAFETY: gather(const double* pts, const double* grid, double* out, int n, int gradient,
    // int m, int p, double l, double h, double alpha, double norm). Thread i < n reads
    // pts[3 i..3 i + 3] (3 n checked), grid[c m^3 + idx] for c < 3 and idx < m^3 (indices
    // reduced into 0..m per axis, p <= m asserted; 3 m^3 checked), and writes out[c n + i]
    // for c < 3, or 12 with gradient (checked); p <= 24 sizes its local arrays (asserted).
    unsafe {
        dev.launch(
            "gather",
            n,
            &mut [
                Arg::In(pts),
                Arg::In(grid),
                Arg::Out(out),
                Arg::Int(ni),
                Arg::Int(i32::from(gradient)),
                Arg::Int(m),
                Arg::Int(p),
                Arg::Real(geo.l),
                Arg::Real(w.h),
                Arg::Real(w.alpha),
                Arg::Real(w.norm),
            ],
        )
    }
}

/// A real-space sum's inputs in cell order (per point: position, then the kernel's values).
pub(super) struct RealSpace<'a> {
    pub(super) pos: &'a Buffer,
    /// RPY: forces (3 per point); stresslets: orientations (3 per point) and strengths.
    pub(super) values: [&'a Buffer; 2],
    pub(super) group: &'a Buffer,
    pub(super) start: &'a Buffer,
    pub(super) table: &'a Buffer,
    pub(super) npts: usize,
    pub(super) ncell: usize,
    pub(super) nodes: usize,
    /// RPY: `l, cutoff, 1/h, c, ca, cb, a, r0^2`; stresslets: `l, cutoff, 1/h, xi, r_direct,
    /// r0^2`.
    pub(super) reals: Vec<f64>,
}

/// Which real-space sum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Real {
    Rpy,
    Stresslet,
}

pub(super) fn real_space(
    dev: &Device,
    which: Real,
    r: &RealSpace<'_>,
    out: &mut Buffer,
) -> Result<(), GpuError> {
    let n = r.npts;
    let int = |v: usize, what: &str| {
        i32::try_from(v).map_err(|_| GpuError::Input(format!("{what} {v} exceeds an int")))
    };
    let (npts, ncell, nt) = (
        int(n, "points")?,
        int(r.ncell, "cells")?,
        int(r.nodes, "nodes")?,
    );
    let (kernel, per_node, outputs, reals) = match which {
        Real::Rpy => ("rpy_real", 2, 4, 8),
        Real::Stresslet => ("stresslet_real", 5, 13, 6),
    };
    int(outputs * n, "outputs")?;
    assert!(
        r.nodes >= 3 && r.reals.len() == reals,
        "a table of 4 nodes or more, {reals} reals"
    );
    check("positions", r.pos, 3 * n)?;
    check("values", r.values[0], 3 * n)?;
    if which == Real::Stresslet {
        check("strengths", r.values[1], n)?;
    }
    check("groups", r.group, n)?;
    check("cell starts", r.start, r.ncell.pow(3) + 1)?;
    check("table", r.table, per_node * (r.nodes + 1))?;
    check("real-space sums", out, outputs * n)?;
    let mut args = vec![Arg::In(r.pos), Arg::In(r.values[0])];
    if which == Real::Stresslet {
        args.push(Arg::In(r.values[1]));
    }
    args.extend([
        Arg::In(r.group),
        Arg::In(r.start),
        Arg::In(r.table),
        Arg::Out(out),
        Arg::Int(npts),
        Arg::Int(ncell),
        Arg::Int(nt),
    ]);
    args.extend(r.reals.iter().map(|&x| Arg::Real(x)));
    // SAFETY: rpy_real(const double* pos, const double* force, const double* group,
    // const double* start, const double* table, double* out, int npts, int ncell, int nt,
    // double l, double cutoff, double inv_h, double c, double ca, double cb, double a,
    // double r0sq) and stresslet_real(pos, const double* orient, const double* sigma, group,
    // start, table, out, npts, ncell, nt, double l, double cutoff, double inv_h, double xi,
    // double r_direct, double r0sq). Thread t < npts reads pos and the forces or orientations
    // at 3 j..3 j + 3, sigma[j] and group[j] for j < npts (3 n, 3 n, n, n checked); cell
    // indices are clamped into 0..ncell per axis (both ends) and wrapped per neighbour, so
    // start is read at cc and cc + 1 <= ncell^3 (checked), and j runs between two of its
    // entries with the upper one clamped to npts in the kernel (for PointCells' starts, which
    // are non-decreasing and end at npts, the clamp never acts); the table index i is clamped
    // to 0..=nt - 3 and reads
    // per_node (i + 3) + per_node - 1 < per_node (nt + 1) (checked); it writes
    // out[outputs t..outputs (t + 1)] (outputs n checked).
    unsafe { dev.launch(kernel, n, &mut args) }
}
