//! Eigen-decomposition of symmetric 3×3 matrices: covariances of point sets (normals,
//! confidence of supports) and Hessians (ridge directions) both need it.

use glam::{DMat3, DVec3};

/// The eigenvalues of a symmetric 3×3 matrix in ascending order, with unit eigenvectors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SymmetricEigen3 {
    /// Eigenvalues `λ1 ≤ λ2 ≤ λ3`.
    pub values: [f64; 3],
    /// Unit eigenvectors in the order of `values` (zero where the solver's vector vanished).
    pub vectors: [DVec3; 3],
}

impl SymmetricEigen3 {
    /// Decomposes the symmetric matrix `m` (only its lower triangle is read) by nalgebra's
    /// symmetric QR iteration; `None` when `m` is not finite.
    ///
    /// ```
    /// use sphcover_core::{DMat3, DVec3, SymmetricEigen3};
    ///
    /// let m = DMat3::from_diagonal(DVec3::new(3.0, -1.0, 2.0));
    /// let eig = SymmetricEigen3::of(&m).unwrap();
    /// assert_eq!(eig.values, [-1.0, 2.0, 3.0]);
    /// assert_eq!(eig.vectors[0].abs(), DVec3::Y);
    /// ```
    pub fn of(m: &DMat3) -> Option<SymmetricEigen3> {
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
        let vector = |i: usize| {
            let col = eig.eigenvectors.column(i);
            DVec3::new(col[0], col[1], col[2]).normalize_or_zero()
        };
        Some(SymmetricEigen3 {
            values: order.map(|i| eig.eigenvalues[i]),
            vectors: order.map(vector),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// `M v_i = λ_i v_i` for every pair, eigenvalues ascending, trace preserved,
        /// eigenvectors orthonormal.
        #[test]
        fn eigenpairs_of_symmetric_matrices(a in -5.0..5.0f64, b in -5.0..5.0f64, c in -5.0..5.0f64,
                                            d in -5.0..5.0f64, e in -5.0..5.0f64, f in -5.0..5.0f64) {
            let m = DMat3::from_cols(DVec3::new(a, d, e), DVec3::new(d, b, f), DVec3::new(e, f, c));
            let eig = SymmetricEigen3::of(&m).unwrap();
            let scale = 1.0 + m.to_cols_array().iter().fold(0.0f64, |s, x| s.max(x.abs()));
            for (l, v) in eig.values.iter().zip(&eig.vectors) {
                prop_assert!((m * *v - *l * *v).length() < 1e-9 * scale);
                prop_assert!((v.length() - 1.0).abs() < 1e-12);
            }
            prop_assert!(eig.values[0] <= eig.values[1] && eig.values[1] <= eig.values[2]);
            prop_assert!(eig.vectors[0].dot(eig.vectors[1]).abs() < 1e-9);
            let trace: f64 = eig.values.iter().sum();
            prop_assert!((trace - (a + b + c)).abs() < 1e-9 * scale);
        }
    }

    #[test]
    fn non_finite_is_none() {
        assert!(
            SymmetricEigen3::of(&DMat3::from_diagonal(DVec3::new(f64::NAN, 1.0, 1.0))).is_none()
        );
    }
}
