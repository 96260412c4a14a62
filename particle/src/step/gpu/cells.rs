//! The rods' cell list and neighbour pairs on the device (`cells.cu`): see [`super`].
#![allow(unsafe_code)]

use super::device::{GpuStep, int};
use super::signatures::{CellCount, CellOrder, CellScatter, PairCount, PairWrite};
use crate::model::geometry::Vec3;
use motile_gpu::{Buffer, GpuError};

/// The neighbour pairs of one configuration, on the device.
#[derive(Debug)]
pub struct DevicePairs {
    /// First members `i` of the pairs, sorted (the first `len` values).
    pub first: Buffer<i32>,
    /// Second members `j > i`, increasing for each `i`.
    pub second: Buffer<i32>,
    /// How many pairs.
    pub len: usize,
    /// Cells per axis.
    pub cells_per_side: usize,
}

/// Points sorted into the cells of a box on the device.
struct DeviceCells {
    /// Each point's cell.
    cell: Buffer<i32>,
    /// Each cell's first member in `members` (`nc^3 + 1` values).
    start: Buffer<i32>,
    /// The points cell by cell, ascending within a cell.
    members: Buffer<i32>,
    /// How many points.
    n: usize,
    /// Cells per axis.
    nc: usize,
    /// The box side.
    box_length: f64,
}

impl GpuStep {
    /// Every pair `(i, j)`, `i < j`, of the centres `x` (in `[0, L)^3`) closer than `cutoff`
    /// (minimum image), sorted: built on the device and downloaded.
    pub fn pairs(
        &self,
        x: &[Vec3],
        box_length: f64,
        cutoff: f64,
    ) -> Result<Vec<(u32, u32)>, GpuError> {
        let flat: Vec<f64> = x.iter().flatten().copied().collect();
        let pts = self.dev.upload(&flat)?;
        let p = self.build(&pts, x.len(), box_length, cutoff)?;
        let (a, b) = (
            self.dev.download_range(&p.first, 0, p.len)?,
            self.dev.download_range(&p.second, 0, p.len)?,
        );
        Ok(a.iter()
            .zip(&b)
            .map(|(&i, &j)| (i as u32, j as u32))
            .collect())
    }

    /// The pairs of the `n` centres `pts` (x, y, z triples) closer than `cutoff`, left on the
    /// device. The box must hold at least 3 cells of side `cutoff` per axis (smaller boxes
    /// are the CPU's: [`GpuError::Input`]).
    pub fn build(
        &self,
        pts: &Buffer,
        n: usize,
        box_length: f64,
        cutoff: f64,
    ) -> Result<DevicePairs, GpuError> {
        let nc = ((box_length / cutoff).floor() as usize).max(1);
        if nc < 3 {
            return Err(GpuError::Input(format!(
                "the device cell list needs at least 3 cells per axis: L = {box_length} holds \
                 {nc} of side {cutoff}"
            )));
        }
        if pts.len() < 3 * n {
            return Err(GpuError::Input(format!(
                "centres: {} values for {n} points",
                pts.len()
            )));
        }
        int(n, "points")?;
        int(nc.pow(3), "cells")?;
        int(3 * n, "3 x points")?;
        let cells = self.sort_into_cells(pts, n, box_length, nc)?;
        self.pairs_within(pts, &cells, cutoff)
    }

