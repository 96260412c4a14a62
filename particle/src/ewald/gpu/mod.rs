//! The spectral Ewald sums on a GPU (feature `gpu`): the Fourier part (spreading, FFTs, the
//! Fourier-space multiplication and the interpolation back) and the real-space parts (every
//! pair within the cutoff, from the CPU's cell list and with its interpolation tables), each
//! the twin of the CPU's (`ewald/grid.rs`, the mode and pair functions of
//! [`crate::ewald::kernels`], `ewald/spectral/real_space.rs`), on a
//! [`motile_gpu::Device`]. [`crate::ewald::spectral::SpectralEwald::with_device`] uses it in
//! place of the CPU's; the cell list's sort, the corrections, the error estimate and the
//! refinement stay on the CPU and are shared with the CPU sum, so the accuracy contract is the
//! same.
//!
//! The device is opened by [`GpuFourier::open`] with a [`motile_gpu::Backend`]: CUDA, or the
//! host emulation (the same kernels compiled by the C++ compiler and run on the CPU, for tests
//! on machines without a GPU). The points and the cell list stay on the device while the
//! caller's generation is the same (the products of one GMRES solve); each sum uploads its
//! values and downloads the gathered values; the grids, spectra and FFT plans stay on the
//! device from sum to sum (rebuilt when the grid size changes). Kernels are declared in
//! `signatures.rs` and launched in `launch.rs`.
//!
//! Spreading sorts the points into bins on the device and sums each bin's grid values from the
//! points that reach them, without atomics, in the same order in every run (`binned.rs`, the
//! default; the global-memory spreader in bin order and the per-point atomic spreader in the
//! points' order stay selectable, the last as the slow twin). With the
//! default the sums repeat bit for bit on a GPU; with the atomic spreaders the last bits vary
//! from run to run.

pub(crate) mod backend;
mod binned;
mod launch;
pub(crate) mod resident;
mod scan;
mod signatures;
mod work;

pub use binned::{CELL_BIN, CELL_BIN_MAX, GATHER_TILE, SpreadMethod, cell_bin, tiles_fit};
pub(crate) use launch::Geometry;
pub use launch::STRESSLET_FIELDS;
use launch::{Fields, FourierKind, Points};
pub use launch::{OrientedPoints, PointForces};
pub(crate) use scan::prefix_sum;
pub use work::{FourierPart, PhaseWork, work_model};

use crate::ewald::gpu::signatures::KERNELS;
use crate::ewald::kernels::{RealSpaceTable, StressletTable};
use crate::ewald::point_cells::PointCells;
use crate::model::geometry::Vec3;
use motile_gpu::{Backend, Buffer, Device, Direction, Fft3, GpuError};

/// The device and what stays on it between sums.
#[derive(Debug)]
pub struct GpuFourier {
    dev: Device,
    grid: Option<Grid>,
    /// The last points uploaded (as given, and the cell list's layout), with the caller's
    /// generation: the products of one GMRES solve reuse them instead of uploading again.
    points: Option<(u64, Buffer)>,
    cells: Option<(u64, CellBuffers)>,
    /// The points of a generation sorted into bins for the binned spreaders.
    bins: Option<(u64, binned::Bins)>,
    /// The spreading method, or `None` for [`SpreadMethod::for_support`].
    method: Option<SpreadMethod>,
    /// Whether the gather over the output-driven sort's bins takes the tiled kernel where its
    /// tiles fit (the default) or a thread per point.
    tiled_gather: bool,
}

/// The cell list's layout on the device: sorted positions, each point's group, cell starts.
#[derive(Debug)]
struct CellBuffers {
    pos: Buffer,
    group: Buffer<i32>,
    start: Buffer<i32>,
}

/// Plans and buffers for one grid size.
#[derive(Debug)]
struct Grid {
    m: usize,
    /// The spread fields and their spectra: three (RPY forces) and five (trace-free
    /// stresslets), each made when first used.
    inputs: [Option<Input>; 2],
    /// The inverse transform of three fields, in place: the first three of an input's spectra
    /// (the multiplication leaves the velocities there) into the first three of its fields.
    inverse3: Fft3,
}

