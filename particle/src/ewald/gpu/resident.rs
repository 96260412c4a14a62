//! The sums with their points, values and results on the device (`resident.cu`): for the
//! particle step resident on a GPU, whose rods never leave the device between outputs. The
//! point cell list of the real-space part is built on the device (the twin of
//! [`PointCells::build`](crate::ewald::point_cells::PointCells): the same cells, each one's
//! points in increasing index, so the same neighbours in the same order); the stresslet sum
//! is assembled there (the CPU's `stresslet_attempt` pass after the Fourier part) and its error
//! model reduced there in the CPU's fixed chunks, so the host reads a few numbers per chunk
//! and decides, as for the CPU's sums, whether the attempt stands.
#![allow(unsafe_code)]

use super::GpuFourier;
use super::launch::{self, Geometry, STRESSLET_FIELDS};
use super::launch::{Fields, FourierKind, OrientedPoints, PointForces, Points};
use super::signatures::{
    BinOrder, BinScatter, EstimateChunks, JefferyVelocities, MemberGroup, NodeValues, PermuteRows,
    PointCell, RodAxes, RodFlowVelocities, RpyAssemble, StressletAssemble, StressletValues,
};
use crate::ewald::kernels::{RealSpaceTable, StressletTable};
use motile_gpu::check_len;
use motile_gpu::{Buffer, GpuError, kernel_int as int};

/// The point cell list on the device: positions wrapped and in cell order, each one's group,
/// the cells' starts and members (the points' indices in cell order).
#[derive(Debug)]
pub(crate) struct ResidentCells {
    pub(crate) pos: Buffer,
    pub(crate) group: Buffer<i32>,
    pub(crate) start: Buffer<i32>,
    pub(crate) members: Buffer<i32>,
    /// Cells per axis.
    pub(crate) n: usize,
}

/// A stresslet sum's results on the device, and its error model's reductions.
#[derive(Debug)]
pub(crate) struct ResidentStresslets {
    /// Velocities (triples) and gradients (9 per point, `du_i/dx_m` at `3 i + m`), divided by
    /// the viscosity.
    pub(crate) u: Buffer,
    pub(crate) grad: Buffer,
    /// The estimate's reductions per output (velocity, gradient) and chunk.
    pub(crate) reductions: [Vec<[f64; 4]>; 2],
}

/// The quadrature rule along a rod: node positions `s_j` (arc length from the centre) and
/// weights `w_j`, as many of each.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rule<'a> {
    /// The nodes' positions along the rod.
    pub(crate) s: &'a [f64],
    /// The nodes' weights.
    pub(crate) w: &'a [f64],
}

/// How the rods swim: their swimming speed and their length.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Swimming {
    /// The swimming speed along the axis.
    pub(crate) speed: f64,
    /// The rods' length.
    pub(crate) length: f64,
}

/// What a resident RPY sum needs besides its points: the real-space table, cutoff and
/// error-model range, the radius, the group size (points per rod), the viscosity and the error
/// model's weights.
pub(crate) struct RpyInputs<'a> {
    pub(crate) table: &'a RealSpaceTable,
    pub(crate) cutoff: f64,
    pub(crate) r0: f64,
    pub(crate) a: f64,
    pub(crate) group: usize,
    pub(crate) mu: f64,
    pub(crate) weights: [f64; 3],
    /// Points per chunk of the error model's reductions.
    pub(crate) chunk: usize,
}

/// What a resident stresslet sum needs besides its points: the real-space table, cutoff and
/// error-model range, the strength (one for all), the Fourier part's own-gradient
/// coefficient and the viscosity, and the error model's weights per output.
pub(crate) struct StressletInputs<'a> {
    pub(crate) table: &'a StressletTable,
    pub(crate) cutoff: f64,
    pub(crate) r0: f64,
    pub(crate) sigma: f64,
    pub(crate) own_c: f64,
    pub(crate) mu: f64,
    pub(crate) weights: [[f64; 3]; 2],
    /// Points per chunk of the error model's reductions.
    pub(crate) chunk: usize,
}

