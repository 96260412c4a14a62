//! The slender-body level's (P4) on the device of its resident sum (feature `gpu`): GMRES with
//! its vectors on the device ([`crate::hydro::gmres::KrylovSpace`]), each product one
//! resident RPY sum between two kernels (the weighted forces, the operator per rod), the
//! modified Gram-Schmidt dot products summed in the CPU's fixed chunks and folded on the
//! device, so that per iteration only the Hessenberg column (`k + 2` numbers) and the sum's
//! error reductions come back to the host. The right-hand side, the nodes and the rods'
//! velocities are kernels too (`slender.cu`), each the CPU's arithmetic in the CPU's order:
//! with the same products (a sum of host values, [`P4Sum::Host`]) the device's iterates are
//! the CPU's bits; with the resident sum they differ by the sums' round-off.
//!
//! Counted work per iteration `k` (from 0) of `3 m n` values (`m` nodes per rod): one resident
//! RPY sum of `m n` points, 2 kernels around it, `k + 2` dot products (2 launches each: the
//! chunks' partials, their fold), `k + 1` updates of `w` and one normalisation; one download
//! of `k + 2` numbers.
#![allow(unsafe_code)]

mod levels;
mod resident;
mod signatures;

pub use resident::{DeviceVelocities, ResidentMobility, RodsOnDevice};

use crate::ewald::periodic::{PeriodicStokes, RpyGeometry, SumError};
use crate::ewald::spectral::SpectralEwald;
use crate::hydro::gmres::{GmresError, GmresInfo, GmresParams, KrylovSpace, gmres_in};
use crate::hydro::report::HydroReport;
use crate::model::geometry::Vec3;
use motile_analysis::reduce::CHUNK;
use motile_gpu::{Backend, Buffer, Device, GpuError, check_len, kernel_int as int};
use signatures::{
    KERNELS, KrylovAxpy, KrylovDiv, KrylovDotChunks, KrylovFold, KrylovResidual, KrylovUpdate,
    SlenderNodes, SlenderP4, SlenderPredict, SlenderRhs, SlenderVelocities, SlenderWeighted,
};
use std::time::Instant;

// krylov_dot_chunks stages THREADS products per round in shared memory, one per thread.
const _: () = assert!(motile_gpu::THREADS == 256);

/// A device with the slender-body level's kernels compiled.
#[derive(Debug)]
pub struct SlenderDevice {
    dev: Device,
}

/// The rods' quadrature rule on the device: `(s, w)`, `m` nodes each.
#[derive(Debug)]
pub struct DeviceRule {
    s: Buffer,
    w: Buffer,
    m: usize,
}

/// How a rod moves through the flow at its nodes: its length, its swimming speed and its local
/// drag `(trans, rot)` ([`crate::hydro::mobility::LocalDrag::coefficients`]).
#[derive(Clone, Copy, Debug)]
pub struct RodMotion {
    /// The rod's length.
    pub length: f64,
    /// The swimming speed along its axis.
    pub swim: f64,
    /// The local drag's translational and rotational coefficients.
    pub drag: (f64, f64),
}

/// Where a dot product of the Arnoldi process goes: the chunks' partial sums, then the
/// Hessenberg column `h` at `slot`, its square root where `root` (a norm).
struct ColumnSlot<'a> {
    partial: &'a mut Buffer,
    h: &'a mut Buffer,
    slot: usize,
    root: bool,
}

/// What the slender-body kernels give of the rods' flow: the flow velocities (6 values per
/// rod: `v`, then `w`) and the rods' velocities.
#[derive(Debug)]
pub struct SlenderFlow {
    /// The flow velocities.
    pub flow: Buffer,
    /// The rods' velocities and angular velocities.
    pub rods: DeviceVelocities,
}

impl SlenderDevice {
    /// The device `backend` names (where a sum's device is, [`Device::backend`]), with the
    /// kernels compiled.
    pub fn open(backend: Backend) -> Result<Self, GpuError> {
        Ok(Self {
            dev: Device::open(backend, &KERNELS)?,
        })
    }