/// How far a real-space sum reaches, and the range of its error model.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RealSpaceReach {
    /// The cutoff: pairs farther apart are left to the Fourier part.
    pub(crate) cutoff: f64,
    /// The error model's range `r0`.
    pub(crate) error_range: f64,
}

/// A real-space kernel's table as the device reads it.
#[derive(Clone, Copy, Debug)]
struct TableParts<'a> {
    /// The tabulated values.
    values: &'a [f64],
    /// Nodes of the table.
    nodes: usize,
    /// The inverse of the node spacing.
    inv_h: f64,
}

/// `nf` spread fields and their in-place forward plan: each field's real values in cuFFT's
/// padded layout (`x` rows of `2 (m/2 + 1)` values), its half spectrum over them, so a sum
/// holds one grid per field (`2 m m (m/2 + 1)` values).
#[derive(Debug)]
pub(crate) struct Input {
    plan: Fft3,
    grids: Buffer,
}

impl GpuFourier {
    /// The device `backend` names, with the kernels compiled: [`GpuError::NoDevice`] where
    /// there is none. It spreads with [`SpreadMethod::for_support`]'s choice until
    /// [`Self::set_spread_method`] says otherwise.
    pub fn open(backend: Backend) -> Result<Self, GpuError> {
        Ok(Self {
            dev: Device::open(backend, &KERNELS)?,
            grid: None,
            points: None,
            cells: None,
            bins: None,
            method: None,
            tiled_gather: true,
        })
    }

    /// The backend of this sum's device (to open other kernels beside it).
    pub fn backend(&self) -> Backend {
        self.dev.backend()
    }

    /// Spread with `method` from now on, or (`None`) with [`SpreadMethod::for_support`]'s
    /// choice: for tests and benchmarks that compare the spreaders, and for runs on the host
    /// emulation, whose threaded blocks (an OS thread per GPU thread, a condition-variable
    /// barrier) make the output-driven spreader's many small blocks slow there.
    pub fn set_spread_method(&mut self, method: Option<SpreadMethod>) {
        self.method = method;
        self.bins = None;
    }

    /// Gather over the output-driven sort's bins with the tiled kernel where its tiles fit
    /// (`true`, the default) or with a thread per point (`false`): the same bits either way;
    /// for tests and benchmarks that compare them.
    pub fn set_tiled_gather(&mut self, on: bool) {
        self.tiled_gather = on;
    }

    /// On the host emulation, run blocks in a new random order at every launch (`seed`
    /// nonzero), to expose races between blocks ([`motile_gpu::Device::shuffle_blocks`]).
    pub fn shuffle_blocks(&self, seed: u64) -> bool {
        self.dev.shuffle_blocks(seed)
    }

    /// The method a sum of support `p` spreads with: the one set, or
    /// [`SpreadMethod::for_support`]'s.
    pub fn spread_method(&self, p: usize) -> SpreadMethod {
        self.method.unwrap_or_else(|| SpreadMethod::for_support(p))
    }

    /// What the device is.
    pub fn describe(&self) -> String {
        self.dev.describe()
    }

    /// `(bytes in use, total bytes)` of the device's memory (every context on it), `None` on
    /// the host emulation.
    pub fn memory(&self) -> Result<Option<(usize, usize)>, GpuError> {
        self.dev.memory()
    }

    /// The plans and buffers for grid size `m`, and the input of `nf` (3 or
    /// [`STRESSLET_FIELDS`]) fields.
    fn grid(&mut self, m: usize, nf: usize) -> Result<&mut Grid, GpuError> {
        let dev = &self.dev;
        if self.grid.as_ref().is_none_or(|g| g.m != m) {
            self.grid = None; // the old buffers go first
            let inverse3 = dev.fft3_in_place(m, 3, Direction::Inverse)?;
            self.grid = Some(Grid {
                m,
                inputs: [None, None],
                inverse3,
            });
        }
        let g = self.grid.as_mut().expect("made above");
        let slot = &mut g.inputs[usize::from(nf == STRESSLET_FIELDS)];
        if slot.is_none() {
            let plan = dev.fft3_in_place(m, nf, Direction::Forward)?;
            *slot = Some(Input {
                grids: dev.zeros(plan.padded_len())?,
                plan,
            });
        }
        Ok(g)
    }