impl GpuFourier {
    /// The point cell list of the `npts` points `y` (triples) for a real-space cutoff `cutoff`
    /// in a box of side `l`, points `group` at a time forming a group: [`PointCells::build`]'s
    /// cells (`floor(2 L / cutoff)` per axis, at least one), built here.
    ///
    /// [`PointCells::build`]: crate::ewald::point_cells::PointCells
    pub(crate) fn resident_cells(
        &self,
        y: &Buffer,
        npts: usize,
        l: f64,
        cutoff: f64,
        group: usize,
    ) -> Result<ResidentCells, GpuError> {
        let nc = ((2.0 * l / cutoff).floor() as usize).max(1);
        let ncells = nc.pow(3);
        let (ni, nci, ncells_i, gi) = (
            int(npts, "points")?,
            int(nc, "cells per axis")?,
            int(ncells, "cells")?,
            int(group.max(1), "group size")?,
        );
        int(3 * npts, "3 x points")?;
        check_len("points", y, 3 * npts)?;
        let dev = &self.dev;
        let mut wrapped = dev.zeros::<f64>(3 * npts)?;
        let mut cell = dev.zeros::<i32>(npts)?;
        let mut rank = dev.zeros::<i32>(npts)?;
        let mut count = dev.zeros::<i32>(ncells)?;
        let mut start = dev.zeros::<i32>(ncells + 1)?;
        let mut members = dev.zeros::<i32>(npts)?;
        // SAFETY: thread i < npts reads y[3 i..3 i + 3] (checked), writes wrapped there (3 n),
        // cell[i], rank[i] (n) and adds to count[k]: each axis index is clamped to 0..nc in the
        // kernel (both ends: a coordinate that is not finite truncates to anything), so
        // k < nc^3 (allocated).
        unsafe {
            dev.launch(
                npts,
                PointCell {
                    y,
                    wrapped: &mut wrapped,
                    cell: &mut cell,
                    rank: &mut rank,
                    count: &mut count,
                    n: ni,
                    nc: nci,
                    l,
                },
            )?;
        }
        super::scan::prefix_sum(dev, &count, &mut start, ncells)?;
        // SAFETY: thread i < npts reads cell[i] < ncells, rank[i], start[cell] and writes
        // members[start[cell] + rank] < start[cell + 1] <= npts (ranks are 0..count).
        unsafe {
            dev.launch(
                npts,
                BinScatter {
                    bin: &cell,
                    rank: &rank,
                    start: &start,
                    perm: &mut members,
                    n: ni,
                },
            )?;
        }
        // SAFETY: thread k < ncells permutes members between start[k] and start[k + 1] (<=
        // npts, allocated ncells + 1).
        unsafe {
            dev.launch(
                ncells,
                BinOrder {
                    start: &start,
                    perm: &mut members,
                    nbins: ncells_i,
                },
            )?;
        }
        let pos = self.permute_rows(&wrapped, &members, npts, 3, false)?;
        let mut groups = dev.zeros::<i32>(npts)?;
        // SAFETY: thread k < npts reads members[k] and writes group[k] (npts each).
        unsafe {
            dev.launch(
                npts,
                MemberGroup {
                    members: &members,
                    group: &mut groups,
                    n: ni,
                    size: gi,
                },
            )?;
        }
        Ok(ResidentCells {
            pos,
            group: groups,
            start,
            members,
            n: nc,
        })
    }

    /// What the device has been asked to do so far.
    pub(crate) fn counters(&self) -> motile_gpu::Counters {
        self.dev.counters()
    }

    /// Values onto the device.
    pub(crate) fn upload(&self, values: &[f64]) -> Result<Buffer, GpuError> {
        self.dev.upload(values)
    }

    /// A buffer's values on the host.
    pub(crate) fn download(&self, buf: &Buffer) -> Result<Vec<f64>, GpuError> {
        self.dev.download(buf)
    }

