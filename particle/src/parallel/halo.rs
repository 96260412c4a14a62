//! The halo of a rank (docs/MODEL.md §3a): which of its local rods are copies of other ranks'
//! rods, and the collective moves of values between owners and copies.

use crate::parallel::comm::Comm;

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
