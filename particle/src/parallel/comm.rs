//! One box shared by several processes (docs/MODEL.md §3a; the distributed driver of
//! [`crate::step::distributed`]): the collective operations a step needs ([`Comm`]); the
//! halo that ties each rank's copies of its neighbours' rods to their owners is
//! [`crate::parallel::halo::Halo`].
//!
//! A rank holds its own rods first (`0..owned`) and copies of other ranks' rods after them. The
//! step runs on that local set: a constraint belongs to the rank that owns its pair's
//! smaller-numbered rod, forces on copies are added into their owners
//! (`Halo::accumulate`), and owners' velocities are copied back (`Halo::refresh`). Sums over
//! ranks are taken in rank order, so every rank gets the same bits and the result does not
//! depend on timing.
//!
//! The single-process case is [`SingleProcess`] with `Halo::none`: every operation is the
//! identity, and the step computes exactly what it computed before ranks existed.

use std::fmt::Debug;
use std::sync::{Arc, Barrier, Mutex};

/// What the ranks sharing a box can do together. Every method is collective: all ranks call it
/// in the same order, or the run deadlocks.
pub trait Comm: Send + Sync + Debug {
    /// This rank, `0..size`.
    fn rank(&self) -> usize;
    /// Number of ranks.
    fn size(&self) -> usize;
    /// All-to-all exchange: `send[r]` goes to rank `r` (`send.len() == size`); returns what
    /// each rank sent here, indexed by sender.
    fn exchange(&self, send: Vec<Vec<f64>>) -> Vec<Vec<f64>>;

    /// Elementwise sum over ranks, added in rank order (the same bits on every rank).
    fn sum(&self, v: &mut [f64]) {
        if self.size() == 1 {
            return;
        }
        let all = self.exchange(vec![v.to_vec(); self.size()]);
        for (k, x) in v.iter_mut().enumerate() {
            *x = all.iter().fold(0.0, |acc, a| acc + a[k]);
        }
    }

    /// Elementwise maximum over ranks.
    fn max(&self, v: &mut [f64]) {
        if self.size() == 1 {
            return;
        }
        let all = self.exchange(vec![v.to_vec(); self.size()]);
        for (k, x) in v.iter_mut().enumerate() {
            *x = all.iter().fold(f64::NEG_INFINITY, |acc, a| acc.max(a[k]));
        }
    }

    /// Every rank's `v`, indexed by rank.
    fn all_gather(&self, v: &[f64]) -> Vec<Vec<f64>> {
        if self.size() == 1 {
            return vec![v.to_vec()];
        }
        self.exchange(vec![v.to_vec(); self.size()])
    }
}

impl<T: Comm + ?Sized> Comm for &T {
    fn rank(&self) -> usize {
        (**self).rank()
    }

    fn size(&self) -> usize {
        (**self).size()
    }

    fn exchange(&self, send: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        (**self).exchange(send)
    }

    fn sum(&self, v: &mut [f64]) {
        (**self).sum(v)
    }

    fn max(&self, v: &mut [f64]) {
        (**self).max(v)
    }

    fn all_gather(&self, v: &[f64]) -> Vec<Vec<f64>> {
        (**self).all_gather(v)
    }
}

/// One process owning the whole box.
#[derive(Clone, Copy, Debug, Default)]
pub struct SingleProcess;

impl Comm for SingleProcess {
    fn rank(&self) -> usize {
        0
    }

    fn size(&self) -> usize {
        1
    }

    fn exchange(&self, send: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        send
    }
}

/// Ranks as threads of one process (for tests of the distributed step without MPI, and for
/// sharing one box among thread groups): [`ThreadRanks::group`] makes the ranks, each moved
/// into its own thread.
#[derive(Debug)]
pub struct ThreadRanks {
    rank: usize,
    shared: Arc<Mailbox>,
}

#[derive(Debug)]
struct Mailbox {
    /// `slots[to][from]`.
    slots: Mutex<Vec<Vec<Vec<f64>>>>,
    barrier: Barrier,
    size: usize,
}

impl ThreadRanks {
    /// `size` ranks sharing one mailbox.
    pub fn group(size: usize) -> Vec<ThreadRanks> {
        let shared = Arc::new(Mailbox {
            slots: Mutex::new(vec![vec![Vec::new(); size]; size]),
            barrier: Barrier::new(size),
            size,
        });
        (0..size)
            .map(|rank| ThreadRanks {
                rank,
                shared: Arc::clone(&shared),
            })
            .collect()
    }
}

impl Comm for ThreadRanks {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.shared.size
    }

    fn exchange(&self, send: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        assert_eq!(send.len(), self.size(), "one message per rank");
        {
            let mut slots = self.shared.slots.lock().expect("a rank panicked");
            for (to, m) in send.into_iter().enumerate() {
                slots[to][self.rank] = m;
            }
        }
        // Everyone has posted; take this rank's messages, then wait until every rank has taken
        // its own before the slots are reused.
        self.shared.barrier.wait();
        let got = {
            let mut slots = self.shared.slots.lock().expect("a rank panicked");
            slots[self.rank].iter_mut().map(std::mem::take).collect()
        };
        self.shared.barrier.wait();
        got
    }
}
