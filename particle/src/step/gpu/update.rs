//! The rods' update on the device (`update.cu`): see [`super`].
#![allow(unsafe_code)]

use super::device::{GpuStep, int};
use super::signatures::RodUpdate;
use crate::model::geometry::Vec3;
use crate::model::rods::RodSet;
use motile_gpu::{Buffer, GpuError};

/// The rods' state on the device: centres (triples), the images each has crossed (as `i32`
/// triples: a rod would need to cross the box two billion times to overflow one) and unit
/// quaternions (`w, x, y, z`).
#[derive(Debug)]
pub struct DeviceRods {
    /// Centres in `[0, L)^3`.
    pub x: Buffer,
    /// Images crossed since the start.
    pub image: Buffer<i32>,
    /// Unit quaternions.
    pub q: Buffer,
    /// How many rods.
    pub len: usize,
    /// The box side.
    pub box_length: f64,
    /// The rods' diameter.
    pub diameter: f64,
}

impl GpuStep {
    /// Upload the rods' state.
    pub fn upload_rods(&self, rods: &RodSet) -> Result<DeviceRods, GpuError> {
        let image = rods
            .image
            .iter()
            .flatten()
            .map(|&k| i32::try_from(k).map_err(|_| GpuError::Input(format!("image count {k}"))))
            .collect::<Result<Vec<i32>, _>>()?;
        Ok(DeviceRods {
            x: self.dev.upload(&rods.x.concat())?,
            image: self.dev.upload(&image)?,
            q: self.dev.upload(&rods.q.concat())?,
            len: rods.len(),
            box_length: rods.box_length,
            diameter: rods.diameter,
        })
    }

    /// Download the rods' state into `rods` (the same rods: their number and box).
    pub fn download_rods(&self, d: &DeviceRods, rods: &mut RodSet) -> Result<(), GpuError> {
        if rods.len() != d.len || rods.box_length != d.box_length {
            return Err(GpuError::Input(format!(
                "{} rods in a box of {} on the device, {} in a box of {} here",
                d.len,
                d.box_length,
                rods.len(),
                rods.box_length
            )));
        }
        let (x, image, q) = (
            self.dev.download(&d.x)?,
            self.dev.download(&d.image)?,
            self.dev.download(&d.q)?,
        );
        for i in 0..d.len {
            rods.x[i] = [x[3 * i], x[3 * i + 1], x[3 * i + 2]];
            rods.image[i] = [0, 1, 2].map(|k| i64::from(image[3 * i + k]));
            rods.q[i] = [q[4 * i], q[4 * i + 1], q[4 * i + 2], q[4 * i + 3]];
        }
        Ok(())
    }

    /// Move the rods by `dt` with velocities `v` and angular velocities `w` (triples on the
    /// device), as the stepper does.
    pub fn update(
        &self,
        rods: &mut DeviceRods,
        v: &Buffer,
        w: &Buffer,
        dt: f64,
    ) -> Result<(), GpuError> {
        let n = rods.len;
        for (what, b, len) in [
            ("centres", &rods.x, 3 * n),
            ("velocities", v, 3 * n),
            ("angular velocities", w, 3 * n),
            ("quaternions", &rods.q, 4 * n),
        ] {
            if b.len() < len {
                return Err(GpuError::Input(format!(
                    "{what}: {} values for {n} rods",
                    b.len()
                )));
            }
        }
        if rods.image.len() < 3 * n {
            return Err(GpuError::Input(format!(
                "images: {} values for {n} rods",
                rods.image.len()
            )));
        }
        int(4 * n, "4 x rods")?;
        // SAFETY: thread i < n reads and writes x, image, v, w at 3 i..3 i + 3 and q at
        // 4 i..4 i + 4, all checked above to be inside their buffers.
        unsafe {
            self.dev.launch(
                n,
                RodUpdate {
                    x: &mut rods.x,
                    image: &mut rods.image,
                    q: &mut rods.q,
                    v,
                    w,
                    n: int(n, "rods")?,
                    dt,
                    l: rods.box_length,
                },
            )?;
        }
        Ok(())
    }

    /// Upload triples (velocities, angular velocities).
    pub fn upload_triples(&self, t: &[Vec3]) -> Result<Buffer, GpuError> {
        self.dev.upload(&t.concat())
    }
}