    /// `out[k] = rows[idx[k]]`, `width` values per row, for `n` rows (`idx` a permutation of
    /// `0..n`: the cells' members), or with `scatter` `out[idx[k]] = rows[k]` (back to the
    /// points' order).
    pub(crate) fn permute_rows(
        &self,
        rows: &Buffer,
        idx: &Buffer<i32>,
        n: usize,
        width: usize,
        scatter: bool,
    ) -> Result<Buffer, GpuError> {
        check_len("rows", rows, width * n)?;
        check_len("indices", idx, n)?;
        let mut out = self.dev.zeros::<f64>(width * n)?;
        // SAFETY: thread k < n reads idx[k] (n checked), a permutation of 0..n (the cells'
        // members: every point once), and moves the row of width values between k and idx[k]
        // (both below n; width n checked and allocated).
        unsafe {
            self.dev.launch(
                n,
                PermuteRows {
                    rows_in: rows,
                    idx,
                    rows_out: &mut out,
                    n: int(n, "rows")?,
                    width: int(width, "row width")?,
                    scatter: i32::from(scatter),
                },
            )?;
        }
        Ok(out)
    }

    /// The axes of `n` rods from their quaternions `q` (4 per rod).
    pub(crate) fn rod_axes(&self, q: &Buffer, n: usize) -> Result<Buffer, GpuError> {
        check_len("quaternions", q, 4 * n)?;
        let mut p = self.dev.zeros::<f64>(3 * n)?;
        // SAFETY: thread r < n reads q[4 r..4 r + 4] (checked) and writes p[3 r..3 r + 3].
        unsafe {
            self.dev.launch(
                n,
                RodAxes {
                    q,
                    p: &mut p,
                    n: int(n, "rods")?,
                },
            )?;
        }
        Ok(p)
    }

    /// The dipole level's free velocities `(v, w)` of `n` rods with axes `p` in the flow `u`
    /// with gradient `grad` (as [`ResidentStresslets`]), swimming at `swim`.
    pub(crate) fn jeffery_velocities(
        &self,
        p: &Buffer,
        u: &Buffer,
        grad: &Buffer,
        n: usize,
        swim: f64,
    ) -> Result<(Buffer, Buffer), GpuError> {
        check_len("axes", p, 3 * n)?;
        check_len("velocities", u, 3 * n)?;
        check_len("gradients", grad, 9 * n)?;
        let dev = &self.dev;
        let (mut v, mut w) = (dev.zeros::<f64>(3 * n)?, dev.zeros::<f64>(3 * n)?);
        // SAFETY: thread t < n reads p, u at 3 t..3 t + 3 and grad at 9 t..9 t + 9 (checked)
        // and writes v, w at 3 t..3 t + 3 (3 n each).
        unsafe {
            dev.launch(
                n,
                JefferyVelocities {
                    p,
                    u,
                    grad,
                    v: &mut v,
                    w: &mut w,
                    n: int(n, "rods")?,
                    swim,
                },
            )?;
        }
        Ok((v, w))
    }

