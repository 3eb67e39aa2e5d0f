//! The smallest eigenpair of a symmetric 3×3 matrix (the Hessian's ridge direction).

use glam::{DMat3, DVec3};
use sphcover_core::SymmetricEigen3;

/// Eigenvalues of a symmetric 3×3 matrix in ascending order, with the unit eigenvector of
/// the smallest one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmallestEigen {
    /// Eigenvalues `λ1 ≤ λ2 ≤ λ3`.
    pub values: [f64; 3],
    /// Unit eigenvector of `λ1`.
    pub vector: DVec3,
}

/// The smallest eigenpair of the symmetric matrix `m` (only its lower triangle is read),
/// from the core's decomposition. `None` when `m` is not finite or the solver's vector
/// vanished.
pub(crate) fn smallest_eigen(m: &DMat3) -> Option<SmallestEigen> {
    let eig = SymmetricEigen3::of(m)?;
    let vector = eig.vectors[0];
    (vector != DVec3::ZERO).then_some(SmallestEigen {
        values: eig.values,
        vector,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// `H e = λ1 e`, eigenvalues ascending, trace preserved.
        #[test]
        fn eigenpair_identity(a in -5.0..5.0f64, b in -5.0..5.0f64, c in -5.0..5.0f64,
                              d in -5.0..5.0f64, e in -5.0..5.0f64, f in -5.0..5.0f64) {
            let m = DMat3::from_cols(DVec3::new(a, d, e), DVec3::new(d, b, f), DVec3::new(e, f, c));
            let eig = smallest_eigen(&m).unwrap();
            let scale = 1.0 + m.to_cols_array().iter().fold(0.0f64, |s, x| s.max(x.abs()));
            prop_assert!((m * eig.vector - eig.values[0] * eig.vector).length() < 1e-9 * scale);
            prop_assert!(eig.values[0] <= eig.values[1] && eig.values[1] <= eig.values[2]);
            let trace: f64 = eig.values.iter().sum();
            prop_assert!((trace - (a + b + c)).abs() < 1e-9 * scale);
        }
    }

    #[test]
    fn non_finite_is_none() {
        assert!(smallest_eigen(&DMat3::from_diagonal(DVec3::new(f64::NAN, 1.0, 1.0))).is_none());
    }
}
