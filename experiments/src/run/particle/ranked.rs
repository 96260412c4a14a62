//! A particle run shared among ranks (docs/MODEL.md §3a; the protocol of [`crate::run::ranks`]):
//! rank 0's side ([`Ranked`]: the start message with the resolved config and the starting
//! state, then an order before each collective step or gather) and the followers' side
//! ([`Follower`], driven by [`follow`] until rank 0 says stop).

use crate::run::particle::config::{ParticleRunConfig, shared_mobility};
use crate::run::ranks::{self, Order, broadcast};
use anyhow::{Context, bail};
use motile_particle::model::rods::RodSet;
use motile_particle::parallel::comm::Comm;
use motile_particle::step::contact::WarmStart;
use motile_particle::step::distributed::Distributed;
use motile_particle::step::report::{StepError, StepReport};
use motile_particle::step::stepper::Stepper;

/// Rank 0's side of a particle run shared among ranks ([`run::ranks`]).
pub(crate) struct Ranked {
    pub(crate) dist: Distributed<&'static dyn Comm>,
}

/// Rows a gather brings per rod: velocity, angular velocity, contact force.
pub(crate) const ROW: usize = 9;

impl Ranked {
    /// Send the followers the resolved config and the starting state, and take rank 0's share.
    pub(crate) fn start(
        comm: &'static dyn Comm,
        cfg: &ParticleRunConfig,
        rods: &RodSet,
        stepper: &Stepper,
    ) -> anyhow::Result<Self> {
        let mut own = Stepper::new(shared_mobility(cfg)?, cfg.contact.clone());
        own.set_warm_start(stepper.warm_start().to_vec());
        let sum_state = stepper.mobility().sum_state();
        own.mobility_mut().set_sum_state(&sum_state);
        let hydro = stepper.mobility().warm_state();
        own.mobility_mut().set_warm_state(hydro.clone());
        let mut m = vec![ranks::Order::Start as u8 as f64];
        ranks::encode_text(&toml::to_string(cfg)?, &mut m);
        encode_state(rods, (&sum_state, &hydro), stepper.warm_start(), &mut m);
        ranks::broadcast(comm, Some(m));
        Ok(Self {
            dist: Distributed::new(comm, own, rods),
        })
    }

    pub(crate) fn step(&mut self, dt: f64) -> Result<StepReport, StepError> {
        let comm = *self.dist.comm();
        ranks::broadcast(comm, Some(vec![ranks::Order::Step as u8 as f64, dt]));
        self.dist.step(dt)
    }

    /// The whole state on rank 0 (collective).
    pub(crate) fn gather(&self) -> Gathered {
        let comm = *self.dist.comm();
        ranks::broadcast(comm, Some(vec![ranks::Order::Gather as u8 as f64]));
        gather_share(&self.dist).expect("rank 0 gathers")
    }
}

/// Each own rod's velocity, angular velocity and contact force.
fn rows(dist: &Distributed<&'static dyn Comm>) -> Vec<[f64; ROW]> {
    let f = dist.stepper().contact_forces();
    dist.velocity_rows()
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let c = f.get(k).copied().unwrap_or([0.0; 3]);
            [v[0], v[1], v[2], v[3], v[4], v[5], c[0], c[1], c[2]]
        })
        .collect()
}

/// A state gathered on rank 0: rods, per-rod rows, contact warm start, the mobility's per-rod
/// state.
pub(crate) type Gathered = (RodSet, Vec<[f64; ROW]>, WarmStart, Vec<f64>);

/// The gather every rank takes part in; rank 0 gets the state.
fn gather_share(dist: &Distributed<&'static dyn Comm>) -> Option<Gathered> {
    let state = dist.gather(&rows(dist));
    let warm = dist.gather_warm_start();
    let rod_state = dist.gather_rod_state();
    match (state, warm, rod_state) {
        (Some((r, v)), Some(w), Some(s)) => Some((r, v, w, s)),
        _ => None,
    }
}

