//! The particle model on several ranks (docs/MODEL.md §3): spatial slabs along `z`, each rank
//! owning the rods whose centres lie in its slab, with copies of the other ranks' rods within
//! contact reach ([`crate::parallel::halo::Halo`]). A step ([`Distributed::step`]):
//!
//! 1. the slab bounds are rebalanced so that each holds as many rods as it can (from a
//!    histogram of all centres, summed over ranks), and rods whose centres left their slab move
//!    to the new owner with the contact multipliers of the pairs they own (the warm start);
//! 2. each rank sends copies of its rods within reach `l + b + margin` (in `z`, periodic) of
//!    another slab to that slab's rank;
//! 3. [`Stepper::step_part`] advances the local rods: contacts owned by the rank of the pair's
//!    smaller-numbered rod, the contact solver's operator applied across ranks (forces on
//!    copies added into their owners, velocities copied back), sums and maxima over all ranks;
//! 4. the copies are dropped.
//!
//! Every rank holds only its own rods between steps; [`Distributed::gather`] brings the whole
//! state to rank 0 (for outputs and checkpoints, in the single-process numbering, so a
//! checkpoint restarts on any rank count).
//!
//! Results agree with the single-process step within the contact solver's tolerance: the
//! iteration is the same, but sums over constraints are added per rank and then in rank order,
//! so their round-off differs. On one rank the step is the single-process step, bit for bit.

use crate::model::geometry::Vec3;
use crate::model::rods::RodSet;
use crate::model::units::ROD_LENGTH;
use crate::parallel::comm::Comm;
use crate::parallel::halo::Halo;
use crate::parallel::part::Part;
use crate::step::contact::WarmStart;
use crate::step::report::{StepError, StepReport};
use crate::step::stepper::Stepper;
use std::collections::HashMap;

/// Histogram bins per rank for the slab balance.
const BINS_PER_RANK: usize = 256;

/// Slab bounds along `z`: rank `r` owns `bounds[r] <= z < bounds[r + 1]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Slabs {
    bounds: Vec<f64>,
}

impl Slabs {
    /// Bounds that split the centres `z` (all rods of a box of side `l`) into `ranks` slabs of
    /// as equal counts as bins of `l / (256 ranks)` allow (slabs may be empty when rods pile up).
    pub fn balanced(ranks: usize, l: f64, counts: &[f64]) -> Self {
        let bins = counts.len();
        let total: f64 = counts.iter().sum();
        let mut bounds = vec![0.0; ranks + 1];
        bounds[ranks] = l;
        let mut cumulative = 0.0;
        let mut next = 1;
        for (b, c) in counts.iter().enumerate() {
            cumulative += c;
            while next < ranks && cumulative >= total * next as f64 / ranks as f64 {
                bounds[next] = l * (b + 1) as f64 / bins as f64;
                next += 1;
            }
        }
        for k in next..ranks {
            bounds[k] = l;
        }
        Self { bounds }
    }

    /// The histogram of centres `z` in a box of side `l` that [`Self::balanced`] takes.
    pub fn histogram(ranks: usize, l: f64, z: impl Iterator<Item = f64>) -> Vec<f64> {
        let bins = BINS_PER_RANK * ranks;
        let mut counts = vec![0.0; bins];
        for z in z {
            counts[((z / l * bins as f64) as usize).min(bins - 1)] += 1.0;
        }
        counts
    }

    /// The rank whose slab holds `z`.
    pub fn owner(&self, z: f64) -> usize {
        let ranks = self.bounds.len() - 1;
        self.bounds[1..ranks].partition_point(|&b| b <= z)
    }

    /// Periodic distance from `z` to slab `r` (zero inside it).
    fn distance(&self, r: usize, z: f64, l: f64) -> f64 {
        let (lo, hi) = (self.bounds[r], self.bounds[r + 1]);
        if lo >= hi {
            return f64::INFINITY;
        }
        if (lo..hi).contains(&z) {
            return 0.0;
        }
        (lo - z).rem_euclid(l).min((z - hi).rem_euclid(l))
    }
}

/// Values per rod in a message: centre, quaternion, image counters, number.
const RECORD: usize = 11;

