//! The local linear fit of a support to oriented points (thesis eq. 3.2) and its error.
//!
//! With kernel weights `w_j = ψ(‖p_j − c‖ / r)` (times the point's confidence, when given):
//!
//! ```text
//! n̄ = Σ w_j n_j / ‖Σ w_j n_j‖,   p̄ = Σ w_j p_j / Σ w_j,   g(x) = n̄·(p̄ − x)
//! ```
//!
//! so `α = −n̄` and `β = n̄·(p̄ − c)` in the centred form, positive inside for outward
//! normals. The error is `E = max_j |g(p_j)|` over the points in the open ball (points of
//! zero confidence excluded). Both are single passes over the candidate points, which sum
//! offsets from the centre so the sums stay well conditioned for small balls far from the
//! origin. The candidates are slots of the point index: a ball's points lie in a few runs of
//! consecutive slots, so the passes still read memory nearly sequentially.

use crate::kernel::Kernel;
use crate::local_function::LinearFunction;
use crate::point_index::PointIndex;
use glam::DVec3;
use std::borrow::Cow;

/// The oriented points of the build, in the slot order of the point index.
#[derive(Debug)]
pub(crate) struct Samples<'i> {
    /// The point index (holds the positions in slot order): the caller's when it indexes
    /// exactly the points used, else the build's own.
    pub index: Cow<'i, PointIndex>,
    /// Unit normals in slot order.
    pub normals: Vec<DVec3>,
    /// Confidences in slot order, when given.
    pub confidence: Option<Vec<f64>>,
}

/// The result of a fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Fit {
    /// Unit mean normal `n̄`.
    pub normal: DVec3,
    /// Weighted centroid offset `p̄ − c`.
    pub centroid: DVec3,
    /// `E = max |g(p_j)|`, or a value above the early-exit limit when it was exceeded.
    pub error: f64,
}

impl Fit {
    /// The local function in centred form.
    pub fn linear(&self) -> LinearFunction {
        LinearFunction {
            alpha: -self.normal,
            beta: self.normal.dot(self.centroid),
        }
    }
}

/// Candidate points of one support: the slots of the points in the ball of the last gather
/// (in tree order) and their squared distances from its centre. The fits read positions,
/// normals and confidences through the slots: copying them here wrote 56 bytes per point
/// and gather, against 12, and a support gathers once per doubling of its radius but fits
/// only a few times more.
#[derive(Debug, Default)]
pub(crate) struct Candidates {
    center: DVec3,
    slots: Vec<u32>,
    dist2: Vec<f64>,
}

impl Candidates {
    /// Number of candidates.
    pub fn len(&self) -> usize {
        self.dist2.len()
    }

    /// Gathers the points with `‖p − c‖² < r²`, in tree order.
    pub fn gather(&mut self, samples: &Samples<'_>, c: DVec3, r: f64) {
        self.center = c;
        self.slots.clear();
        self.dist2.clear();
        samples.index.for_each_slot_within(c, r, |s, d2| {
            self.slots.push(s as u32);
            self.dist2.push(d2);
        });
    }

    /// Drops the candidates with `distance² ≥ r²`, keeping the others in order. Exact for
    /// every later fit whose radius `ρ` has `ρ² ≤ r² / (1 + 1e-6)`: the dropped candidates
    /// would get kernel weight exactly 0 there (`s = d²/ρ² > 1`, with a margin far above
    /// rounding) and be skipped by the error pass, so the sums and the error do not change
    /// by a bit.
    pub fn keep_within(&mut self, r: f64) {
        let r2 = r * r;
        let mut kept = 0;
        for j in 0..self.len() {
            if self.dist2[j] < r2 {
                self.slots[kept] = self.slots[j];
                self.dist2[kept] = self.dist2[j];
                kept += 1;
            }
        }
        self.slots.truncate(kept);
        self.dist2.truncate(kept);
    }

    /// Fits the candidates inside the ball of radius `r` (at most the gather radius) with
    /// kernel radius `r`, reading them from `samples` (those of the gather). Candidates
    /// outside get weight 0 from the kernel and are skipped by the error pass, so one gather
    /// at the largest radius serves every smaller trial. The error pass stops as soon as `E`
    /// exceeds `limit` (pass `f64::INFINITY` for the exact error). `None` when no candidate
    /// lies inside.
    pub fn fit(&self, samples: &Samples<'_>, r: f64, kernel: Kernel, limit: f64) -> Option<Fit> {
        let len = self.len();
        let r2 = r * r;
        let inv_r2 = 1.0 / r2;
        let c = self.center;
        let points = samples.index.slot_points();
        let normals = &samples.normals[..];
        let slots = &self.slots[..len];
        let dist2 = &self.dist2[..len];
        let mut sum_w = 0.0;
        let mut sum_p = DVec3::ZERO;
        let mut sum_n = DVec3::ZERO;
        match &samples.confidence {
            None => {
                for j in 0..len {
                    let s = slots[j] as usize;
                    let w = kernel.value_sq(dist2[j] * inv_r2);
                    sum_w += w;
                    sum_p += w * (points[s] - c);
                    sum_n += w * normals[s];
                }
            }
            Some(conf) => {
                for j in 0..len {
                    let s = slots[j] as usize;
                    let w = kernel.value_sq(dist2[j] * inv_r2) * conf[s];
                    sum_w += w;
                    sum_p += w * (points[s] - c);
                    sum_n += w * normals[s];
                }
            }
        }
        let length = sum_n.length();
        let (normal, centroid) = if sum_w > 0.0 && length > 0.0 && length.is_finite() {
            (sum_n / length, sum_p / sum_w)
        } else {
            // The weighted normals cancel (two sheets facing each other with equal weight)
            // or no point carries weight: take the nearest point's plane. Its error decides
            // whether the support is refined.
            let j = (0..len)
                .filter(|&j| dist2[j] < r2)
                .min_by(|&a, &b| dist2[a].total_cmp(&dist2[b]).then(a.cmp(&b)))?;
            let s = slots[j] as usize;
            (normals[s], points[s] - c)
        };
        let level = normal.dot(centroid);
        let mut error: f64 = 0.0;
        let conf = samples.confidence.as_deref();
        for j in 0..len {
            let s = slots[j] as usize;
            if dist2[j] >= r2 || conf.is_some_and(|conf| conf[s] <= 0.0) {
                continue;
            }
            let e = (level - normal.dot(points[s] - c)).abs();
            if e > error {
                error = e;
                if error > limit {
                    break;
                }
            }
        }
        Some(Fit {
            normal,
            centroid,
            error,
        })
    }
}