/// Rods, the sum's adaptive state, the mobility's warm state and the contact warm start as
/// numbers: box, diameter, count, then per rod centre, quaternion, images; the sum state's
/// length and values; the mobility state's length and values; then the warm start's
/// (a, b, lambda).
fn encode_state(
    rods: &RodSet,
    (sum_state, hydro): (&[u32], &[f64]),
    warm: &[((u32, u32), f64)],
    m: &mut Vec<f64>,
) {
    m.extend([rods.box_length, rods.diameter, rods.len() as f64]);
    for k in 0..rods.len() {
        m.extend_from_slice(&rods.x[k]);
        m.extend_from_slice(&rods.q[k]);
        m.extend(rods.image[k].iter().map(|&i| i as f64));
    }
    m.push(sum_state.len() as f64);
    m.extend(sum_state.iter().map(|&s| f64::from(s)));
    m.push(hydro.len() as f64);
    m.extend_from_slice(hydro);
    m.extend(
        warm.iter()
            .flat_map(|&((a, b), l)| [f64::from(a), f64::from(b), l]),
    );
}

/// What [`encode_state`] wrote: rods, sum state, mobility state, warm start.
type StartState = (RodSet, Vec<u32>, Vec<f64>, WarmStart);

fn decode_state(m: &[f64]) -> anyhow::Result<StartState> {
    let head = m.get(..3).context("state message too short")?;
    let n = head[2] as usize;
    let body = m.get(3..3 + 10 * n).context("state message too short")?;
    let mut rods = RodSet {
        box_length: head[0],
        diameter: head[1],
        x: Vec::with_capacity(n),
        q: Vec::with_capacity(n),
        image: Vec::with_capacity(n),
    };
    for r in body.chunks_exact(10) {
        rods.x.push([r[0], r[1], r[2]]);
        rods.q.push([r[3], r[4], r[5], r[6]]);
        rods.image.push([r[7] as i64, r[8] as i64, r[9] as i64]);
    }
    let rest = &m[3 + 10 * n..];
    let k = *rest.first().context("state message too short")? as usize;
    let sum_state = rest
        .get(1..1 + k)
        .context("state message too short")?
        .iter()
        .map(|&s| s as u32)
        .collect();
    let rest = &rest[1 + k..];
    let h = *rest.first().context("state message too short")? as usize;
    let hydro = rest
        .get(1..1 + h)
        .context("state message too short")?
        .to_vec();
    let warm = rest[1 + h..]
        .chunks_exact(3)
        .map(|w| ((w[0] as u32, w[1] as u32), w[2]))
        .collect();
    Ok((rods, sum_state, hydro, warm))
}

/// A follower rank's share of a particle run ([`follow`]).
#[derive(Debug)]
pub(crate) struct Follower {
    dist: Distributed<&'static dyn Comm>,
}

impl Follower {
    /// Set up from the leader's start message (after its order).
    pub(crate) fn start(comm: &'static dyn Comm, m: &[f64]) -> anyhow::Result<Self> {
        let (text, rest) = ranks::decode_text(m)?;
        let cfg: ParticleRunConfig = toml::from_str(&text)?;
        let (rods, sum_state, hydro, warm) = decode_state(rest)?;
        let mut stepper = Stepper::new(shared_mobility(&cfg)?, cfg.contact.clone());
        stepper.set_warm_start(warm);
        stepper.mobility_mut().set_sum_state(&sum_state);
        stepper.mobility_mut().set_warm_state(hydro);
        Ok(Self {
            dist: Distributed::new(comm, stepper, &rods),
        })
    }

    /// A step (its errors are every rank's: the leader reports them).
    pub(crate) fn step(&mut self, dt: f64) {
        let _ = self.dist.step(dt);
    }

    /// This rank's part of a gather.
    pub(crate) fn gather(&self) {
        let _ = gather_share(&self.dist);
    }
}

/// A follower's life: wait for the leader's orders until it says stop.
pub fn follow(comm: &'static dyn Comm) -> anyhow::Result<()> {
    let mut model = None;
    loop {
        let m = broadcast(comm, None);
        let order = *m.first().context("empty order from rank 0")? as u8;
        match order {
            o if o == Order::Stop as u8 => return Ok(()),
            o if o == Order::Start as u8 => {
                model = Some(Follower::start(comm, &m[1..])?);
            }
            o if o == Order::Step as u8 || o == Order::Gather as u8 => {
                let Some(f) = model.as_mut() else {
                    bail!("rank {}: order {order} before the start", comm.rank());
                };
                if o == Order::Step as u8 {
                    f.step(m[1]);
                } else {
                    f.gather();
                }
            }
            _ => bail!("rank {}: unknown order {order} from rank 0", comm.rank()),
        }
    }
}