    /// Spread `values` (field-major, `nf` fields of the points of `generation`) and forward
    /// transform them into the input's spectra.
    fn spread(
        &mut self,
        generation: u64,
        geo: &Geometry,
        points: Points<'_>,
        fields: Fields<'_>,
    ) -> Result<(), GpuError> {
        let Points { pos: pts, n } = points;
        let Fields { vals, nf } = fields;
        self.grid(geo.m, nf)?;
        let method = self.spread_method(geo.window.p);
        let bins = match method {
            SpreadMethod::Atomic => None,
            _ => Some(self.bins(generation, geo, method, pts, n)?),
        };
        let dev = &self.dev;
        let g = self.grid.as_mut().expect("made by grid()");
        let input = g.inputs[usize::from(nf == STRESSLET_FIELDS)]
            .as_mut()
            .expect("made by grid()");
        // The output-driven spreader writes every grid value; the others add to zeros.
        if method != SpreadMethod::Cells {
            dev.zero(&mut input.grids)?;
        }
        match &bins {
            None => launch::spread(dev, geo, pts, vals, &mut input.grids, n, nf)?,
            Some(b) => binned::spread(dev, geo, b, points, fields, &mut input.grids)?,
        }
        self.bins = bins.map(|b| (generation, b));
        dev.forward_in_place(&input.plan, &mut input.grids, 0)
    }

    /// The points of `generation` sorted into bins for `method`: the cached sort, or a new one
    /// (the caller puts it back in [`Self::bins`]).
    fn bins(
        &mut self,
        generation: u64,
        geo: &Geometry,
        method: SpreadMethod,
        pts: &Buffer,
        n: usize,
    ) -> Result<binned::Bins, GpuError> {
        match self.bins.take() {
            Some((g, b))
                if g == generation
                    && b.n == n
                    && b.method == method
                    && b.key.0 == geo.m
                    && b.key.1 == geo.window.p =>
            {
                Ok(b)
            }
            _ => binned::sort(&self.dev, geo, method, pts, n),
        }
    }

    /// The Fourier part of a sum of the `n` points `pts` with `nf` field-major values
    /// `vals`: spread, forward transforms, the multiplication `which` (in place), the inverse
    /// transform of the three velocity spectra into the first three fields, and the gather
    /// (with gradients if asked, in bin order where the spread sorted the points): field-major
    /// values (3, or 12 with gradients) left on the device.
    fn fourier(
        &mut self,
        generation: u64,
        geo: &Geometry,
        points: Points<'_>,
        fields: Fields<'_>,
        kind: FourierKind,
    ) -> Result<Buffer, GpuError> {
        self.spread(generation, geo, points, fields)?;
        self.fourier_spread(geo, points, fields.nf, kind)
    }

    /// [`Self::fourier`] after its spread (the values of the `nf` fields already on the grid,
    /// so the caller may drop them first): the multiplication, the inverse transforms and the
    /// gather.
    fn fourier_spread(
        &mut self,
        geo: &Geometry,
        points: Points<'_>,
        nf: usize,
        kind: FourierKind,
    ) -> Result<Buffer, GpuError> {
        let Points { pos: pts, n } = points;
        let FourierKind {
            modes: which,
            gradient,
        } = kind;
        let method = self.spread_method(geo.window.p);
        let g = self.grid.as_mut().expect("spread made it");
        let input = g.inputs[usize::from(nf == STRESSLET_FIELDS)]
            .as_mut()
            .expect("spread made it");
        let dev = &self.dev;
        launch::modes(dev, geo, which, &mut input.grids)?;
        // The velocity spectra back to the grid, in place.
        dev.inverse_in_place(&g.inverse3, &mut input.grids, 0)?;
        let mut out = dev.zeros(if gradient { 12 } else { 3 } * n)?;
        let back = &input.grids;
        match (&self.bins, method) {
            (Some((_, b)), m) if m != SpreadMethod::Atomic => {
                let tiles = self.tiled_gather;
                binned::gather(dev, geo, b, points, (back, &mut out), gradient, tiles)?;
            }
            _ => launch::gather(dev, geo, pts, back, &mut out, n, gradient)?,
        }
        Ok(out)
    }

