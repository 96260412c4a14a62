//! What a device has been asked to do, counted as it is issued: kernel launches (by kernel),
//! 3D transforms, and the transfers between host and device. The counts are the same on CUDA
//! and on the host emulation, so a design's launches, transforms and host round trips can be
//! measured by running it where no GPU is at hand.

use std::collections::BTreeMap;

/// Counts of what a [`crate::Device`] did since it was opened.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Kernel launches, in all.
    pub launches: u64,
    /// Kernel launches by kernel name.
    pub by_kernel: BTreeMap<&'static str, u64>,
    /// 3D transforms of one field, forward (a batch of `b` fields counts `b`).
    pub forward: u64,
    /// 3D transforms of one field, inverse.
    pub inverse: u64,
    /// Uploads (host to device).
    pub uploads: u64,
    /// Bytes uploaded.
    pub upload_bytes: u64,
    /// Downloads (device to host; each waits for the device's queued work: a round trip).
    pub downloads: u64,
    /// Bytes downloaded.
    pub download_bytes: u64,
    /// Copies from one buffer to another on the device (no host round trip).
    pub copies: u64,
    /// Bytes copied on the device (each read once and written once).
    pub copy_bytes: u64,
}

impl Counters {
    /// Add `other`'s counts (another device's: a step on one device whose sums run on
    /// another).
    pub fn add(&mut self, other: &Counters) {
        for (k, v) in &other.by_kernel {
            *self.by_kernel.entry(k).or_insert(0) += v;
        }
        self.launches += other.launches;
        self.forward += other.forward;
        self.inverse += other.inverse;
        self.uploads += other.uploads;
        self.upload_bytes += other.upload_bytes;
        self.downloads += other.downloads;
        self.download_bytes += other.download_bytes;
        self.copies += other.copies;
        self.copy_bytes += other.copy_bytes;
    }

    /// What was done after `before` (an earlier reading of the same device's counters).
    pub fn since(&self, before: &Counters) -> Counters {
        let by_kernel = self
            .by_kernel
            .iter()
            .map(|(k, &v)| (*k, v - before.by_kernel.get(k).copied().unwrap_or(0)))
            .filter(|(_, v)| *v > 0)
            .collect();
        Counters {
            launches: self.launches - before.launches,
            by_kernel,
            forward: self.forward - before.forward,
            inverse: self.inverse - before.inverse,
            uploads: self.uploads - before.uploads,
            upload_bytes: self.upload_bytes - before.upload_bytes,
            downloads: self.downloads - before.downloads,
            download_bytes: self.download_bytes - before.download_bytes,
            copies: self.copies - before.copies,
            copy_bytes: self.copy_bytes - before.copy_bytes,
        }
    }
}
