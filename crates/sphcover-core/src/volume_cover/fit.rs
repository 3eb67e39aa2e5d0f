//! Least-squares fits of a local function to the samples inside a ball (thesis §3.4.2,
//! eq. 3.11–3.12), for every radius of a growing family of balls at once.
//!
//! Samples come in shells of equal distance from the centre. The normal equations are
//! accumulated in the fixed frame `d/h` (`h` a per-build length) shell by shell, and
//! rescaled to the frame `u = d/r` of the trial radius before solving: a monomial of degree
//! `p` scales by `(h/r)^p`, so the scaled system is exactly the one of the centred, scaled
//! coordinates `(x − c)/r` without touching the samples again.

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

/// Number of coefficients of the quadratic (`1, u, v, w, u², v², w², uv, vw, uw`).
pub(crate) const QUADRATIC: usize = 10;
/// Number of coefficients of the linear function (`1, u, v, w`).
pub(crate) const LINEAR: usize = 4;

/// Degree of each basis monomial, in basis order.
const DEGREE: [i32; QUADRATIC] = [0, 1, 1, 1, 2, 2, 2, 2, 2, 2];

/// The basis monomials at `p` (the first `N` of them).
#[inline]
pub(crate) fn basis<const N: usize>(p: [f64; 3]) -> [f64; N] {
    let [x, y, z] = p;
    let all = [1.0, x, y, z, x * x, y * y, z * z, x * y, y * z, x * z];
    let mut out = [0.0; N];
    out.copy_from_slice(&all[..N]);
    out
}

/// Running sums of the normal equations: `Σ φφᵀ`, `Σ φ v`, `Σ v²` and the sample count.
/// Only the upper triangle of `m` is kept up to date.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NormalEquations<const N: usize> {
    m: [[f64; N]; N],
    b: [f64; N],
    vv: f64,
    count: usize,
}

impl<const N: usize> NormalEquations<N> {
    pub(crate) fn new() -> Self {
        NormalEquations {
            m: [[0.0; N]; N],
            b: [0.0; N],
            vv: 0.0,
            count: 0,
        }
    }

    pub(crate) fn count(&self) -> usize {
        self.count
    }

    /// Adds a sample at `p` (frame `d/h`) with value `v`.
    #[inline]
    pub(crate) fn add(&mut self, p: [f64; 3], v: f64) {
        let phi = basis::<N>(p);
        for a in 0..N {
            let pa = phi[a];
            for bb in a..N {
                self.m[a][bb] += pa * phi[bb];
            }
            self.b[a] += pa * v;
        }
        self.vv += v * v;
        self.count += 1;
    }

    /// Solves for the coefficients in the frame `u = d/r`, given `scale = h/r`. Returns the
    /// coefficients and the root-mean-square residual, or `None` with no sample.
    ///
    /// Cholesky of the scaled system, unless it fails or its pivots span more than 10⁶
    /// (condition number above 10¹²): then the minimum-norm least-squares solution by SVD,
    /// which also serves rank-deficient sample sets (a single slice, a line of voxels).
    pub(crate) fn solve(&self, scale: f64) -> Option<([f64; N], f64)> {
        if self.count == 0 {
            return None;
        }
        let mut pow = [1.0; N];
        for a in 0..N {
            pow[a] = scale.powi(DEGREE[a]);
        }
        let m = SMatrix::<f64, N, N>::from_fn(|a, bb| {
            let (lo, hi) = if a <= bb { (a, bb) } else { (bb, a) };
            self.m[lo][hi] * pow[a] * pow[bb]
        });
        let b = SVector::<f64, N>::from_fn(|a, _| self.b[a] * pow[a]);
        let c = solve_spd(m, &b)?;
        // RSS = Σv² − 2cᵀb + cᵀMc (exact for any c; no normal-equation assumption).
        let mc = m * c;
        let rss = (self.vv - 2.0 * c.dot(&b) + c.dot(&mc)).max(0.0);
        let rms = (rss / self.count as f64).sqrt();
        let mut out = [0.0; N];
        out.copy_from_slice(c.as_slice());
        Some((out, rms))
    }
}