    /// Values onto the device.
    pub fn upload(&self, values: &[f64]) -> Result<Buffer, GpuError> {
        self.dev.upload(values)
    }

    /// A buffer's values on the host.
    pub fn download(&self, buf: &Buffer) -> Result<Vec<f64>, GpuError> {
        self.dev.download(buf)
    }

    /// What the device has been asked to do so far.
    pub fn counters(&self) -> motile_gpu::Counters {
        self.dev.counters()
    }

    /// On the host emulation, run the blocks of every later launch in a random order (`seed`
    /// nonzero; 0: in order): [`Device::shuffle_blocks`].
    pub fn shuffle_blocks(&self, seed: u64) -> bool {
        self.dev.shuffle_blocks(seed)
    }

    /// The rule `(s, w)` on the device.
    pub fn rule(&self, s: &[f64], w: &[f64]) -> Result<DeviceRule, GpuError> {
        if s.len() != w.len() || s.is_empty() {
            return Err(GpuError::Input(format!(
                "a quadrature rule of {} nodes and {} weights",
                s.len(),
                w.len()
            )));
        }
        Ok(DeviceRule {
            s: self.dev.upload(s)?,
            w: self.dev.upload(w)?,
            m: s.len(),
        })
    }

    /// The nodes `x_r + s_j p_r` of `n` rods with centres `x` and axes `p` (triples).
    pub fn nodes(
        &self,
        x: &Buffer,
        p: &Buffer,
        rule: &DeviceRule,
        n: usize,
    ) -> Result<Buffer, GpuError> {
        let m = rule.m;
        check_len("centres", x, 3 * n)?;
        check_len("axes", p, 3 * n)?;
        int(3 * n * m, "3 x nodes")?;
        let mut nodes = self.dev.zeros::<f64>(3 * n * m)?;
        // SAFETY: thread k < n m reads x, p at 3 (k / m)..+3 (3 n checked), s[k % m] (m) and
        // writes nodes at 3 k..3 k + 3 (3 n m).
        unsafe {
            self.dev.launch(
                n * m,
                SlenderNodes {
                    x,
                    p,
                    s: &rule.s,
                    nodes: &mut nodes,
                    n: int(n, "rods")?,
                    m: int(m, "nodes per rod")?,
                },
            )?;
        }
        Ok(nodes)
    }

    /// (P4)'s right-hand side for `n` rods with axes `p`: swimming, `c sign(s_j) p`, plus the
    /// contact forces and torques `ft` (6 values per rod) where given, for rods of length `l`.
    pub fn rhs(
        &self,
        p: &Buffer,
        ft: Option<&Buffer>,
        rule: &DeviceRule,
        n: usize,
        c: f64,
        l: f64,
    ) -> Result<Buffer, GpuError> {
        let m = rule.m;
        check_len("axes", p, 3 * n)?;
        if let Some(ft) = ft {
            check_len("contact forces", ft, 6 * n)?;
        }
        let len = 3 * n * m;
        int(len, "3 x nodes")?;
        let mut rhs = self.dev.zeros::<f64>(len)?;
        // SAFETY: thread k < 3 n m reads p (3 n checked), ft at 6 (k / 3 m)..+6 (6 n checked,
        // only with has_ft), s (m) and writes rhs[k] (3 n m).
        unsafe {
            self.dev.launch(
                len,
                SlenderRhs {
                    p,
                    ft: ft.unwrap_or(p),
                    s: &rule.s,
                    rhs: &mut rhs,
                    n: int(n, "rods")?,
                    m: int(m, "nodes per rod")?,
                    c,
                    l,
                    has_ft: i32::from(ft.is_some()),
                },
            )?;
        }
        Ok(rhs)
    }

