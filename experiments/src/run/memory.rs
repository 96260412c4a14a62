//! The host memory a run needs, and the check that refuses a run this machine cannot hold
//! before it allocates (a run of 6e9 rods would otherwise abort inside the allocator).
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