    /// The Fourier part of the RPY sum (radius `a`) at the points: three velocity components
    /// per point (before the division by the viscosity), in the points' order.
    pub(crate) fn rpy(
        &mut self,
        generation: u64,
        geo: &Geometry,
        a: f64,
        points: &[Vec3],
        forces: &[Vec3],
    ) -> Result<[Vec<f64>; 3], GpuError> {
        let n = points.len();
        let pts = self.points(generation, points)?;
        let vals: Vec<f64> = (0..3)
            .flat_map(|d| forces.iter().map(move |f| f[d]))
            .collect();
        let vals = self.dev.upload(&vals)?;
        let back = self.fourier(
            generation,
            geo,
            Points { pos: &pts, n },
            Fields { vals: &vals, nf: 3 },
            FourierKind {
                modes: launch::Modes::Rpy { a },
                gradient: false,
            },
        )?;
        let out = self.dev.download(&back)?;
        self.points = Some((generation, pts));
        Ok(std::array::from_fn(|c| out[c * n..(c + 1) * n].to_vec()))
    }

    /// The points of `generation` on the device, as given: the cached upload, or a new one
    /// (the caller puts it back in [`Self::points`] after use).
    fn points(&mut self, generation: u64, points: &[Vec3]) -> Result<Buffer, GpuError> {
        match self.points.take() {
            Some((g, b)) if g == generation && b.len() == 3 * points.len() => Ok(b),
            _ => self.dev.upload(points.as_flattened()),
        }
    }

    /// The cell list's layout on the device (sorted positions, groups, cell starts) for the
    /// points of `generation`: the cached upload, or a new one.
    fn cells(&mut self, generation: u64, cells: &PointCells) -> Result<CellBuffers, GpuError> {
        if !cells.all_own() {
            return Err(GpuError::Input(
                "the device's real-space sums take every point as a target".into(),
            ));
        }
        if let Some((g, b)) = self.cells.take()
            && g == generation
            && b.pos.len() == 3 * cells.members.len()
        {
            return Ok(b);
        }
        let dev = &self.dev;
        let to_int = motile_gpu::kernel_int;
        let group = cells
            .group
            .iter()
            .map(|&g| to_int(g as usize, "group"))
            .collect::<Result<Vec<i32>, _>>()?;
        let start = cells
            .start
            .iter()
            .map(|&s| to_int(s, "cell start"))
            .collect::<Result<Vec<i32>, _>>()?;
        Ok(CellBuffers {
            pos: dev.upload(cells.sorted.as_flattened())?,
            group: dev.upload(&group)?,
            start: dev.upload(&start)?,
        })
    }

    /// Run a real-space kernel and return its `K` outputs per point in the points' own order.
    fn real_space<const K: usize>(
        &mut self,
        generation: u64,
        which: launch::Real<'_>,
        cells: &PointCells,
        table: TableParts<'_>,
        reach: RealSpaceReach,
    ) -> Result<Vec<[f64; K]>, GpuError> {
        let TableParts {
            values: table,
            nodes,
            inv_h,
        } = table;
        let RealSpaceReach {
            cutoff,
            error_range: r0,
        } = reach;
        let n = cells.members.len();
        let cb = self.cells(generation, cells)?;
        let dev = &self.dev;
        let table = dev.upload(table)?;
        let mut out = dev.zeros(K * n)?;
        let inputs = launch::RealSpace {
            pos: &cb.pos,
            group: &cb.group,
            start: &cb.start,
            table: &table,
            npts: n,
            ncell: cells.n,
            nodes,
            l: cells.l,
            cutoff,
            inv_h,
            r0sq: r0 * r0,
        };
        launch::real_space(dev, which, &inputs, &mut out)?;
        let sorted = dev.download(&out)?;
        self.cells = Some((generation, cb));
        let mut result = vec![[0.0; K]; n];
        for (k, &i) in cells.members.iter().enumerate() {
            result[i as usize].copy_from_slice(&sorted[K * k..K * (k + 1)]);
        }
        Ok(result)
    }

