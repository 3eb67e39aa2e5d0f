//! Spatial index over balls: "which balls contain x" and "which balls come near a ball".
//!
//! INTERIM: a brute-force scan. To be replaced by the fast multi-level structure, keeping
//! this exact API; the brute force then moves to the tests as the oracle.

use glam::DVec3;

/// An index over a fixed set of balls `(c_j, r_j)`.
#[derive(Clone, Debug)]
pub struct BallIndex {
    centers: Vec<DVec3>,
    radii: Vec<f64>,
}

impl BallIndex {
    /// Builds the index. `centers` and `radii` have the same length; radii are finite and
    /// non-negative.
    pub fn new(centers: &[DVec3], radii: &[f64]) -> BallIndex {
        assert_eq!(centers.len(), radii.len());
        BallIndex {
            centers: centers.to_vec(),
            radii: radii.to_vec(),
        }
    }

    /// Number of balls.
    pub fn len(&self) -> usize {
        self.centers.len()
    }

    /// True when the index holds no ball.
    pub fn is_empty(&self) -> bool {
        self.centers.is_empty()
    }

    /// Calls `visit(j)` for every ball `j` with `‖x − c_j‖ < scale·r_j + extra`, in no
    /// particular order. `scale > 0`, `extra ≥ 0`.
    pub fn for_each_within(&self, x: DVec3, scale: f64, extra: f64, mut visit: impl FnMut(u32)) {
        for (j, (c, r)) in self.centers.iter().zip(&self.radii).enumerate() {
            if c.distance(x) < scale * r + extra {
                visit(j as u32);
            }
        }
    }

    /// The balls whose open interior contains `x` (`‖x − c_j‖ < r_j`), ascending, into `out`
    /// (cleared first).
    pub fn containing(&self, x: DVec3, out: &mut Vec<u32>) {
        out.clear();
        self.for_each_within(x, 1.0, 0.0, |j| out.push(j));
        out.sort_unstable();
    }
}
