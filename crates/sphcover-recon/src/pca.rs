//! Principal component analysis of small point sets: centroid, covariance and its
//! eigen-decomposition, shared by the confidence of samples and the normal estimation.

use sphcover_core::{DMat3, DVec3, SymmetricEigen3};

/// The centroid and the principal axes of a point set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Pca {
    /// Mean of the points.
    pub centroid: DVec3,
    /// Eigenvalues of the covariance, ascending.
    pub eigenvalues: [f64; 3],
    /// Unit eigenvectors, in the order of `eigenvalues`.
    pub axes: [DVec3; 3],
}

impl Pca {
    /// The PCA of `points` (two passes: the centroid, then the centred covariance, which is
    /// far more accurate than the one-pass formula for points far from the origin). `None`
    /// for an empty set or non-finite input.
    pub fn of(points: &[DVec3]) -> Option<Pca> {
        if points.is_empty() {
            return None;
        }
        let centroid = points.iter().fold(DVec3::ZERO, |s, &p| s + p) / points.len() as f64;
        let mut c = [0.0f64; 6];
        for &p in points {
            let d = p - centroid;
            c[0] += d.x * d.x;
            c[1] += d.x * d.y;
            c[2] += d.x * d.z;
            c[3] += d.y * d.y;
            c[4] += d.y * d.z;
            c[5] += d.z * d.z;
        }
        if !(centroid.is_finite() && c.iter().all(|v| v.is_finite())) {
            return None;
        }
        let m = DMat3::from_cols(
            DVec3::new(c[0], c[1], c[2]),
            DVec3::new(c[1], c[3], c[4]),
            DVec3::new(c[2], c[4], c[5]),
        );
        let eig = SymmetricEigen3::of(&m)?;
        Some(Pca {
            centroid,
            eigenvalues: eig.values.map(|l| l.max(0.0)),
            axes: eig.vectors,
        })
    }

    /// The plane normal (the axis of least variance) when the points span a plane or a
    /// volume; `None` when they are (numerically) on a line or a single point, where no plane
    /// is determined.
    pub fn normal(&self) -> Option<DVec3> {
        let [_, l1, l2] = self.eigenvalues;
        if l2 <= 0.0 || l1 <= RANK_TOLERANCE * l2 {
            return None;
        }
        Some(self.axes[0]).filter(|n| n.length_squared() > 0.5)
    }
}

/// Relative eigenvalue below which a direction counts as flat.
pub(crate) const RANK_TOLERANCE: f64 = 1e-10;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Points on a plane through any centre with any orientation: the normal is the
        /// plane's, the smallest eigenvalue is zero, the centroid is the mean.
        #[test]
        fn plane_normal_is_recovered(
            nx in -1.0f64..1.0, ny in -1.0f64..1.0, nz in -1.0f64..1.0,
            ox in -100.0f64..100.0, spread in 0.01f64..10.0,
        ) {
            let n = DVec3::new(nx, ny, nz);
            prop_assume!(n.length() > 0.1);
            let n = n.normalize();
            let (u, v) = n.any_orthonormal_pair();
            let o = DVec3::new(ox, -ox / 2.0, 3.0);
            let pts: Vec<DVec3> = (0..20)
                .map(|i| o + spread * ((i % 5) as f64 * u + (i / 5) as f64 * v * 0.7))
                .collect();
            let pca = Pca::of(&pts).unwrap();
            let normal = pca.normal().unwrap();
            prop_assert!(normal.dot(n).abs() > 1.0 - 1e-9);
            prop_assert!(pca.eigenvalues[0] <= 1e-9 * pca.eigenvalues[2]);
            let mean = pts.iter().sum::<DVec3>() / 20.0;
            prop_assert!((pca.centroid - mean).length() < 1e-9 * (1.0 + mean.length()));
        }
    }

    #[test]
    fn degenerate_sets_have_no_normal() {
        assert!(Pca::of(&[]).is_none());
        let one = Pca::of(&[DVec3::ONE]).unwrap();
        assert!(one.normal().is_none());
        let line: Vec<DVec3> = (0..10).map(|i| DVec3::X * i as f64).collect();
        assert!(Pca::of(&line).unwrap().normal().is_none());
        assert!(Pca::of(&[DVec3::NAN, DVec3::ONE]).is_none());
    }
}