    /// The flow velocities of `n` rods with axes `p` from the flow `u` at their nodes, and
    /// their velocities: swimming at `swim` along `p`, the flow's, and with contact forces and
    /// torques `ft` (6 values per rod) their local drag `(trans, rot)`
    /// ([`crate::hydro::mobility::LocalDrag::coefficients`]), for rods of length `l`.
    pub fn velocities(
        &self,
        p: &Buffer,
        u: &Buffer,
        ft: Option<&Buffer>,
        rule: &DeviceRule,
        n: usize,
        motion: RodMotion,
    ) -> Result<SlenderFlow, GpuError> {
        let RodMotion {
            length: l,
            swim,
            drag,
        } = motion;
        let m = rule.m;
        check_len("axes", p, 3 * n)?;
        check_len("flow at the nodes", u, 3 * n * m)?;
        if let Some(ft) = ft {
            check_len("contact forces", ft, 6 * n)?;
        }
        int(6 * n, "6 x rods")?;
        let dev = &self.dev;
        let mut flow = dev.zeros::<f64>(6 * n)?;
        let (mut vel, mut omega) = (dev.zeros::<f64>(3 * n)?, dev.zeros::<f64>(3 * n)?);
        // SAFETY: thread r < n reads p at 3 r (3 n checked), u at 3 r m..3 (r + 1) m (checked),
        // s, w (m), with has_ft ft at 6 r..6 r + 6 (checked) and writes flow at 6 r..6 r + 6
        // (6 n) and vel, omega at 3 r..3 r + 3 (3 n).
        unsafe {
            dev.launch(
                n,
                SlenderVelocities {
                    p,
                    u,
                    s: &rule.s,
                    w: &rule.w,
                    ft: ft.unwrap_or(p),
                    flow: &mut flow,
                    vel: &mut vel,
                    omega: &mut omega,
                    n: int(n, "rods")?,
                    m: int(m, "nodes per rod")?,
                    l,
                    swim,
                    trans: drag.0,
                    rot: drag.1,
                    has_ft: i32::from(ft.is_some()),
                },
            )?;
        }
        Ok(SlenderFlow {
            flow,
            rods: DeviceVelocities { v: vel, w: omega },
        })
    }

    /// The velocities the contact solver plans with: swimming at `swim` along the axes `p`
    /// plus the last flow velocities `flow` (6 per rod), for `n` rods.
    pub fn predict(
        &self,
        p: &Buffer,
        flow: &Buffer,
        n: usize,
        swim: f64,
    ) -> Result<(Buffer, Buffer), GpuError> {
        check_len("axes", p, 3 * n)?;
        check_len("flow velocities", flow, 6 * n)?;
        int(6 * n, "6 x rods")?;
        let dev = &self.dev;
        let (mut vel, mut omega) = (dev.zeros::<f64>(3 * n)?, dev.zeros::<f64>(3 * n)?);
        // SAFETY: thread r < n reads p at 3 r..3 r + 3 and flow at 6 r..6 r + 6 (checked) and
        // writes vel, omega at 3 r..3 r + 3 (3 n).
        unsafe {
            dev.launch(
                n,
                SlenderPredict {
                    p,
                    flow,
                    vel: &mut vel,
                    omega: &mut omega,
                    n: int(n, "rods")?,
                    swim,
                },
            )?;
        }
        Ok((vel, omega))
    }

    /// A copy of `src` on the device.
    pub fn copy_of(&self, src: &Buffer) -> Result<Buffer, GpuError> {
        let mut out = self.dev.zeros::<f64>(src.len())?;
        self.dev.copy((src, 0), (&mut out, 0), src.len())?;
        Ok(out)
    }

    /// `len` zeros on the device.
    pub fn zeros(&self, len: usize) -> Result<Buffer, GpuError> {
        self.dev.zeros::<f64>(len)
    }
}

