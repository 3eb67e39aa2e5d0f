//! The thesis gradient at support centres by φ-weighted least squares (thesis eq. 4.22).
//!
//! The thesis defines `Grad(u)_i` only through the Taylor relation
//! `u_j = u_i + Grad(u)_i · (c_j − c_i)` over the neighbours. Its φ-weighted least-squares
//! solution is
//!
//! ```text
//! Grad(u)_i = G_i⁺ Σ_j φ_ij d_ij (u_j − u_i),   G_i = Σ_j φ_ij d_ij d_ijᵀ,   d_ij = c_j − c_i
//! ```
//!
//! exact for linear `u` whenever the neighbour offsets span ℝ³. When they do not (one
//! neighbour, or all neighbours on a line or plane), `G_i⁺` is the pseudo-inverse and the
//! result is the minimum-norm gradient: the projection of the true gradient onto the span of
//! the offsets, which still reproduces every difference `u_j − u_i` of a linear field. Then
//! `Div(Grad(u)) = Lap(u)` holds for linear `u` in every case (thesis eq. 4.23–4.28).

use glam::{DMat3, DVec3};
use nalgebra::{Matrix3, SymmetricEigen};
use rayon::prelude::*;

use crate::pair_geometry::PairGeometry;

/// Eigenvalues of `G_i` below this fraction of the largest are treated as zero.
const RANK_TOLERANCE: f64 = 1e-12;

/// The pseudo-inverse of the symmetric 3×3 matrix `m`, cutting eigenvalues below
/// `RANK_TOLERANCE ×` the largest (zero for the zero matrix).
pub(crate) fn symmetric_pseudo_inverse(m: DMat3) -> DMat3 {
    let a = Matrix3::from_fn(|r, c| m.col(c)[r]);
    let eigen = SymmetricEigen::new(a);
    let largest = eigen
        .eigenvalues
        .iter()
        .fold(0.0f64, |acc, v| acc.max(v.abs()));
    if largest == 0.0 || !largest.is_finite() {
        return DMat3::ZERO;
    }
    let mut out = DMat3::ZERO;
    for k in 0..3 {
        let lambda = eigen.eigenvalues[k];
        if lambda > RANK_TOLERANCE * largest {
            let v = eigen.eigenvectors.column(k);
            let v = DVec3::new(v[0], v[1], v[2]);
            out += DMat3::from_cols(v * v.x, v * v.y, v * v.z) * (1.0 / lambda);
        }
    }
    out
}

/// The least-squares gradient operator of a [`PairGeometry`]: one 3×3 pseudo-inverse per
/// support.
#[derive(Clone, Debug, PartialEq)]
pub struct LeastSquaresGradient {
    pseudo_inverse: Vec<DMat3>,
    full_rank: Vec<bool>,
}

impl LeastSquaresGradient {
    /// Precomputes `G_i⁺` for every support, in parallel.
    pub fn new(geometry: &PairGeometry) -> LeastSquaresGradient {
        let c = geometry.centers();
        let (pseudo_inverse, full_rank) = (0..geometry.len())
            .into_par_iter()
            .map(|i| {
                let mut g = DMat3::ZERO;
                for (&j, &phi) in geometry.neighbors(i).iter().zip(geometry.phi_row(i)) {
                    if phi > 0.0 {
                        let d = c[j as usize] - c[i];
                        g += DMat3::from_cols(d * d.x, d * d.y, d * d.z) * phi;
                    }
                }
                let p = symmetric_pseudo_inverse(g);
                // Full rank exactly when G⁺G is the identity.
                let full = (p * g - DMat3::IDENTITY)
                    .to_cols_array()
                    .iter()
                    .all(|e| e.abs() < 1e-6);
                (p, full)
            })
            .unzip();
        LeastSquaresGradient {
            pseudo_inverse,
            full_rank,
        }
    }

    /// `G_i⁺` per support.
    pub fn pseudo_inverses(&self) -> &[DMat3] {
        &self.pseudo_inverse
    }

    /// Whether the neighbour offsets of support `i` span ℝ³ (then the gradient is exact on
    /// linear fields).
    pub fn is_full_rank(&self, i: usize) -> bool {
        self.full_rank[i]
    }

    /// `Grad(u)` at every centre.
    pub fn apply(&self, geometry: &PairGeometry, u: &[f64]) -> Vec<DVec3> {
        assert_eq!(u.len(), geometry.len(), "u has the wrong length");
        let c = geometry.centers();
        (0..geometry.len())
            .into_par_iter()
            .map(|i| {
                let mut rhs = DVec3::ZERO;
                for (&j, &phi) in geometry.neighbors(i).iter().zip(geometry.phi_row(i)) {
                    rhs += (phi * (u[j as usize] - u[i])) * (c[j as usize] - c[i]);
                }
                self.pseudo_inverse[i] * rhs
            })
            .collect()
    }
}