    /// The real-space part of the RPY sum (radius `a`, cutoff and table as the CPU's
    /// [`crate::ewald::spectral::real_space::rpy_real`]) at every point of `cells`: `[u_0, u_1, u_2, e2]`
    /// per point in the points' own order, `e2` the error model's weighted strengths with
    /// the reach's error range.
    pub(crate) fn rpy_real(
        &mut self,
        generation: u64,
        cells: &PointCells,
        table: &RealSpaceTable,
        reach: RealSpaceReach,
        a: f64,
        forces: &[Vec3],
    ) -> Result<Vec<[f64; 4]>, GpuError> {
        let (inv_h, nodes, [c, ca, cb], g) = table.parts();
        let force = self
            .dev
            .upload(cells.sorted_values(forces).as_flattened())?;
        self.real_space(
            generation,
            launch::Real::Rpy {
                force: &force,
                c,
                ca,
                cb,
                a,
            },
            cells,
            TableParts {
                values: &g,
                nodes,
                inv_h,
            },
            reach,
        )
    }

    /// The real-space part of the stresslet sum (the CPU's
    /// [`crate::ewald::spectral::real_space::stresslet_real`]): per point in its own order, velocity
    /// `0..3`, gradient `du_i/dx_m` at `3 + 3 i + m`, and the error model's weighted strengths
    /// at 12.
    pub(crate) fn stresslet_real(
        &mut self,
        generation: u64,
        cells: &PointCells,
        table: &StressletTable,
        reach: RealSpaceReach,
        p: &[Vec3],
        sigma: &[f64],
    ) -> Result<Vec<[f64; 13]>, GpuError> {
        let (inv_h, nodes, xi, r_direct, g) = table.parts();
        let orient = self.dev.upload(cells.sorted_values(p).as_flattened())?;
        let strength = self.dev.upload(&cells.sorted_values(sigma))?;
        self.real_space(
            generation,
            launch::Real::Stresslet {
                orient: &orient,
                sigma: &strength,
                xi,
                r_direct,
            },
            cells,
            TableParts {
                values: &g,
                nodes,
                inv_h,
            },
            reach,
        )
    }

    /// The Fourier part of the stresslet sum: the six stresslet components per point
    /// (`xx, yy, zz, xy, xz, yz`) in, velocity and gradient out as
    /// `GaussianGrid::gather_gradient` gives them (`3 + 3 i + m` is `du_i/dx_m`). The device
    /// spreads the [`STRESSLET_FIELDS`] trace-free components (the trace's flow is zero).
    pub(crate) fn stresslet(
        &mut self,
        generation: u64,
        geo: &Geometry,
        points: &[Vec3],
        s: [&[f64]; 6],
    ) -> Result<[Vec<f64>; 12], GpuError> {
        let n = points.len();
        let pts = self.points(generation, points)?;
        if let Some(c) = s.iter().position(|c| c.len() != n) {
            return Err(GpuError::Input(format!(
                "stresslet component {c} has {} values for {n} points",
                s[c].len()
            )));
        }
        let [xx, yy, zz, xy, xz, yz] = s;
        let third: Vec<f64> = (0..n).map(|i| (xx[i] + yy[i] + zz[i]) / 3.0).collect();
        let vals: Vec<f64> = xx
            .iter()
            .zip(&third)
            .map(|(v, t)| v - t)
            .chain(yy.iter().zip(&third).map(|(v, t)| v - t))
            .chain([xy, xz, yz].into_iter().flatten().copied())
            .collect();
        let vals = self.dev.upload(&vals)?;
        let back = self.fourier(
            generation,
            geo,
            Points { pos: &pts, n },
            Fields {
                vals: &vals,
                nf: STRESSLET_FIELDS,
            },
            FourierKind {
                modes: launch::Modes::Stresslet,
                gradient: true,
            },
        )?;
        let out = self.dev.download(&back)?;
        self.points = Some((generation, pts));
        Ok(std::array::from_fn(|c| out[c * n..(c + 1) * n].to_vec()))
    }
}