fn push_record(buf: &mut Vec<f64>, rods: &RodSet, k: usize, id: u32) {
    buf.extend_from_slice(&rods.x[k]);
    buf.extend_from_slice(&rods.q[k]);
    buf.extend(rods.image[k].iter().map(|&i| i as f64));
    buf.push(f64::from(id));
}

fn pop_records(buf: &[f64], rods: &mut RodSet, ids: &mut Vec<u32>) {
    for r in buf.chunks_exact(RECORD) {
        rods.x.push([r[0], r[1], r[2]]);
        rods.q.push([r[3], r[4], r[5], r[6]]);
        rods.image.push([r[7] as i64, r[8] as i64, r[9] as i64]);
        ids.push(r[10] as u32);
    }
}

/// One rank's share of a particle run on several ranks.
#[derive(Debug)]
pub struct Distributed<C: Comm> {
    comm: C,
    stepper: Stepper,
    /// This rank's own rods (between steps: no copies).
    rods: RodSet,
    /// Their numbers in the whole box.
    ids: Vec<u32>,
    total: usize,
    slabs: Slabs,
    last_halo: usize,
}

impl<C: Comm> Distributed<C> {
    /// This rank's share of `all` (the whole box, the same on every rank; its numbering is the
    /// rods' numbers from now on), stepped by `stepper`, whose warm start may be the whole
    /// box's (this rank keeps the pairs it owns).
    pub fn new(comm: C, mut stepper: Stepper, all: &RodSet) -> Self {
        let ranks = comm.size();
        let l = all.box_length;
        let slabs = Slabs::balanced(
            ranks,
            l,
            &Slabs::histogram(ranks, l, all.x.iter().map(|x| x[2])),
        );
        let me = comm.rank();
        let mine: Vec<usize> = (0..all.len())
            .filter(|&k| slabs.owner(all.x[k][2]) == me)
            .collect();
        let rods = RodSet {
            box_length: l,
            diameter: all.diameter,
            x: mine.iter().map(|&k| all.x[k]).collect(),
            q: mine.iter().map(|&k| all.q[k]).collect(),
            image: mine.iter().map(|&k| all.image[k]).collect(),
        };
        let ids = mine.iter().map(|&k| k as u32).collect();
        let own = |a: u32| slabs.owner(all.x[a as usize][2]) == me;
        let warm = stepper
            .warm_start()
            .iter()
            .filter(|((a, _), _)| own(*a))
            .copied()
            .collect();
        stepper.set_warm_start(warm);
        // The mobility's per-rod state (the slender-body solution and flow), if it has the
        // whole box's: the own rods' rows.
        let width = stepper.mobility().rod_state_width();
        let rows = match stepper.mobility().rod_state() {
            Some(rows) if width > 0 && rows.len() == width * all.len() => mine
                .iter()
                .flat_map(|&k| rows[k * width..(k + 1) * width].to_vec())
                .collect(),
            _ => Vec::new(),
        };
        stepper.mobility_mut().set_rod_state(rows);
        Self {
            comm,
            stepper,
            rods,
            ids,
            total: all.len(),
            slabs,
            last_halo: 0,
        }
    }

    /// The ranks.
    pub fn comm(&self) -> &C {
        &self.comm
    }

    /// The stepper (its velocities and contact forces are the last step's local rods': own
    /// rods first, in the order of [`Self::ids`]).
    pub fn stepper(&self) -> &Stepper {
        &self.stepper
    }

    /// The stepper, to change its settings between steps (every rank must make the same
    /// change: the ranks' steps are collective).
    pub fn stepper_mut(&mut self) -> &mut Stepper {
        &mut self.stepper
    }

    /// This rank's own rods.
    pub fn rods(&self) -> &RodSet {
        &self.rods
    }

    /// Their numbers in the whole box.
    pub fn ids(&self) -> &[u32] {
        &self.ids
    }

    /// Copies this rank held in the last step.
    pub fn last_halo(&self) -> usize {
        self.last_halo
    }