/// What the slender-body mobility keeps on its sum's device: the kernels and the rule (opened
/// at the first solve there), and between resident steps the last solution of (P4) and the
/// flow velocities (6 per rod) of `n` rods (`host_behind`: the host's copies are older), copies
/// of both from before the step (restored where the step fails), the step's axes and nodes
/// (from the prediction, for the final solve), and the emulation's block order.
#[derive(Debug, Default)]
pub struct SlenderState {
    pub(crate) kern: Option<(SlenderDevice, DeviceRule)>,
    pub(crate) x: Option<Buffer>,
    pub(crate) flow: Option<Buffer>,
    pub(crate) n: usize,
    pub(crate) host_behind: bool,
    pub(crate) before: (Option<Buffer>, Option<Buffer>),
    /// The kernels' block order on the host emulation ([`SlenderDevice::shuffle_blocks`]).
    pub(crate) shuffle: u64,
    pub(crate) step: Option<(Buffer, Buffer)>,
}

impl SlenderState {
    /// Drop the resident state (the host's is set anew, or brought up to it).
    pub fn forget(&mut self) {
        (self.x, self.flow, self.step) = (None, None, None);
        self.before = (None, None);
        self.host_behind = false;
    }

    /// The state before the step restored (after a failed step).
    pub fn rollback(&mut self) {
        (self.x, self.flow) = std::mem::take(&mut self.before);
        self.step = None;
    }
}

/// Where the products' RPY sums run.
#[derive(Debug)]
pub enum P4Sum<'a> {
    /// The resident sum: forces and velocities stay on the device.
    Resident(&'a mut SpectralEwald),
    /// A sum of host values at the nodes given (the weighted forces downloaded, the velocities
    /// uploaded, per product): the slow twin, with which the device's iterates are the CPU's
    /// bits.
    Host(&'a mut dyn PeriodicStokes, &'a [Vec3]),
}

/// The operator of (P4) on the device: the sum, the nodes (triples), the axes (triples) of `n`
/// rods, the rule and `eta` ([`crate::model::units::eta`]) of rods of length `l`.
#[derive(Debug)]
pub struct DeviceP4<'a> {
    /// Where the sums run.
    pub sum: P4Sum<'a>,
    /// The sum's geometry (box, RPY radius, the nodes' group of `m`).
    pub geometry: RpyGeometry,
    /// The nodes.
    pub nodes: &'a Buffer,
    /// The axes.
    pub p: &'a Buffer,
    /// The rule.
    pub rule: &'a DeviceRule,
    /// Rods.
    pub n: usize,
    /// `eta`.
    pub eta: f64,
    /// The rod length.
    pub l: f64,
}

/// What a solve on the device did: GMRES's report, the flow at the nodes for the solution,
/// the sums' accuracy and seconds.
#[derive(Debug)]
pub struct DeviceSolve {
    /// GMRES's report.
    pub info: GmresInfo,
    /// The flow at the nodes for the solution (triples).
    pub u: Buffer,
    /// The sums' accuracy, folded.
    pub accuracy: HydroReport,
    /// Seconds in the sums.
    pub seconds: f64,
}