fn solve_spd<const N: usize>(
    m: SMatrix<f64, N, N>,
    b: &SVector<f64, N>,
) -> Option<SVector<f64, N>> {
    if let Some(chol) = m.cholesky() {
        let diag = chol.l_dirty().diagonal();
        let (lo, hi) = diag.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        });
        if lo > 1e-6 * hi {
            let c = chol.solve(b);
            if c.iter().all(|v| v.is_finite()) {
                return Some(c);
            }
        }
    }
    // The fallback is rare: a dynamic matrix avoids const-generic bounds of nalgebra's SVD.
    let svd = DMatrix::from_column_slice(N, N, m.as_slice()).svd(true, true);
    let max = svd.singular_values.max();
    if !(max.is_finite() && max > 0.0) {
        return Some(SVector::zeros());
    }
    let c = svd
        .solve(&DVector::from_column_slice(b.as_slice()), 1e-12 * max)
        .ok()?;
    c.iter()
        .all(|v| v.is_finite())
        .then(|| SVector::from_column_slice(c.as_slice()))
}

/// Value of the fitted function (coefficients `c` in the frame `u`) at `u`.
#[inline]
pub(crate) fn evaluate<const N: usize>(c: &[f64; N], u: [f64; 3]) -> f64 {
    let phi = basis::<N>(u);
    (0..N).map(|a| c[a] * phi[a]).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// A quadratic sampled at scattered points is recovered exactly, with zero residual,
        /// in every frame scale.
        #[test]
        fn quadratic_reproduced(
            coef in proptest::array::uniform10(-2.0f64..2.0),
            pts in proptest::collection::vec(proptest::array::uniform3(-3.0f64..3.0), 30..60),
            scale in 0.2f64..5.0,
        ) {
            let mut ne = NormalEquations::<QUADRATIC>::new();
            let mut vmax: f64 = 0.0;
            for p in &pts {
                let u = [p[0] * scale, p[1] * scale, p[2] * scale];
                let v = evaluate(&coef, u);
                vmax = vmax.max(v.abs());
                ne.add(*p, v);
            }
            let (c, rms) = ne.solve(scale).unwrap();
            // The residual comes from Σv² − 2cᵀb + cᵀMc, which cancels to ~√(ε_mach)·|v|
            // for an exact fit; the builder reports directly summed residuals instead.
            prop_assert!(rms < 1e-6 * (1.0 + vmax), "rms {rms}");
            for (a, b) in c.iter().zip(&coef) {
                prop_assert!((a - b).abs() < 1e-6, "{c:?} vs {coef:?}");
            }
        }

        /// The residual of the normal equations equals the one summed directly.
        #[test]
        fn rms_matches_direct_sum(
            pts in proptest::collection::vec(
                (proptest::array::uniform3(-1.0f64..1.0), 0.0f64..1.0), 12..50),
        ) {
            let mut ne = NormalEquations::<QUADRATIC>::new();
            for (p, v) in &pts {
                ne.add(*p, *v);
            }
            let (c, rms) = ne.solve(1.0).unwrap();
            let direct = (pts.iter().map(|(p, v)| (evaluate(&c, *p) - v).powi(2)).sum::<f64>()
                / pts.len() as f64).sqrt();
            prop_assert!((rms - direct).abs() < 1e-6, "{rms} vs {direct}");
        }
    }

    #[test]
    fn rank_deficient_planar_samples_fit() {
        // Samples on the plane z = 0: the z monomials are unconstrained; SVD gives the
        // minimum-norm fit, which reproduces x² + y.
        let mut ne = NormalEquations::<QUADRATIC>::new();
        for i in -3..=3 {
            for j in -3..=3 {
                let (x, y) = (i as f64 * 0.3, j as f64 * 0.3);
                ne.add([x, y, 0.0], x * x + y);
            }
        }
        let (c, rms) = ne.solve(1.0).unwrap();
        assert!(rms < 1e-9);
        assert!((c[4] - 1.0).abs() < 1e-9 && (c[2] - 1.0).abs() < 1e-9);
        assert!(c[3].abs() < 1e-9 && c[6].abs() < 1e-9);
    }
}
