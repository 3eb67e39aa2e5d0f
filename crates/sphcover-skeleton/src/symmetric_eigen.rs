//! The smallest eigenpair of a symmetric 3×3 matrix (the Hessian's ridge direction).

use glam::{DMat3, DVec3};

/// Eigenvalues of a symmetric 3×3 matrix in ascending order, with the unit eigenvector of
/// the smallest one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmallestEigen {
    /// Eigenvalues `λ1 ≤ λ2 ≤ λ3`.
    pub values: [f64; 3],
    /// Unit eigenvector of `λ1`.
    pub vector: DVec3,
}

/// Decomposes the symmetric matrix `m` (only its lower triangle is read) with nalgebra's
/// symmetric QR iteration. Returns `None` when `m` is not finite.
pub fn smallest_eigen(m: &DMat3) -> Option<SmallestEigen> {
    if !m.is_finite() {
        return None;
    }
    let a = nalgebra::Matrix3::new(
        m.x_axis.x, m.y_axis.x, m.z_axis.x, //
        m.x_axis.y, m.y_axis.y, m.z_axis.y, //
        m.x_axis.z, m.y_axis.z, m.z_axis.z,
    );
    let eig = a.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let col = eig.eigenvectors.column(order[0]);
    let vector = DVec3::new(col[0], col[1], col[2]).normalize_or_zero();
    if vector == DVec3::ZERO {
        return None;
    }
    Some(SmallestEigen {
        values: order.map(|i| eig.eigenvalues[i]),
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