impl SlenderDevice {
    /// Solve (P4) `A x = b` by GMRES from the warm start `x` (overwritten with the solution),
    /// the vectors on the device ([`super::gmres::gmres`]'s iteration and bits, the products
    /// `op`'s). On failure `x` holds the last iterate.
    pub fn solve(
        &self,
        op: DeviceP4<'_>,
        b: &Buffer,
        x: &mut Buffer,
        params: &GmresParams,
    ) -> Result<DeviceSolve, GmresError<SumError>> {
        let dim = 3 * op.rule.m * op.n;
        let setup = || -> Result<_, GpuError> {
            check_len("right-hand side", b, dim)?;
            check_len("iterate", x, dim)?;
            check_len("nodes", op.nodes, dim)?;
            check_len("axes", op.p, 3 * op.n)?;
            // The dot products' chunk loop runs to dim + CHUNK in int.
            int(dim + CHUNK, "unknowns")?;
            let slots = params.restart.max(1).min(params.max_iterations.max(1)) + 1;
            Ok((
                self.dev.zeros::<f64>(dim)?,
                self.dev.zeros::<f64>(slots + 1)?,
                self.dev.zeros::<f64>(dim.div_ceil(CHUNK).max(1))?,
            ))
        };
        let (w, h, partial) = setup()
            .map_err(SumError::from)
            .map_err(GmresError::Operator)?;
        let mut space = Space {
            kern: self,
            op,
            b,
            x,
            basis: Vec::new(),
            w,
            h,
            partial,
            u: None,
            u_at_x: false,
            dim,
            accuracy: HydroReport::default(),
            seconds: 0.0,
        };
        let info = gmres_in(&mut space, params)?;
        if !space.u_at_x {
            // Only after x = 0 (a zero right-hand side): its flow.
            space.product_at_x().map_err(GmresError::Operator)?;
        }
        let u = space
            .u
            .take()
            .expect("the flow of the last product at the solution");
        Ok(DeviceSolve {
            info,
            u,
            accuracy: space.accuracy,
            seconds: space.seconds,
        })
    }
}

/// A vector of the space by name.
#[derive(Clone, Copy)]
enum Which {
    Rhs,
    W,
}

/// GMRES's vectors on the device.
struct Space<'a, 'b> {
    kern: &'a SlenderDevice,
    op: DeviceP4<'b>,
    b: &'a Buffer,
    x: &'a mut Buffer,
    /// The basis, each vector made when GMRES first reaches it (kept over restarts).
    basis: Vec<Buffer>,
    /// The product being orthogonalised, or the residual.
    w: Buffer,
    /// The Hessenberg column (and single norms at slot 0).
    h: Buffer,
    partial: Buffer,
    /// The flow of the last product.
    u: Option<Buffer>,
    /// Whether that product was at `x`.
    u_at_x: bool,
    dim: usize,
    accuracy: HydroReport,
    seconds: f64,
}

/// `out = A f`: the weighted forces, the sum, the operator per rod; returns the flow at the
/// nodes.
fn product(
    kern: &SlenderDevice,
    op: &mut DeviceP4<'_>,
    src: &Buffer,
    out: &mut Buffer,
    accuracy: &mut HydroReport,
    seconds: &mut f64,
) -> Result<Buffer, SumError> {
    let dev = &kern.dev;
    let m = op.rule.m;
    let npts = op.n * m;
    let launch = || -> Result<(Buffer, Buffer), GpuError> {
        let mut force = dev.zeros::<f64>(3 * npts)?;
        let mut fields = dev.zeros::<f64>(3 * npts)?;
        // SAFETY: thread k < n m reads src at 3 k..+3 (3 n m checked), w[k % m] (m) and
        // writes force at 3 k..+3 and fields at d n m + k (3 n m each).
        unsafe {
            dev.launch(
                npts,
                SlenderWeighted {
                    f: src,
                    w: &op.rule.w,
                    force: &mut force,
                    fields: &mut fields,
                    npts: int(npts, "nodes")?,
                    m: int(m, "nodes per rod")?,
                },
            )?;
        }
        Ok((force, fields))
    };
    check_len("density", src, 3 * npts).map_err(SumError::from)?;
    let (force, fields) = launch().map_err(SumError::from)?;
    let t = Instant::now();
    let (u, report) = match &mut op.sum {
        P4Sum::Resident(sum) => {
            let sources = crate::ewald::gpu::PointForces {
                points: op.nodes,
                forces: &force,
                fields: &fields,
            };
            let u = sum.rpy_resident(&op.geometry, sources, npts)?;
            drop((force, fields));
            (u, sum.last_report())
        }
        P4Sum::Host(sum, points) => {
            drop(fields);
            let f = kern.download(&force).map_err(SumError::from)?;
            let forces: Vec<Vec3> = f.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            let u = sum.rpy(&op.geometry, points, &forces)?;
            (
                kern.upload(u.as_flattened()).map_err(SumError::from)?,
                sum.last_report(),
            )
        }
    };
    *seconds += t.elapsed().as_secs_f64();
    accuracy.add_sum(report);
    // SAFETY: thread r < n reads src at 3 r m..+3 m (checked above), u, out at
    // 3 r m..3 (r + 1) m (3 n m: the sum's result and the caller's vector), p at 3 r (3 n),
    // s, w (m), and writes out there.
    unsafe {
        dev.launch(
            op.n,
            SlenderP4 {
                f: src,
                u: &u,
                p: op.p,
                s: &op.rule.s,
                w: &op.rule.w,
                out,
                n: int(op.n, "rods").map_err(SumError::from)?,
                m: int(m, "nodes per rod").map_err(SumError::from)?,
                e: op.eta,
                l: op.l,
            },
        )
        .map_err(SumError::from)?;
    }
    Ok(u)
}

