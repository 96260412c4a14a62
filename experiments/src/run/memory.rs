//! The host and GPU memory a run needs, and the checks that refuse a run this machine or its
//! GPU cannot hold before it allocates (a run of 6e9 rods would otherwise abort inside the
//! allocator).
//!
//! The needs are measured peaks (`/usr/bin/time -v`, maximum resident set, 5 steps, release
//! build, x86_64): a particle run at `sbt` 5.6 kB per rod at nu = 5 (L/l 6 and 12) and 7.5 kB at
//! nu = 0.625 (L/l 8 and 16), the other levels less, so 8 kB per rod and 50 MB besides; a
//! mean-field run 0.82 kB per grid point (32^3 and 64^3), so 1 kB and 50 MB besides.

/// What a run needs: `base + per_item * items` bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HostMemoryNeed {
    /// Rods or grid points.
    pub items: f64,
    /// What the items are ("rods", "grid points").
    pub what: &'static str,
    /// Bytes per item at the step's peak.
    pub per_item: f64,
    /// Bytes besides.
    pub base: f64,
}

impl HostMemoryNeed {
    /// A particle run of `rods` rods on the CPU.
    pub fn particle(rods: usize) -> Self {
        Self {
            items: rods as f64,
            what: "rods",
            per_item: 8e3,
            base: 50e6,
        }
    }

    /// A mean-field run on `grid^3` points on the CPU.
    pub fn meanfield(grid: usize) -> Self {
        Self {
            items: (grid as f64).powi(3),
            what: "grid points",
            per_item: 1e3,
            base: 50e6,
        }
    }

    /// Bytes in all.
    pub fn bytes(&self) -> f64 {
        self.base + self.per_item * self.items
    }

    /// Refuse a need above `available` bytes (`None`: unknown, accepted), with the figures.
    pub fn check(&self, available: Option<u64>) -> anyhow::Result<()> {
        let Some(avail) = available else {
            return Ok(());
        };
        if self.bytes() > avail as f64 {
            anyhow::bail!(
                "the run needs about {:.3} GB of memory ({:.3e} {} x {:.0} bytes at the step's measured peak, and {:.2} GB besides) but this machine has {:.2} GB available; use a smaller box or grid, or a machine with more memory",
                self.bytes() / 1e9,
                self.items,
                self.what,
                self.per_item,
                self.base / 1e9,
                avail as f64 / 1e9
            );
        }
        Ok(())
    }
}

/// The memory this machine can give a new process (`MemAvailable` of /proc/meminfo), where
/// the system says.
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_above_the_available_memory_with_the_figures() {
        let need = HostMemoryNeed::particle(6_000_000_000);
        let e = need.check(Some(24_000_000_000)).unwrap_err().to_string();
        assert!(
            e.contains("48000.050 GB") && e.contains("6.000e9 rods") && e.contains("24.00 GB"),
            "{e}"
        );
        assert!(
            HostMemoryNeed::particle(1000)
                .check(Some(24_000_000_000))
                .is_ok()
        );
        assert!(need.check(None).is_ok(), "unknown memory: accepted");
        assert_eq!(
            HostMemoryNeed::meanfield(64).bytes(),
            50e6 + 1e3 * 262_144.0
        );
    }
}

/// The CUDA context's bytes on the H100 before any buffer (BENCHMARKS.md, "Memory per rod").
pub const CUDA_CONTEXT_BYTES: f64 = 0.55e9;

/// The GPU memory a run needs at its step's peak: the CUDA context and a measured figure per
/// rod or grid point (`ParticleRunConfig::gpu_memory`, `MeanFieldRunConfig::gpu_memory`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuMemoryNeed {
    /// Rods or grid points.
    pub items: usize,
    /// What the items are ("rods", "grid points").
    pub what: &'static str,
    /// Bytes per item at the step's peak.
    pub per_item: f64,
    /// The context's bytes.
    pub context: f64,
}

impl GpuMemoryNeed {
    /// Bytes in all.
    pub fn bytes(&self) -> f64 {
        self.context + self.per_item * self.items as f64
    }

    /// Refuse a need above `device` (`(free, total)` bytes, `None` on the host emulation) or
    /// `limit` bytes, with the figures.
    pub fn check(
        &self,
        device: Option<(usize, usize)>,
        limit: Option<usize>,
    ) -> anyhow::Result<()> {
        let free = match (device, limit) {
            (Some((free, _)), Some(l)) => free.min(l),
            (Some((free, _)), None) => free,
            (None, Some(l)) => l,
            (None, None) => return Ok(()),
        };
        let gb = |b: f64| b / 1e9;
        if self.bytes() > free as f64 {
            let of = device.map_or(" (MOTILE_GPU_MEMORY_LIMIT)".to_string(), |(f, t)| {
                format!(
                    " ({:.2} GB free of {:.2} GB{})",
                    gb(f as f64),
                    gb(t as f64),
                    if limit.is_some() {
                        ", MOTILE_GPU_MEMORY_LIMIT lower"
                    } else {
                        ""
                    }
                )
            });
            anyhow::bail!(
                "device = \"gpu\": the run needs about {:.2} GB of GPU memory ({} {} x {:.0} bytes at the step's measured peak, and the context's {:.2} GB) but may use {:.2} GB{of}; use a smaller {}, a GPU with more memory, or device = \"cpu\"",
                gb(self.bytes()),
                self.items,
                self.what,
                self.per_item,
                gb(self.context),
                gb(free as f64),
                if self.what == "rods" { "box" } else { "grid" }
            );
        }
        Ok(())
    }
}

/// `MOTILE_GPU_MEMORY_LIMIT`: bytes of GPU memory a run may assume, below the device's free
/// memory (a GPU shared with other work; on the host emulation, the memory the checks see).
/// `None` where unset; a value that is not a whole number of bytes is an error naming it.
pub fn gpu_memory_limit() -> anyhow::Result<Option<usize>> {
    match std::env::var("MOTILE_GPU_MEMORY_LIMIT") {
        Err(_) => Ok(None),
        Ok(v) => v.trim().parse().map(Some).map_err(|_| {
            anyhow::anyhow!(
                "MOTILE_GPU_MEMORY_LIMIT = {v:?}: expected a whole number of bytes (e.g. 40000000000)"
            )
        }),
    }
}