    /// Rebalance the slabs and move rods that left theirs, with the warm start of the pairs
    /// they own and the mobility's state of each rod (collective).
    fn migrate(&mut self) {
        let (ranks, me, l) = (self.comm.size(), self.comm.rank(), self.rods.box_length);
        let mut counts = Slabs::histogram(ranks, l, self.rods.x.iter().map(|x| x[2]));
        self.comm.sum(&mut counts);
        self.slabs = Slabs::balanced(ranks, l, &counts);
        let dest: Vec<usize> = self.rods.x.iter().map(|x| self.slabs.owner(x[2])).collect();
        // Each rod's mobility state, when this rank has it for every own rod.
        let width = self.stepper.mobility().rod_state_width();
        let state = self
            .stepper
            .mobility()
            .rod_state()
            .filter(|s| width > 0 && s.len() == width * self.rods.len());
        let row = |k: usize| state.as_ref().map(|s| &s[k * width..(k + 1) * width]);
        let mut send = vec![Vec::new(); ranks];
        let mut send_state = vec![Vec::new(); ranks];
        let mut leaving: HashMap<u32, usize> = HashMap::new();
        for (k, &r) in dest.iter().enumerate() {
            if r != me {
                push_record(&mut send[r], &self.rods, k, self.ids[k]);
                if let Some(v) = row(k) {
                    send_state[r].extend_from_slice(v);
                }
                leaving.insert(self.ids[k], r);
            }
        }
        // Warm-start entries of pairs whose first rod leaves, as (a, b, lambda) after the rods.
        let mut warm_send = vec![Vec::new(); ranks];
        let mut kept_warm = Vec::new();
        for &((a, b), lam) in self.stepper.warm_start() {
            match leaving.get(&a) {
                Some(&r) => warm_send[r].extend([f64::from(a), f64::from(b), lam]),
                None => kept_warm.push(((a, b), lam)),
            }
        }
        // One message per rank: the rod count, whether their states follow, the rods, their
        // states, then the warm entries.
        let has_state = if state.is_some() { 1.0 } else { 0.0 };
        let messages = send
            .into_iter()
            .zip(send_state)
            .zip(warm_send)
            .map(|((rods, states), warm)| {
                let mut m = vec![(rods.len() / RECORD) as f64, has_state];
                m.extend(rods);
                m.extend(states);
                m.extend(warm);
                m
            })
            .collect();
        let got = self.comm.exchange(messages);
        let keep: Vec<usize> = (0..dest.len()).filter(|&k| dest[k] == me).collect();
        let mut rods = RodSet {
            box_length: l,
            diameter: self.rods.diameter,
            x: keep.iter().map(|&k| self.rods.x[k]).collect(),
            q: keep.iter().map(|&k| self.rods.q[k]).collect(),
            image: keep.iter().map(|&k| self.rods.image[k]).collect(),
        };
        let mut ids: Vec<u32> = keep.iter().map(|&k| self.ids[k]).collect();
        // The new own rods' states; incomplete (dropped below) if some rod came without one.
        let mut complete = state.is_some();
        let mut states: Vec<f64> = keep
            .iter()
            .filter_map(|&k| row(k))
            .flatten()
            .copied()
            .collect();
        for (r, m) in got.iter().enumerate() {
            if r == me || m.is_empty() {
                continue;
            }
            let (count, with_state) = (m[0] as usize, m[1] > 0.0);
            let (rod_part, rest) = m[2..].split_at(count * RECORD);
            pop_records(rod_part, &mut rods, &mut ids);
            let rest = if with_state {
                let (s, rest) = rest.split_at(count * width);
                states.extend_from_slice(s);
                rest
            } else {
                complete &= count == 0;
                rest
            };
            for w in rest.chunks_exact(3) {
                kept_warm.push(((w[0] as u32, w[1] as u32), w[2]));
            }
        }
        kept_warm.sort_unstable_by_key(|w| w.0);
        self.stepper.set_warm_start(kept_warm);
        // Own rods in number order: the local numbering (and so every sum's order) is then a
        // function of the state alone, the same in a run resumed from a checkpoint.
        let mut perm: Vec<usize> = (0..ids.len()).collect();
        perm.sort_unstable_by_key(|&k| ids[k]);
        self.rods = RodSet {
            box_length: l,
            diameter: rods.diameter,
            x: perm.iter().map(|&k| rods.x[k]).collect(),
            q: perm.iter().map(|&k| rods.q[k]).collect(),
            image: perm.iter().map(|&k| rods.image[k]).collect(),
        };
        self.ids = perm.iter().map(|&k| ids[k]).collect();
        let rows = if complete {
            perm.iter()
                .flat_map(|&k| states[k * width..(k + 1) * width].to_vec())
                .collect()
        } else {
            Vec::new()
        };
        self.stepper.mobility_mut().set_rod_state(rows);
    }