    /// One attempt of the stresslet sum of `n` stresslets `sigma p p` at the `stresslets`'
    /// centres `x` with axes `p` (triples, on this device), with the parameters of `geo` and
    /// `inp`: the velocities and gradients left on the device, the error model's reductions read
    /// back.
    pub(crate) fn stresslet_resident(
        &mut self,
        generation: u64,
        geo: &Geometry,
        inp: &StressletInputs<'_>,
        stresslets: OrientedPoints<'_>,
        n: usize,
    ) -> Result<ResidentStresslets, GpuError> {
        let OrientedPoints {
            centres: x,
            axes: p,
        } = stresslets;
        let ni = int(n, "points")?;
        int(13 * n, "13 x points")?;
        check_len("points", x, 3 * n)?;
        check_len("axes", p, 3 * n)?;
        // The real-space part over the device's cell list, written in the points' order.
        let cells = self.resident_cells(x, n, geo.l, inp.cutoff, 1)?;
        let orient = self.permute_rows(p, &cells.members, n, 3, false)?;
        let table = &inp.table;
        let (inv_h, nodes, xi, r_direct, g) = table.parts();
        let table_buf = self.dev.upload(&g)?;
        let dev = &self.dev;
        let mut u = dev.zeros::<f64>(3 * n)?;
        let mut grad = dev.zeros::<f64>(9 * n)?;
        let mut weighted = dev.zeros::<f64>(n)?;
        let real_in = launch::RealSpace {
            pos: &cells.pos,
            group: &cells.group,
            start: &cells.start,
            table: &table_buf,
            npts: n,
            ncell: cells.n,
            nodes,
            l: geo.l,
            cutoff: inp.cutoff,
            inv_h,
            r0sq: inp.r0 * inp.r0,
        };
        launch::stresslet_real_points(
            dev,
            launch::OneStrength {
                orient: &orient,
                sigma: inp.sigma,
                xi,
                r_direct,
            },
            &real_in,
            launch::PointOutputs {
                members: &cells.members,
                u: &mut u,
                grad: &mut grad,
                weighted: &mut weighted,
            },
        )?;
        // What only the real-space part needed goes before the Fourier part's bins and gather.
        drop((orient, cells, table_buf));
        // The Fourier part: the trace-free components, spread and dropped before the gather.
        let mut vals = self.dev.zeros::<f64>(STRESSLET_FIELDS * n)?;
        // SAFETY: thread t < n reads p[3 t..3 t + 3] (checked) and writes vals[c n + t] for
        // c < 5 (STRESSLET_FIELDS n).
        unsafe {
            self.dev.launch(
                n,
                StressletValues {
                    p,
                    sigma: inp.sigma,
                    vals: &mut vals,
                    n: ni,
                },
            )?;
        }
        let points = Points { pos: x, n };
        let fields = Fields {
            vals: &vals,
            nf: STRESSLET_FIELDS,
        };
        self.spread(generation, geo, points, fields)?;
        drop(vals);
        let kind = FourierKind {
            modes: launch::Modes::Stresslet,
            gradient: true,
        };
        let back = self.fourier_spread(geo, points, STRESSLET_FIELDS, kind)?;
        // Assembly (on the real part's velocities and gradients) and the error model.
        let dev = &self.dev;
        let mut parts = dev.zeros::<f64>(4 * n)?;
        // SAFETY: thread t < n reads weighted[t] (n, made above), back[c n + t] for c < 12 (the
        // gather's 12 n), p (3 n checked), and reads and writes u (3 n), grad (9 n) and writes
        // parts (4 n) at its own point.
        unsafe {
            dev.launch(
                n,
                StressletAssemble {
                    weighted: &weighted,
                    back: &back,
                    p,
                    u: &mut u,
                    grad: &mut grad,
                    parts: &mut parts,
                    n: ni,
                    sigma: inp.sigma,
                    own_c: inp.own_c,
                    mu: inp.mu,
                },
            )?;
        }
        let mut reductions = self.estimate_reductions(&parts, n, &inp.weights, inp.chunk)?;
        let g = reductions.pop().expect("two outputs");
        let v = reductions.pop().expect("two outputs");
        Ok(ResidentStresslets {
            u,
            grad,
            reductions: [v, g],
        })
    }

    /// The explicit level's nodes of `n` `rods` with centres `x` and axes `p` (triples on this
    /// device), `m = s.len()` per rod at `x + s_j p` (the `rule`'s nodes `s` and weights `w`),
    /// and their weighted forces `(c sign(s_j) p) w_j`: `(nodes, forces)` as triples and the
    /// forces field-major.
    pub(crate) fn node_values(
        &self,
        rods: OrientedPoints<'_>,
        rule: Rule<'_>,
        n: usize,
        c: f64,
    ) -> Result<(Buffer, Buffer, Buffer), GpuError> {
        let OrientedPoints {
            centres: x,
            axes: p,
        } = rods;
        let Rule { s, w } = rule;
        let m = s.len();
        assert_eq!(w.len(), m, "a weight per node");
        check_len("centres", x, 3 * n)?;
        check_len("axes", p, 3 * n)?;
        int(3 * n * m, "3 x nodes")?;
        let dev = &self.dev;
        let (sb, wb) = (dev.upload(s)?, dev.upload(w)?);
        let mut nodes = dev.zeros::<f64>(3 * n * m)?;
        let mut force = dev.zeros::<f64>(3 * n * m)?;
        let mut fields = dev.zeros::<f64>(3 * n * m)?;
        // SAFETY: thread k < n m reads x, p at 3 (k / m)..+3 (3 n checked), s[k % m], w[k % m]
        // (m uploaded) and writes nodes, force at 3 k..3 k + 3 and fields at d n m + k (3 n m
        // each).
        unsafe {
            dev.launch(
                n * m,
                NodeValues {
                    x,
                    p,
                    s: &sb,
                    w: &wb,
                    nodes: &mut nodes,
                    force: &mut force,
                    fields: &mut fields,
                    n: int(n, "rods")?,
                    m: int(m, "nodes per rod")?,
                    c,
                },
            )?;
        }
        Ok((nodes, force, fields))
    }

