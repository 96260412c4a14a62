//! The contact constraints of the neighbour pairs on the device (`contacts.cu`): see [`super`].
#![allow(unsafe_code)]

use super::cells::DevicePairs;
use super::device::{GpuStep, int};
use super::signatures::{ContactFlag, ContactWrite};
use super::update::DeviceRods;
use crate::step::contact::Constraint;
use motile_gpu::{Buffer, GpuError};

/// The constraints of one configuration on the device, in the pairs' order.
#[derive(Debug)]
pub struct DeviceConstraints {
    /// First rods (the first `len` values).
    pub i: Buffer<i32>,
    /// Second rods.
    pub j: Buffer<i32>,
    /// Rows of 10: `ri`, `rj`, `n`, `phi` ([`Constraint`]'s fields).
    pub rows: Buffer,
    /// How many constraints.
    pub len: usize,
}

impl GpuStep {
    /// The constraint of every pair whose centerlines are closer than `b + margin`
    /// ([`crate::step::constraints::constraint`]), in the pairs' order: a flag per pair, their
    /// prefix sum, the constraints written at it (no atomics).
    pub fn constraints(
        &self,
        rods: &DeviceRods,
        pairs: &DevicePairs,
        margin: f64,
    ) -> Result<DeviceConstraints, GpuError> {
        let np = pairs.len;
        let n = rods.len;
        if rods.x.len() < 3 * n || rods.q.len() < 4 * n {
            return Err(GpuError::Input(format!(
                "rods: buffers shorter than {n} rods"
            )));
        }
        if pairs.first.len() < np || pairs.second.len() < np {
            return Err(GpuError::Input(format!("pairs: buffers shorter than {np}")));
        }
        let npi = int(np, "pairs")?;
        int(10 * np, "10 x pairs")?;
        let dev = &self.dev;
        let mut flag = dev.zeros::<i32>(np.max(1))?;
        let mut at = dev.zeros::<i32>(np + 1)?;
        // SAFETY: thread k < np reads first[k], second[k] (np checked), which are rod indices
        // below n (the pairs of these rods), x at 3 i..3 i + 3 and q at 4 i..4 i + 4 of both
        // (checked), and writes flag[k] (np).
        unsafe {
            dev.launch(
                np,
                ContactFlag {
                    x: &rods.x,
                    q: &rods.q,
                    first: &pairs.first,
                    second: &pairs.second,
                    flag: &mut flag,
                    npairs: npi,
                    l: rods.box_length,
                    b: rods.diameter,
                    margin,
                },
            )?;
        }
        self.scan(&flag, &mut at, np)?;
        let len = dev.download_range(&at, np, 1)?[0] as usize;
        let mut ci = dev.zeros::<i32>(len.max(1))?;
        let mut cj = dev.zeros::<i32>(len.max(1))?;
        let mut rows = dev.zeros::<f64>(10 * len.max(1))?;
        // SAFETY: thread k < np with flag[k] = 1 reads as contact_flag and at[k] < len (the
        // flags' exclusive prefix sum, total len), and writes ci, cj at at[k] (len) and rows
        // at 10 at[k]..10 at[k] + 10 (10 len).
        unsafe {
            dev.launch(
                np,
                ContactWrite {
                    x: &rods.x,
                    q: &rods.q,
                    first: &pairs.first,
                    second: &pairs.second,
                    flag: &flag,
                    at: &at,
                    ci: &mut ci,
                    cj: &mut cj,
                    rows: &mut rows,
                    npairs: npi,
                    l: rods.box_length,
                    b: rods.diameter,
                    margin,
                },
            )?;
        }
        Ok(DeviceConstraints {
            i: ci,
            j: cj,
            rows,
            len,
        })
    }

    /// Download constraints into the CPU's form.
    pub fn download_constraints(&self, c: &DeviceConstraints) -> Result<Vec<Constraint>, GpuError> {
        let (i, j, r) = (
            self.dev.download_range(&c.i, 0, c.len)?,
            self.dev.download_range(&c.j, 0, c.len)?,
            self.dev.download_range(&c.rows, 0, 10 * c.len)?,
        );
        Ok((0..c.len)
            .map(|k| {
                let row = &r[10 * k..10 * k + 10];
                Constraint {
                    i: i[k] as u32,
                    j: j[k] as u32,
                    ri: [row[0], row[1], row[2]],
                    rj: [row[3], row[4], row[5]],
                    n: [row[6], row[7], row[8]],
                    phi: row[9],
                }
            })
            .collect())
    }
}
