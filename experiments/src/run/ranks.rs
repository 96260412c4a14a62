//! Particle runs on several processes (`mpirun -n P motile particle run CONFIG --out DIR`).
//!
//! Rank 0 is the leader: it runs the command as a single process would (the run loop, the run
//! directory, every file), with the particle model's step shared among all ranks
//! ([`motile_particle::step::distributed::Distributed`]). The other ranks are followers: they ignore
//! their command line, take the resolved config and the starting state from the leader, and
//! then do what it says, one collective operation at a time (an order each): step, gather the state
//! to rank 0 (for snapshots, checkpoints and the last good state), stop. The leader always says
//! stop when its command ends, successfully or not.
//!
//! MPI comes in with the cargo feature `mpi` (rsmpi over the system's MPI); without it a
//! launch under `mpirun` with more than one rank is refused rather than run P times into one
//! directory. With one rank, or without `mpirun`, nothing here is used.

use anyhow::Context;
use motile_particle::parallel::comm::Comm;
use std::sync::OnceLock;

/// What the leader tells the followers to do next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Order {
    /// Stop: the command is over.
    Stop = 0,
    /// Set up from the message's config and state.
    Start = 1,
    /// One step of the message's `dt`.
    Step = 2,
    /// Gather the state to rank 0.
    Gather = 3,
}

static WORLD: OnceLock<&'static dyn Comm> = OnceLock::new();

/// The ranks of this run when there are several; `None` for a single process.
pub fn world() -> Option<&'static dyn Comm> {
    WORLD.get().copied()
}

/// Use `comm` as this process's ranks (once; the first call wins).
pub fn set_world(comm: &'static dyn Comm) {
    let _ = WORLD.set(comm);
}

/// Rank 0 sends `message` (an [`Order`] first) to every rank; every rank returns it.
pub(crate) fn broadcast(comm: &dyn Comm, message: Option<Vec<f64>>) -> Vec<f64> {
    let size = comm.size();
    let send = match message {
        Some(m) if comm.rank() == 0 => vec![m; size],
        _ => vec![Vec::new(); size],
    };
    comm.exchange(send).swap_remove(0)
}

/// Text as one value per byte (the messages carry numbers).
pub(crate) fn encode_text(s: &str, out: &mut Vec<f64>) {
    out.push(s.len() as f64);
    out.extend(s.bytes().map(f64::from));
}

/// Text written by [`encode_text`] at the start of `m`; returns it and the rest.
pub(crate) fn decode_text(m: &[f64]) -> anyhow::Result<(String, &[f64])> {
    let len = *m.first().context("empty message")? as usize;
    let bytes: Vec<u8> = m
        .get(1..1 + len)
        .context("message shorter than its text")?
        .iter()
        .map(|&b| b as u8)
        .collect();
    Ok((String::from_utf8(bytes)?, &m[1 + len..]))
}

/// Tell the followers to stop (the leader, when its command ends; nothing for one process).
pub fn release() {
    if let Some(comm) = world()
        && comm.rank() == 0
    {
        broadcast(comm, Some(vec![Order::Stop as u8 as f64]));
    }
}

/// Messages this process has exchanged with the others: `(exchanges, values sent to other
/// ranks)`, counted by `MpiRanks` (feature `mpi`; zero otherwise).
pub fn traffic() -> (u64, u64) {
    #[cfg(feature = "mpi")]
    {
        (
            TRAFFIC[0].load(std::sync::atomic::Ordering::Relaxed),
            TRAFFIC[1].load(std::sync::atomic::Ordering::Relaxed),
        )
    }
    #[cfg(not(feature = "mpi"))]
    {
        (0, 0)
    }
}

#[cfg(feature = "mpi")]
static TRAFFIC: [std::sync::atomic::AtomicU64; 2] = [
    std::sync::atomic::AtomicU64::new(0),
    std::sync::atomic::AtomicU64::new(0),
];

/// Ranks under `mpirun` as the environment tells them (OpenMPI, MPICH, Slurm), if more than one.
pub fn launched_ranks() -> Option<usize> {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"]
        .iter()
        .filter_map(|k| std::env::var(k).ok()?.parse::<usize>().ok())
        .find(|&n| n > 1)
}

/// The ranks of MPI's world communicator (feature `mpi`): messages are MPI all-to-all
/// exchanges, made from the thread that calls (MPI's funneled mode).
#[cfg(feature = "mpi")]
#[derive(Clone, Copy, Debug)]
pub struct MpiRanks {
    rank: usize,
    size: usize,
}

#[cfg(feature = "mpi")]
impl MpiRanks {
    /// The world's ranks (MPI must be initialised and stay so while this is used).
    pub fn world() -> Self {
        use mpi::traits::Communicator;
        let w = mpi::topology::SimpleCommunicator::world();
        Self {
            rank: w.rank() as usize,
            size: w.size() as usize,
        }
    }
}

#[cfg(feature = "mpi")]
impl Comm for MpiRanks {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn exchange(&self, send: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        use mpi::datatype::{Partition, PartitionMut};
        use mpi::traits::CommunicatorCollectives;
        assert_eq!(send.len(), self.size, "one message per rank");
        let w = mpi::topology::SimpleCommunicator::world();
        let count = |len: usize| -> i32 {
            i32::try_from(len).expect("a message of more than 2^31 values to one rank")
        };
        let send_counts: Vec<i32> = send.iter().map(|m| count(m.len())).collect();
        let mut recv_counts = vec![0i32; self.size];
        w.all_to_all_into(&send_counts[..], &mut recv_counts[..]);
        let displs = |c: &[i32]| -> Vec<i32> {
            c.iter()
                .scan(0i32, |acc, &x| {
                    let d = *acc;
                    *acc += x;
                    Some(d)
                })
                .collect()
        };
        let (sd, rd) = (displs(&send_counts), displs(&recv_counts));
        let flat: Vec<f64> = send.concat();
        let to_others = flat.len() - send[self.rank].len();
        TRAFFIC[0].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        TRAFFIC[1].fetch_add(to_others as u64, std::sync::atomic::Ordering::Relaxed);
        let total: usize = recv_counts.iter().map(|&c| c as usize).sum();
        let mut recv = vec![0.0f64; total];
        {
            let sp = Partition::new(&flat[..], &send_counts[..], &sd[..]);
            let mut rp = PartitionMut::new(&mut recv[..], &recv_counts[..], &rd[..]);
            w.all_to_all_varcount_into(&sp, &mut rp);
        }
        (0..self.size)
            .map(|r| recv[rd[r] as usize..(rd[r] + recv_counts[r]) as usize].to_vec())
            .collect()
    }
}