    /// The rods' velocities `(v, w)` from the flow `u` at their `m = s.len()` nodes each, the
    /// rods' axes `p` (swimming at `swimming.speed` plus the rigid-body projection over the
    /// rule `(s, w)` of rods of length `swimming.length`).
    pub(crate) fn rod_flow_velocities(
        &self,
        p: &Buffer,
        u: &Buffer,
        rule: Rule<'_>,
        n: usize,
        swimming: Swimming,
    ) -> Result<(Buffer, Buffer), GpuError> {
        let Rule { s, w } = rule;
        let Swimming {
            speed: swim,
            length: rod,
        } = swimming;
        let m = s.len();
        assert_eq!(w.len(), m, "a weight per node");
        check_len("axes", p, 3 * n)?;
        check_len("flow", u, 3 * n * m)?;
        let dev = &self.dev;
        let (sb, wb) = (dev.upload(s)?, dev.upload(w)?);
        let (mut v, mut omega) = (dev.zeros::<f64>(3 * n)?, dev.zeros::<f64>(3 * n)?);
        // SAFETY: thread r < n reads u at 3 (r m + j)..+3 for j < m (3 n m checked), s, w (m
        // uploaded), p at 3 r..3 r + 3 (3 n checked) and writes v, omega there (3 n each).
        unsafe {
            dev.launch(
                n,
                RodFlowVelocities {
                    p,
                    u,
                    s: &sb,
                    w: &wb,
                    v: &mut v,
                    omega: &mut omega,
                    n: int(n, "rods")?,
                    m: int(m, "nodes per rod")?,
                    swim,
                    rod,
                },
            )?;
        }
        Ok((v, omega))
    }

    /// One attempt of the RPY sum of the `n` points of `sources` with their forces (triples,
    /// and field-major) on this device: the velocities left there, the error model's
    /// reductions read back.
    pub(crate) fn rpy_resident(
        &mut self,
        generation: u64,
        geo: &Geometry,
        inp: &RpyInputs<'_>,
        sources: PointForces<'_>,
        n: usize,
    ) -> Result<(Buffer, Vec<[f64; 4]>), GpuError> {
        let PointForces {
            points: pts,
            forces: force,
            fields,
        } = sources;
        let ni = int(n, "points")?;
        int(4 * n, "4 x points")?;
        check_len("points", pts, 3 * n)?;
        check_len("forces", force, 3 * n)?;
        check_len("force fields", fields, 3 * n)?;
        if inp.group == 0 || !n.is_multiple_of(inp.group) {
            return Err(GpuError::Input(format!(
                "{n} points do not split into groups of {}",
                inp.group
            )));
        }
        let cells = self.resident_cells(pts, n, geo.l, inp.cutoff, inp.group)?;
        let sorted_force = self.permute_rows(force, &cells.members, n, 3, false)?;
        let (inv_h, nodes, [c, ca, cb], g) = inp.table.parts();
        let table_buf = self.dev.upload(&g)?;
        let mut sorted = self.dev.zeros::<f64>(4 * n)?;
        let real_in = launch::RealSpace {
            pos: &cells.pos,
            group: &cells.group,
            start: &cells.start,
            table: &table_buf,
            npts: n,
            ncell: cells.n,
            nodes,
            l: geo.l,
            cutoff: inp.cutoff,
            inv_h,
            r0sq: inp.r0 * inp.r0,
        };
        launch::real_space(
            &self.dev,
            launch::Real::Rpy {
                force: &sorted_force,
                c,
                ca,
                cb,
                a: inp.a,
            },
            &real_in,
            &mut sorted,
        )?;
        let real = self.permute_rows(&sorted, &cells.members, n, 4, true)?;
        drop((sorted, sorted_force, cells));
        let back = self.fourier(
            generation,
            geo,
            Points { pos: pts, n },
            Fields {
                vals: fields,
                nf: 3,
            },
            FourierKind {
                modes: launch::Modes::Rpy { a: inp.a },
                gradient: false,
            },
        )?;
        let dev = &self.dev;
        let mut u = dev.zeros::<f64>(3 * n)?;
        let mut parts = dev.zeros::<f64>(2 * n)?;
        // SAFETY: thread t < n reads real[4 t..4 t + 4] (4 n, made above), back[d n + t] for
        // d < 3 (the gather's 3 n), pts and force at 3 j..3 j + 3 for j in its group (< n: n a
        // multiple of the group, checked; 3 n checked), and writes u (3 n) and parts (2 n) at
        // its point.
        unsafe {
            dev.launch(
                n,
                RpyAssemble {
                    real: &real,
                    back: &back,
                    pts,
                    force,
                    u: &mut u,
                    parts: &mut parts,
                    n: ni,
                    g: int(inp.group, "group")?,
                    l: geo.l,
                    xi: geo.xi,
                    a: inp.a,
                    r0sq: inp.r0 * inp.r0,
                    mu: inp.mu,
                },
            )?;
        }
        let mut reductions = self.estimate_reductions(&parts, n, &[inp.weights], inp.chunk)?;
        Ok((u, reductions.pop().expect("one output")))
    }

