//! The thesis gradient at support centres by φ-weighted least squares (thesis eq. 4.22).
//!
//! The method is described on [`LeastSquaresGradient`].

use glam::DVec3;
use nalgebra::DMatrix;
use rayon::prelude::*;

use crate::pair_geometry::{PairGeometry, ROWS_PER_TASK};
use crate::weighted_fit::WeightedFit;

/// Singular values of the scaled offsets below this fraction of the largest count as zero: the
/// offsets are then treated as not spanning ℝ³ (exactly degenerate configurations give
/// ratios near 1e-16).
const RANK_TOLERANCE: f64 = 1e-12;

/// The least-squares gradient operator of a [`PairGeometry`]: one weight vector per stored
/// neighbour (zero for unusable pairs), aligned with [`PairGeometry::neighbour_array`].
///
/// The thesis defines `Grad(u)_i` only through the Taylor relation
/// `u_j = u_i + Grad(u)_i · (c_j − c_i)` over the neighbours. Its φ-weighted least-squares
/// solution is
///
/// ```text
/// Grad(u)_i = Σ_j w_ij (u_j − u_i),   w_ij = G_i⁺ φ_ij d_ij,   G_i = Σ_j φ_ij d_ij d_ijᵀ,   d_ij = c_j − c_i
/// ```
///
/// exact for linear `u` whenever the neighbour offsets span ℝ³. When they do not (one
/// neighbour, or all neighbours on a line or plane), the result is the minimum-norm gradient:
/// the projection of the true gradient onto the span of the offsets, which still reproduces
/// every difference `u_j − u_i` of a linear field. Then `Div(Grad(u)) = Lap(u)` holds for
/// linear `u` in every case (thesis eq. 4.23–4.28).
///
/// Accuracy. The weights `w_ij` are computed from a singular-value decomposition of the
/// row-weighted, column-scaled offsets (never from `G_i`, whose condition number is the square
/// of theirs), and then refined so that `Σ_j w_ij d_ijᵀ = I` holds to rounding: with
/// `E = I − Σ_j w_ij d_ijᵀ`, `w ← (I + E) w` leaves `I − E²`. The gradient of a linear field
/// then reproduces every neighbour difference to rounding, however badly conditioned the
/// neighbourhood (nearly nested or nearly coplanar neighbours).
#[derive(Clone, Debug, PartialEq)]
pub struct LeastSquaresGradient {
    weights: Vec<DVec3>,
    full_rank: Vec<bool>,
    condition: Vec<f64>,
}

/// The gradient weights of row `i` of `geometry` into `out` (aligned with the row); returns
/// whether the offsets span ℝ³ and the condition number of the scaled offsets.
pub(crate) fn gradient_row(geometry: &PairGeometry, i: usize, out: &mut [DVec3]) -> (bool, f64) {
    let c = geometry.centres();
    let phi = geometry.phi_row(i);
    let nb = geometry.neighbours(i);
    let usable: Vec<usize> = (0..nb.len()).filter(|&k| phi[k] > 0.0).collect();
    out.fill(DVec3::ZERO);
    if usable.is_empty() {
        return (false, 1.0);
    }
    let offset = |k: usize| c[nb[k] as usize] - c[i];
    let rows = DMatrix::from_fn(usable.len(), 3, |r, col| offset(usable[r])[col]);
    let weights: Vec<f64> = usable.iter().map(|&k| phi[k]).collect();
    let fit = WeightedFit::new(&rows, &weights, RANK_TOLERANCE);
    for (r, &k) in usable.iter().enumerate() {
        let w = fit.coefficients.column(r);
        out[k] = DVec3::new(w[0], w[1], w[2]);
    }
    let full = fit.nullity() == 0;
    if full {
        refine_linear_exactness(out, offset, &usable);
    }
    (full, fit.condition)
}

/// `w ← (I + E) w` with `E = I − Σ_k w_k d_kᵀ`: one step of refinement towards
/// `Σ_k w_k d_kᵀ = I`; a left multiplication, so every other moment `Σ_k w_k q(d_k)` that
/// vanished still vanishes.
pub(crate) fn refine_linear_exactness(
    weights: &mut [DVec3],
    offset: impl Fn(usize) -> DVec3,
    usable: &[usize],
) {
    let mut moment = glam::DMat3::ZERO;
    for &k in usable {
        let d = offset(k);
        moment += glam::DMat3::from_cols(weights[k] * d.x, weights[k] * d.y, weights[k] * d.z);
    }
    let correction = glam::DMat3::IDENTITY * 2.0 - moment;
    for &k in usable {
        weights[k] = correction * weights[k];
    }
}

impl LeastSquaresGradient {
    /// Computes the weights of every support, in parallel over fixed row blocks (the result
    /// does not depend on the thread count).
    pub fn new(geometry: &PairGeometry) -> LeastSquaresGradient {
        let n = geometry.len();
        let offsets = geometry.offsets();
        let mut weights = vec![DVec3::ZERO; geometry.stored_entries()];
        let mut tasks = Vec::new();
        {
            let mut rest = &mut weights[..];
            let mut row = 0;
            while row < n {
                let end = (row + ROWS_PER_TASK).min(n);
                let len = (offsets[end] - offsets[row]) as usize;
                let (here, next) = rest.split_at_mut(len);
                tasks.push((row..end, here));
                rest = next;
                row = end;
            }
        }
        let per_row: Vec<Vec<(bool, f64)>> = tasks
            .into_par_iter()
            .map(|(rows, out)| {
                let base = offsets[rows.start] as usize;
                rows.map(|i| {
                    let range = offsets[i] as usize - base..offsets[i + 1] as usize - base;
                    gradient_row(geometry, i, &mut out[range])
                })
                .collect()
            })
            .collect();
        let (full_rank, condition) = per_row.into_iter().flatten().unzip();
        LeastSquaresGradient {
            weights,
            full_rank,
            condition,
        }
    }

    /// The weights `w_ij` of every stored entry: `Grad(u)_i = Σ_j w_ij (u_j − u_i)`.
    pub fn weights(&self) -> &[DVec3] {
        &self.weights
    }

    /// Whether the neighbour offsets of support `i` span ℝ³ (then the gradient is exact on
    /// linear fields).
    pub fn is_full_rank(&self, i: usize) -> bool {
        self.full_rank[i]
    }

    /// Condition number of the row-weighted, column-scaled offsets of support `i` (the square
    /// root of that of `G_i`); 1 without usable neighbours.
    pub fn condition(&self, i: usize) -> f64 {
        self.condition[i]
    }

    /// `Grad(u)` at every centre.
    pub fn apply(&self, geometry: &PairGeometry, u: &[f64]) -> Vec<DVec3> {
        assert_eq!(u.len(), geometry.len(), "u has the wrong length");
        let offsets = geometry.offsets();
        let nb = geometry.neighbour_array();
        (0..geometry.len())
            .into_par_iter()
            .map(|i| {
                let mut acc = DVec3::ZERO;
                for k in offsets[i] as usize..offsets[i + 1] as usize {
                    acc += self.weights[k] * (u[nb[k] as usize] - u[i]);
                }
                acc
            })
            .collect()
    }
}
