//! The Cholesky factorisation of small symmetric positive definite systems held in arrays: the
//! normal equations of per-vertex and per-support least-squares fits, solved millions of times,
//! where a heap-allocated matrix type would cost more than the arithmetic.

/// The Cholesky factor `L` (`A = L Lᵀ`) of a symmetric positive definite `N × N` matrix.
///
/// ```
/// use sphcover_core::SmallCholesky;
///
/// let a = [[4.0, 2.0], [2.0, 3.0]];
/// let x = SmallCholesky::new(&a).unwrap().solve([8.0, 7.0]);
/// assert!((x[0] - 1.25).abs() < 1e-12 && (x[1] - 1.5).abs() < 1e-12);
/// // Singular (samples on a line, say): refused rather than solved badly.
/// assert!(SmallCholesky::new(&[[1.0, 1.0], [1.0, 1.0]]).is_none());
/// ```
#[derive(Clone, Debug)]
pub struct SmallCholesky<const N: usize> {
    l: [[f64; N]; N],
}

impl<const N: usize> SmallCholesky<N> {
    /// Factors `a`, of which only the lower triangle is read. `None` when `a` is not
    /// numerically positive definite: a pivot at most `1e-12` times the largest diagonal
    /// entry, or a diagonal that is zero or not finite.
    pub fn new(a: &[[f64; N]; N]) -> Option<SmallCholesky<N>> {
        let scale = (0..N).map(|i| a[i][i]).fold(0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            return None;
        }
        let mut l = [[0.0; N]; N];
        for r in 0..N {
            for c in 0..=r {
                let mut s = a[r][c];
                for k in 0..c {
                    s -= l[r][k] * l[c][k];
                }
                if r == c {
                    if s.is_nan() || s <= 1e-12 * scale {
                        return None;
                    }
                    l[r][r] = s.sqrt();
                } else {
                    l[r][c] = s / l[c][c];
                }
            }
        }
        Some(SmallCholesky { l })
    }

    /// Solves `A x = b` by forward and back substitution.
    pub fn solve(&self, mut b: [f64; N]) -> [f64; N] {
        let l = &self.l;
        for r in 0..N {
            for k in 0..r {
                b[r] -= l[r][k] * b[k];
            }
            b[r] /= l[r][r];
        }
        for r in (0..N).rev() {
            for k in r + 1..N {
                b[r] -= l[k][r] * b[k];
            }
            b[r] /= l[r][r];
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// For `A = MᵀM + I` (symmetric positive definite), the solution satisfies `A x = b`
        /// to rounding.
        #[test]
        fn solves_spd_systems(
            m in proptest::array::uniform4(proptest::array::uniform4(-2.0f64..2.0)),
            b in proptest::array::uniform4(-5.0f64..5.0),
        ) {
            let mut a = [[0.0; 4]; 4];
            for i in 0..4 {
                for j in 0..4 {
                    a[i][j] = (0..4).map(|k| m[k][i] * m[k][j]).sum::<f64>()
                        + if i == j { 1.0 } else { 0.0 };
                }
            }
            let x = SmallCholesky::new(&a).unwrap().solve(b);
            for i in 0..4 {
                let ax: f64 = (0..4).map(|j| a[i][j] * x[j]).sum();
                prop_assert!((ax - b[i]).abs() <= 1e-9 * (1.0 + b[i].abs()), "{ax} vs {}", b[i]);
            }
        }

        /// A rank-deficient matrix `v vᵀ` is refused.
        #[test]
        fn refuses_rank_deficient(v in proptest::array::uniform3(0.5f64..2.0)) {
            let a: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| v[i] * v[j]));
            prop_assert!(SmallCholesky::new(&a).is_none());
        }
    }
}