    /// The error model's reductions (the CPU's `estimate_parts`) of `weights.len()` outputs
    /// over `n` points from `parts` (per point and output: weighted strengths, squared
    /// output), per chunk of `chunk` points in order: for each output, each chunk's
    /// `[max, sum, max, sum]`.
    fn estimate_reductions(
        &self,
        parts: &Buffer,
        n: usize,
        weights: &[[f64; 3]],
        chunk: usize,
    ) -> Result<Vec<Vec<[f64; 4]>>, GpuError> {
        let nout = weights.len();
        check_len("estimate inputs", parts, 2 * nout * n)?;
        let nchunks = n.div_ceil(chunk).max(1);
        let dev = &self.dev;
        let w = dev.upload(weights.as_flattened())?;
        let mut out = dev.zeros::<f64>(4 * nout * nchunks)?;
        // SAFETY: block c < ceil(n / chunk) (its first thread; THREADS per block) reads parts
        // at 2 nout t..2 nout (t + 1) for t in its chunk (< n; 2 nout n checked), w[0..3 nout]
        // (uploaded) and writes out at 4 (nout c + o)..+4 for o < nout (4 nout nchunks).
        unsafe {
            dev.launch(
                nchunks * motile_gpu::THREADS as usize,
                EstimateChunks {
                    parts,
                    w: &w,
                    out: &mut out,
                    n: int(n, "points")?,
                    nout: int(nout, "outputs")?,
                    chunk: int(chunk, "chunk")?,
                },
            )?;
        }
        let chunks = dev.download(&out)?;
        Ok((0..nout)
            .map(|o| {
                (0..n.div_ceil(chunk))
                    .map(|c| {
                        let at = 4 * (nout * c + o);
                        [chunks[at], chunks[at + 1], chunks[at + 2], chunks[at + 3]]
                    })
                    .collect()
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ewald::gpu::scan::SCAN_ONE_BLOCK;
    use crate::ewald::point_cells::PointCells;
    use crate::model::geometry::Vec3;
    use motile_gpu::Backend;
    use rand::{RngExt, SeedableRng};

    /// The device's point cell list is [`PointCells::build`]'s bit for bit (starts, members,
    /// wrapped positions in cell order, groups): points of rods' nodes reaching out of the box
    /// on both sides, points on the faces (a coordinate a rounding error below 0 wraps to L,
    /// stored as 0), boxes of fewer and more than five cells per axis, groups of 1 and 4; the
    /// blocks in order and shuffled (the scatter's atomics then take other orders).
    #[test]
    fn resident_cells_are_the_host_point_cells_on_the_emulation() {
        let gpu = match GpuFourier::open(Backend::HostEmulation) {
            Ok(g) => g,
            Err(e) if std::env::var("MOTILE_REQUIRE_CXX").is_err() => {
                eprintln!("skipped ({e}); set MOTILE_REQUIRE_CXX=1 to make this a failure");
                return;
            }
            Err(e) => panic!("{e} (and MOTILE_REQUIRE_CXX is set)"),
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(29);
        for (l, cutoff, n, group) in [
            (6.0, 0.7, 800, 1),
            (6.0, 0.7, 800, 4),
            (3.0, 1.4, 200, 1),
            (10.0, 0.9, 1200, 4),
        ] {
            let mut y: Vec<Vec3> = (0..n)
                .map(|_| std::array::from_fn(|_| rng.random_range(-0.6..l + 0.6)))
                .collect();
            y[0] = [0.0, l, -1e-17];
            y[1] = [l - 1e-15, 0.5 * l, l];
            let host = PointCells::build(&y, l, cutoff, group);
            for seed in [0, 11] {
                gpu.shuffle_blocks(seed);
                let dev = gpu.dev.upload(y.as_flattened()).unwrap();
                let cells = gpu.resident_cells(&dev, n, l, cutoff, group).unwrap();
                let what =
                    format!("L {l}, cutoff {cutoff}, {n} points, group {group}, seed {seed}");
                assert_eq!(cells.n, host.n, "{what}: cells per axis");
                let start: Vec<usize> = gpu
                    .dev
                    .download(&cells.start)
                    .unwrap()
                    .iter()
                    .map(|&s| s as usize)
                    .collect();
                assert_eq!(start, host.start, "{what}: cell starts");
                let members: Vec<u32> = gpu
                    .dev
                    .download(&cells.members)
                    .unwrap()
                    .iter()
                    .map(|&m| m as u32)
                    .collect();
                assert_eq!(members, host.members, "{what}: members");
                let group_of: Vec<u32> = gpu
                    .dev
                    .download(&cells.group)
                    .unwrap()
                    .iter()
                    .map(|&g| g as u32)
                    .collect();
                assert_eq!(group_of, host.group, "{what}: groups");
                let pos = gpu.dev.download(&cells.pos).unwrap();
                assert_eq!(pos, host.sorted.as_flattened(), "{what}: wrapped positions");
            }
        }
        gpu.shuffle_blocks(0);
    }

    /// The prefix sum in one block and in three passes against the obvious sum: counts of
    /// cells as the cell lists produce them (mostly 0-3, some large), lengths around the
    /// switch between the two and past the tiles' minimum.
    #[test]
    fn long_prefix_sums_are_the_sequential_ones_on_the_emulation() {
        let Ok(gpu) = GpuFourier::open(Backend::HostEmulation) else {
            assert!(
                std::env::var("MOTILE_REQUIRE_CXX").is_err(),
                "no host emulation (and MOTILE_REQUIRE_CXX is set)"
            );
            return;
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for n in [
            1,
            1000,
            SCAN_ONE_BLOCK,
            SCAN_ONE_BLOCK + 1,
            700_001,
            2_000_000,
        ] {
            let count: Vec<i32> = (0..n)
                .map(|_| {
                    if rng.random_range(0..100) == 0 {
                        rng.random_range(0..400)
                    } else {
                        rng.random_range(0..4)
                    }
                })
                .collect();
            let mut want = vec![0i32; n + 1];
            for k in 0..n {
                want[k + 1] = want[k] + count[k];
            }
            let dev = gpu.dev.upload(&count).unwrap();
            let mut start = gpu.dev.zeros::<i32>(n + 1).unwrap();
            super::super::prefix_sum(&gpu.dev, &dev, &mut start, n).unwrap();
            let got = gpu.dev.download(&start).unwrap();
            let first = got.iter().zip(&want).position(|(a, b)| a != b);
            assert_eq!(
                first, None,
                "{n} counts: the starts differ first at {first:?}"
            );
        }
    }
}
