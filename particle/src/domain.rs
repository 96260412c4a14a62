//! One box shared by several processes (docs/MODEL.md §3; the distributed driver of
//! [`crate::distributed`]): the collective operations a step needs ([`Comm`]) and the halo that
//! ties each rank's copies of its neighbours' rods to their owners ([`Halo`]).
//!
//! A rank holds its own rods first (`0..owned`) and copies of other ranks' rods after them. The
//! step runs on that local set: a constraint belongs to the rank that owns its pair's
//! smaller-numbered rod, forces on copies are added into their owners
//! ([`Halo::accumulate`]), and owners' velocities are copied back ([`Halo::refresh`]). Sums over
//! ranks are taken in rank order, so every rank gets the same bits and the result does not
//! depend on timing.
//!
//! The single-process case is [`SingleProcess`] with [`Halo::none`]: every operation is the
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

/// Which local rods are copies of which ranks' rods.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Halo {
    /// Local rods `0..owned` belong to this rank; the rest are copies.
    pub owned: usize,
    /// `send[r]`: local indices of this rank's rods that rank `r` holds copies of, in the order
    /// of `r`'s copies.
    pub(crate) send: Vec<Vec<u32>>,
    /// `recv[r]`: local indices of the copies of rank `r`'s rods, in `r`'s send order.
    pub(crate) recv: Vec<Vec<u32>>,
}

impl Halo {
    /// No copies: `owned` rods, all this rank's.
    pub fn none(owned: usize) -> Self {
        Self {
            owned,
            send: Vec::new(),
            recv: Vec::new(),
        }
    }

    /// The same halo with local rod `k` renamed `new[k]` (`owned` then no longer marks the own
    /// rods: the renumbered halo serves only to move values).
    pub(crate) fn renumbered(&self, new: &[u32]) -> Self {
        let map = |v: &Vec<Vec<u32>>| -> Vec<Vec<u32>> {
            v.iter()
                .map(|l| l.iter().map(|&k| new[k as usize]).collect())
                .collect()
        };
        Self {
            owned: self.owned,
            send: map(&self.send),
            recv: map(&self.recv),
        }
    }

    /// Copy each owner's values to its copies on other ranks (collective).
    pub fn refresh<const K: usize>(&self, comm: &dyn Comm, vals: &mut [[f64; K]]) {
        self.refresh_rows(comm, vals.as_flattened_mut(), K);
    }

    /// [`Self::refresh`] for rows of `width` values, one per local rod, laid end to end.
    pub fn refresh_rows(&self, comm: &dyn Comm, vals: &mut [f64], width: usize) {
        transfer(comm, (&self.send, &self.recv), vals, width, false);
    }

    /// Add the values on copies into their owners, in rank order after the owner's own
    /// (collective); copies keep their values.
    pub fn accumulate<const K: usize>(&self, comm: &dyn Comm, vals: &mut [[f64; K]]) {
        transfer(
            comm,
            (&self.recv, &self.send),
            vals.as_flattened_mut(),
            K,
            true,
        );
    }
}

/// Send row `k` of `vals` (rows of `width` values) for `k` in `from[r]` to rank `r`, which
/// writes (or with `add`, adds) them at its `to[me]` in order (collective).
fn transfer(
    comm: &dyn Comm,
    (from, to): (&[Vec<u32>], &[Vec<u32>]),
    vals: &mut [f64],
    width: usize,
    add: bool,
) {
    if comm.size() == 1 || width == 0 {
        return;
    }
    let row = |k: u32| k as usize * width..(k as usize + 1) * width;
    let send = (0..comm.size())
        .map(|r| match from.get(r) {
            Some(list) => list
                .iter()
                .flat_map(|&k| vals[row(k)].iter().copied())
                .collect(),
            None => Vec::new(),
        })
        .collect();
    let got = comm.exchange(send);
    for (r, data) in got.iter().enumerate() {
        let Some(list) = to.get(r) else {
            continue;
        };
        for (&k, chunk) in list.iter().zip(data.chunks_exact(width)) {
            let v = &mut vals[row(k)];
            if add {
                v.iter_mut().zip(chunk).for_each(|(v, c)| *v += c);
            } else {
                v.copy_from_slice(chunk);
            }
        }
    }
}

/// The maximum over ranks of `value` and its `key`, ties to the smallest key (compared in
/// order; collective: every rank gets the same pair).
pub(crate) fn max_with_key(comm: &dyn Comm, value: f64, key: [f64; 2]) -> (f64, [f64; 2]) {
    if comm.size() == 1 {
        return (value, key);
    }
    let all = comm.all_gather(&[value, key[0], key[1]]);
    all.iter()
        .fold((f64::NEG_INFINITY, [f64::INFINITY; 2]), |a, b| {
            let k = [b[1], b[2]];
            if b[0] > a.0 || (b[0] == a.0 && k < a.1) {
                (b[0], k)
            } else {
                a
            }
        })
}
