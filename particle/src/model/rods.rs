//! The rods' state (docs/MODEL.md §1): centres wrapped into the periodic box, unit quaternions, and
//! the periodic images each rod has crossed, so unwrapped trajectories are exact.

use crate::model::geometry::{Quat, Vec3, quat_axis};
use serde::{Deserialize, Serialize};

/// N rigid rods of one shape (length `l = 1`, diameter `b`) in a periodic cube.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RodSet {
    /// Box side L (rod lengths).
    pub box_length: f64,
    /// Rod diameter `b` (rod lengths): contacts keep centerlines `b` apart; the mobilities take
    /// their `eta` from the same `b` (check with [`crate::model::units::check_diameter`]).
    #[serde(default = "default_diameter")]
    pub diameter: f64,
    /// Centres in `[0, L)^3`.
    pub x: Vec<Vec3>,
    /// Unit quaternions; the orientation is `p = q z q*`.
    pub q: Vec<Quat>,
    /// Periodic images crossed since the start: unwrapped centre = `x + L * image`.
    pub image: Vec<[i64; 3]>,
}

/// Move the centre `x` by `dx` in a periodic box of side `l`, wrapping into `[0, l)` and
/// counting the images crossed in `image`.
pub(crate) fn translate_wrapped(x: &mut Vec3, image: &mut [i64; 3], dx: Vec3, l: f64) {
    for d in 0..3 {
        let mut c = x[d] + dx[d];
        // Steps are far shorter than the box, so one wrap suffices; loop for safety.
        while c >= l {
            c -= l;
            image[d] += 1;
        }
        while c < 0.0 {
            c += l;
            image[d] -= 1;
        }
        // -tiny + L can round to L.
        if c >= l {
            c = 0.0;
            image[d] += 1;
        }
        x[d] = c;
    }
}

fn default_diameter() -> f64 {
    crate::model::units::DEFAULT_DIAMETER
}

impl RodSet {
    /// Number of rods.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// True when there are no rods.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Orientation of rod `i`.
    pub fn p(&self, i: usize) -> Vec3 {
        quat_axis(self.q[i])
    }

    /// All orientations (computed in parallel; each is its own, so any thread count gives the
    /// same values).
    pub fn orientations(&self) -> Vec<Vec3> {
        use rayon::prelude::*;
        self.q.par_iter().map(|q| quat_axis(*q)).collect()
    }

    /// Move rod `i` by `dx`, wrapping into the box and counting images.
    pub fn translate(&mut self, i: usize, dx: Vec3) {
        translate_wrapped(&mut self.x[i], &mut self.image[i], dx, self.box_length);
    }

    /// Unwrapped centres.
    pub fn unwrapped(&self) -> Vec<Vec3> {
        let l = self.box_length;
        self.x
            .iter()
            .zip(&self.image)
            .map(|(x, i)| [0, 1, 2].map(|d| x[d] + l * i[d] as f64))
            .collect()
    }
}