    /// The `n` points sorted into `nc^3` cells of a box of side `box_length`: each point's
    /// cell, the cells' starts and their members in ascending order (a counting sort: an
    /// atomic count, a prefix sum, an atomic scatter, then each cell's members sorted).
    fn sort_into_cells(
        &self,
        pts: &Buffer,
        n: usize,
        box_length: f64,
        nc: usize,
    ) -> Result<DeviceCells, GpuError> {
        let ncells = nc.pow(3);
        let (ni, nci, ncells_i) = (
            int(n, "points")?,
            int(nc, "cells per axis")?,
            int(ncells, "cells")?,
        );
        let dev = &self.dev;
        let mut cell = dev.zeros::<i32>(n)?;
        let mut count = dev.zeros::<i32>(ncells)?;
        let mut start = dev.zeros::<i32>(ncells + 1)?;
        let mut fill = dev.zeros::<i32>(ncells)?;
        let mut members = dev.zeros::<i32>(n)?;
        // SAFETY: thread i < n reads pts[3 i..3 i + 3] (3 n checked), writes cell[i] (n) and
        // adds to count[k], k = (z nc + y) nc + x with each index clamped to 0..nc, so k < nc^3.
        unsafe {
            dev.launch(
                n,
                CellCount {
                    x: pts,
                    cell: &mut cell,
                    count: &mut count,
                    n: ni,
                    nc: nci,
                    l: box_length,
                },
            )?;
        }
        self.scan(&count, &mut start, ncells)?;
        // SAFETY: thread i < n reads cell[i] < ncells, start[cell] and adds to fill[cell]
        // (ncells); the ranks of a cell are 0..count[cell], so start[cell] + rank <
        // start[cell + 1] <= n indexes members (n).
        unsafe {
            dev.launch(
                n,
                CellScatter {
                    cell: &cell,
                    start: &start,
                    fill: &mut fill,
                    members: &mut members,
                    n: ni,
                },
            )?;
        }
        // SAFETY: thread c < ncells reads start[c], start[c + 1] (ncells + 1) and sorts
        // members[start[c]..start[c + 1]], inside 0..n.
        unsafe {
            dev.launch(
                ncells,
                CellOrder {
                    start: &start,
                    members: &mut members,
                    ncells: ncells_i,
                },
            )?;
        }
        Ok(DeviceCells {
            cell,
            start,
            members,
            n,
            nc,
            box_length,
        })
    }

    /// Every pair of points of `cells` closer than `cutoff`: counted per point, the counts'
    /// prefix sum, then written by the same search.
    fn pairs_within(
        &self,
        pts: &Buffer,
        cells: &DeviceCells,
        cutoff: f64,
    ) -> Result<DevicePairs, GpuError> {
        let (n, nc) = (cells.n, cells.nc);
        let (ni, nci) = (int(n, "points")?, int(nc, "cells per axis")?);
        let (l, c2) = (cells.box_length, cutoff * cutoff);
        let dev = &self.dev;
        let mut counts = dev.zeros::<i32>(n)?;
        let mut offset = dev.zeros::<i32>(n + 1)?;
        // SAFETY: thread i < n reads pts (3 n), cell[i], the starts of 27 cells (< ncells,
        // wrapped into 0..nc per axis) and the members between them (< n), and writes
        // counts[i] (n).
        unsafe {
            dev.launch(
                n,
                PairCount {
                    x: pts,
                    cell: &cells.cell,
                    start: &cells.start,
                    members: &cells.members,
                    counts: &mut counts,
                    n: ni,
                    nc: nci,
                    l,
                    c2,
                },
            )?;
        }
        self.scan(&counts, &mut offset, n)?;
        let total = dev.download_range(&offset, n, 1)?[0];
        let len = usize::try_from(total)
            .map_err(|_| GpuError::Input(format!("{total} pairs: the count overflowed")))?;
        // At least one value each (a device allocation of nothing fails); `len` says how many
        // are pairs.
        let mut first = dev.zeros::<i32>(len.max(1))?;
        let mut second = dev.zeros::<i32>(len.max(1))?;
        // SAFETY: thread i < n reads as pair_count and offset[i] (n + 1), and writes its
        // counts[i] pairs at offset[i]..offset[i + 1] <= total = len (allocated): the write
        // pass finds the same neighbours as the count pass (same inputs, same arithmetic).
        unsafe {
            dev.launch(
                n,
                PairWrite {
                    x: pts,
                    cell: &cells.cell,
                    start: &cells.start,
                    members: &cells.members,
                    offset: &offset,
                    first: &mut first,
                    second: &mut second,
                    n: ni,
                    nc: nci,
                    l,
                    c2,
                },
            )?;
        }
        Ok(DevicePairs {
            first,
            second,
            len,
            cells_per_side: nc,
        })
    }
}