impl Space<'_, '_> {
    /// `h[slot] = |a|` for `a` of the space's length.
    fn norm_into(&mut self, a: Which, slot: usize) -> Result<(), SumError> {
        let a = match a {
            Which::Rhs => self.b,
            Which::W => &self.w,
        };
        let out = ColumnSlot {
            partial: &mut self.partial,
            h: &mut self.h,
            slot,
            root: true,
        };
        dot_into(&self.kern.dev, a, a, self.dim, out).map_err(SumError::from)
    }

    /// The flow and product at `x` into `w`.
    fn product_at_x(&mut self) -> Result<(), SumError> {
        let u = product(
            self.kern,
            &mut self.op,
            self.x,
            &mut self.w,
            &mut self.accuracy,
            &mut self.seconds,
        )?;
        self.u = Some(u);
        self.u_at_x = true;
        Ok(())
    }

    /// `h[0..len]` on the host.
    fn column(&self, len: usize) -> Result<Vec<f64>, SumError> {
        self.kern
            .dev
            .download_range(&self.h, 0, len)
            .map_err(SumError::from)
    }
}

/// `h[slot] = a . b` over `n` entries (its square root with `root`), through `partial`.
fn dot_into(
    dev: &Device,
    a: &Buffer,
    b: &Buffer,
    n: usize,
    out: ColumnSlot<'_>,
) -> Result<(), GpuError> {
    let ColumnSlot {
        partial,
        h,
        slot,
        root,
    } = out;
    check_len("dot operand", a, n)?;
    check_len("dot operand", b, n)?;
    let nchunks = n.div_ceil(CHUNK).max(1);
    check_len("partial sums", partial, nchunks)?;
    check_len("column", h, slot + 1)?;
    // SAFETY: block c < ceil(n / CHUNK) reads a, b at c CHUNK..min((c + 1) CHUNK, n) (checked)
    // and writes partial[c] (checked).
    unsafe {
        dev.launch(
            nchunks * motile_gpu::THREADS as usize,
            KrylovDotChunks {
                a,
                b,
                partial,
                n: int(n, "unknowns")?,
                chunk: CHUNK as i32,
            },
        )?;
    }
    // SAFETY: one thread reads partial[0..nchunks] and writes h[slot] (both checked).
    unsafe {
        dev.launch(
            1,
            KrylovFold {
                partial,
                out: h,
                nchunks: int(nchunks, "chunks")?,
                slot: int(slot, "slot")?,
                root: i32::from(root),
            },
        )?;
    }
    Ok(())
}

impl KrylovSpace for Space<'_, '_> {
    type Error = SumError;

    fn rhs_norm(&mut self) -> Result<f64, SumError> {
        self.norm_into(Which::Rhs, 0)?;
        Ok(self.column(1)?[0])
    }

    fn clear(&mut self) -> Result<(), SumError> {
        self.kern.dev.zero(self.x).map_err(SumError::from)?;
        self.u_at_x = false;
        Ok(())
    }