    /// The local set: own rods, then copies of other ranks' rods within `reach` of this slab;
    /// with their numbers and the halo (collective).
    fn with_copies(&self, reach: f64) -> (RodSet, Vec<u32>, Halo) {
        let (ranks, me, l) = (self.comm.size(), self.comm.rank(), self.rods.box_length);
        let mut send_idx = vec![Vec::new(); ranks];
        let mut send = vec![Vec::new(); ranks];
        for (k, x) in self.rods.x.iter().enumerate() {
            for r in 0..ranks {
                if r != me && self.slabs.distance(r, x[2], l) <= reach {
                    send_idx[r].push(k as u32);
                    push_record(&mut send[r], &self.rods, k, self.ids[k]);
                }
            }
        }
        let got = self.comm.exchange(send);
        let mut local = self.rods.clone();
        let mut ids = self.ids.clone();
        let owned = local.len();
        let mut recv = vec![Vec::new(); ranks];
        for (r, m) in got.iter().enumerate() {
            if r == me {
                continue;
            }
            let start = local.len();
            pop_records(m, &mut local, &mut ids);
            recv[r] = (start as u32..local.len() as u32).collect();
        }
        let halo = Halo {
            owned,
            send: send_idx,
            recv,
        };
        (local, ids, halo)
    }

    /// Advance by `dt` (collective). On an error every rank returns it and keeps the state
    /// before the step (its rods, the contact warm start, the mobility's per-rod state and its
    /// sum's adaptive state), ready to be gathered as the last good state.
    pub fn step(&mut self, dt: f64) -> Result<StepReport, StepError> {
        self.migrate();
        let mobility = self.stepper.mobility();
        let before = (
            self.rods.clone(),
            self.stepper.warm_start().to_vec(),
            mobility.rod_state(),
            mobility.sum_state(),
        );
        // The contact reach, or the shared sums' if farther; a sliver beyond, so that
        // round-off at the slab bounds cannot drop a copy the cell list would pair.
        let contact = ROD_LENGTH + self.rods.diameter + self.stepper.contact.margin;
        let (total, box_length) = (self.total, self.rods.box_length);
        let sums = self
            .stepper
            .mobility_mut()
            .on_ranks()
            .map_or(0.0, |m| m.shared_reach(total, box_length));
        let reach = contact.max(sums) * (1.0 + 1e-9);
        let (mut local, ids, halo) = self.with_copies(reach);
        self.last_halo = local.len() - halo.owned;
        let part = Part {
            comm: &self.comm,
            halo: &halo,
            ids: &ids,
            total: self.total,
            reach,
        };
        let report = self.stepper.step_part(&mut local, dt, part);
        if report.is_err() {
            let (rods, warm, rod_state, sum_state) = before;
            self.rods = rods;
            self.stepper.set_warm_start(warm);
            let mobility = self.stepper.mobility_mut();
            // No state before the step: none after (the next step solves afresh).
            mobility.set_rod_state(rod_state.unwrap_or_default());
            mobility.set_sum_state(&sum_state);
            return report;
        }
        let owned = halo.owned;
        local.x.truncate(owned);
        local.q.truncate(owned);
        local.image.truncate(owned);
        self.rods = local;
        report
    }