    fn residual(&mut self) -> Result<f64, SumError> {
        self.product_at_x()?;
        let n = int(self.dim, "unknowns").map_err(SumError::from)?;
        // SAFETY: thread i < dim reads b[i] and updates w[i] (dim each, checked at setup).
        unsafe {
            self.kern
                .dev
                .launch(
                    self.dim,
                    KrylovResidual {
                        b: self.b,
                        w: &mut self.w,
                        n,
                    },
                )
                .map_err(SumError::from)?;
        }
        self.norm_into(Which::W, 0)?;
        Ok(self.column(1)?[0])
    }

    fn start(&mut self, beta: f64) -> Result<(), SumError> {
        self.divide_into(0, beta)
    }

    fn arnoldi(&mut self, k: usize) -> Result<(Vec<f64>, f64), SumError> {
        let dim = self.dim;
        let u = product(
            self.kern,
            &mut self.op,
            &self.basis[k],
            &mut self.w,
            &mut self.accuracy,
            &mut self.seconds,
        )?;
        self.u = Some(u);
        self.u_at_x = false;
        let dev = &self.kern.dev;
        let n = int(dim, "unknowns").map_err(SumError::from)?;
        for j in 0..=k {
            let out = ColumnSlot {
                partial: &mut self.partial,
                h: &mut self.h,
                slot: j,
                root: false,
            };
            dot_into(dev, &self.w, &self.basis[j], dim, out).map_err(SumError::from)?;
            // SAFETY: thread i < dim updates w[i] from basis[j][i] (dim each) and h[j] (j <= k <
            // slots, slots + 1 values).
            unsafe {
                dev.launch(
                    dim,
                    KrylovAxpy {
                        w: &mut self.w,
                        v: &self.basis[j],
                        h: &self.h,
                        slot: j as i32,
                        n,
                    },
                )
                .map_err(SumError::from)?;
            }
        }
        self.norm_into(Which::W, k + 1)?;
        let mut column = self.column(k + 2)?;
        let hn = column.pop().expect("k + 2 values");
        Ok((column, hn))
    }

    fn extend(&mut self, k: usize, hn: f64) -> Result<(), SumError> {
        self.divide_into(k, hn)
    }

    fn update(&mut self, y: &[f64]) -> Result<(), SumError> {
        if y.is_empty() {
            return Ok(());
        }
        let dev = &self.kern.dev;
        let yb = dev.upload(y).map_err(SumError::from)?;
        let n = int(self.dim, "unknowns").map_err(SumError::from)?;
        for (j, v) in self.basis.iter().take(y.len()).enumerate() {
            // SAFETY: thread i < dim updates x[i] from v[i] (dim each) and y[j] (j < k
            // uploaded).
            unsafe {
                dev.launch(
                    self.dim,
                    KrylovUpdate {
                        x: self.x,
                        v,
                        y: &yb,
                        j: j as i32,
                        n,
                    },
                )
                .map_err(SumError::from)?;
            }
        }
        self.u_at_x = false;
        Ok(())
    }
}

impl Space<'_, '_> {
    /// Basis vector `k` = `w / d` (made where GMRES reaches it first).
    fn divide_into(&mut self, k: usize, d: f64) -> Result<(), SumError> {
        let dim = self.dim;
        if k > self.basis.len() {
            return Err(SumError::Device(format!(
                "basis vector {k} before vector {}",
                self.basis.len()
            )));
        }
        if k == self.basis.len() {
            let v = self.kern.dev.zeros::<f64>(dim).map_err(SumError::from)?;
            self.basis.push(v);
        }
        // SAFETY: thread i < dim reads w[i] and writes basis[k][i] (dim each).
        unsafe {
            self.kern
                .dev
                .launch(
                    dim,
                    KrylovDiv {
                        src: &self.w,
                        dst: &mut self.basis[k],
                        d,
                        n: int(dim, "unknowns").map_err(SumError::from)?,
                    },
                )
                .map_err(SumError::from)?;
        }
        Ok(())
    }
}