    /// Every rank's warm start (contact multipliers by rod pair), merged and sorted on rank 0;
    /// `None` on the other ranks (collective).
    pub fn gather_warm_start(&self) -> Option<WarmStart> {
        let mine: Vec<f64> = self
            .stepper
            .warm_start()
            .iter()
            .flat_map(|&((a, b), l)| [f64::from(a), f64::from(b), l])
            .collect();
        let mut send = vec![Vec::new(); self.comm.size()];
        send[0] = mine;
        let got = self.comm.exchange(send);
        if self.comm.rank() != 0 {
            return None;
        }
        let mut warm: WarmStart = got
            .iter()
            .flat_map(|m| m.chunks_exact(3))
            .map(|w| ((w[0] as u32, w[1] as u32), w[2]))
            .collect();
        warm.sort_unstable_by_key(|w| w.0);
        Some(warm)
    }

    /// The whole box on rank 0, in the single-process numbering, with `rows[k]` of each own rod
    /// `k` (velocities, say) put in the same order; `None` on the other ranks (collective).
    pub fn gather<const K: usize>(&self, rows: &[[f64; K]]) -> Option<(RodSet, Vec<[f64; K]>)> {
        let (all, flat) = self.gather_rows(rows.as_flattened(), K)?;
        let out = flat
            .chunks_exact(K)
            .map(|c| c.try_into().expect("rows of K"))
            .collect();
        Some((all, out))
    }

    /// [`Self::gather`] for rows of `width` values laid end to end.
    fn gather_rows(&self, rows: &[f64], width: usize) -> Option<(RodSet, Vec<f64>)> {
        assert_eq!(rows.len(), width * self.rods.len(), "one row per own rod");
        let mut mine = Vec::with_capacity(self.rods.len() * (RECORD + width));
        for k in 0..self.rods.len() {
            push_record(&mut mine, &self.rods, k, self.ids[k]);
            mine.extend_from_slice(&rows[k * width..(k + 1) * width]);
        }
        let ranks = self.comm.size();
        let mut send = vec![Vec::new(); ranks];
        send[0] = mine;
        let got = self.comm.exchange(send);
        if self.comm.rank() != 0 {
            return None;
        }
        let n = self.total;
        let mut all = RodSet {
            box_length: self.rods.box_length,
            diameter: self.rods.diameter,
            x: vec![[0.0; 3]; n],
            q: vec![[0.0; 4]; n],
            image: vec![[0; 3]; n],
        };
        let mut out = vec![0.0; n * width];
        for m in &got {
            for r in m.chunks_exact(RECORD + width) {
                let id = r[10] as usize;
                all.x[id] = [r[0], r[1], r[2]];
                all.q[id] = [r[3], r[4], r[5], r[6]];
                all.image[id] = [r[7] as i64, r[8] as i64, r[9] as i64];
                out[id * width..(id + 1) * width].copy_from_slice(&r[RECORD..]);
            }
        }
        Some((all, out))
    }

    /// The mobility's per-rod state ([`crate::hydro::mobility::MobilityState::rod_state`]) of the whole box
    /// on rank 0, in the single-process numbering: empty when some rank has none (before the
    /// first solve) or the mobility keeps none; `None` on the other ranks (collective).
    pub fn gather_rod_state(&self) -> Option<Vec<f64>> {
        let mobility = self.stepper.mobility();
        let width = mobility.rod_state_width();
        if width == 0 {
            return (self.comm.rank() == 0).then(Vec::new);
        }
        let state = mobility
            .rod_state()
            .filter(|s| s.len() == width * self.rods.len());
        let mut missing = [if state.is_some() { 0.0 } else { 1.0 }];
        self.comm.max(&mut missing);
        if missing[0] > 0.0 {
            return (self.comm.rank() == 0).then(Vec::new);
        }
        let rows = state.unwrap_or_default();
        self.gather_rows(&rows, width).map(|(_, rows)| rows)
    }

    /// The own rods' velocities `(v, w)` of the last step, as rows for [`Self::gather`].
    pub fn velocity_rows(&self) -> Vec<[f64; 6]> {
        let vel = self.stepper.velocities();
        if vel.v.len() < self.rods.len() {
            return vec![[0.0; 6]; self.rods.len()];
        }
        (0..self.rods.len())
            .map(|k| {
                let (v, w): (Vec3, Vec3) = (vel.v[k], vel.w[k]);
                [v[0], v[1], v[2], w[0], w[1], w[2]]
            })
            .collect()
    }
}
