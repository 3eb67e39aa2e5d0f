//! Radial weight kernels of the partition of unity (thesis §3.2–§3.3).
//!
//! The method is described on [`Kernel`].

use glam::{DMat3, DVec3};
use std::fmt;
use std::str::FromStr;

/// Gaussian width of the truncated Gaussian kernel in units of the support radius (thesis
/// eq. 3.10; the OCR copy lost the value, 1/3 puts the truncation at three standard
/// deviations).
pub const GAUSSIAN_KAPPA: f64 = 1.0 / 3.0;

/// `1 / (2κ²)` for [`GAUSSIAN_KAPPA`].
const GAUSSIAN_RATE: f64 = 4.5;

/// The radial weight profile of a support.
///
/// A support with centre `c` and radius `r` weighs a point `x` by `ψ(t)`, `t = ‖x − c‖ / r`,
/// where `ψ` is one of the profiles of [`Kernel`]. Every profile vanishes for `t ≥ 1`, so the
/// support of the weight is exactly the open ball.
///
/// # Derivatives without dividing by zero
///
/// With the scaled offset `u = (x − c) / r` (so `t = ‖u‖`), a radial weight has
///
/// ```text
/// ∇w  = A(t) u / r                      A(t) = ψ'(t) / t
/// ∇²w = (A(t) I + B(t) u uᵀ) / r²       B(t) = (ψ''(t) − A(t)) / t²
/// ```
///
/// For every kernel here `A` has a finite limit at `t = 0` (the profiles are even and smooth
/// at the centre), so the gradient is 0 and the Hessian `A(0) I / r²` at the centre. `B` may
/// grow like `1/t` there (Wendland), but `B u uᵀ` is `O(t)`; the code evaluates `A` and
/// `B u uᵀ` in closed form from `s = t²`, never dividing by `t` where `t` can be 0. The
/// Gaussian needs no square root at all; the B-spline needs `t` only outside its inner
/// parabola; Wendland always needs `t`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// Quadratic B-spline `b2(3t/2)` (thesis eq. 3.3): `b2(u) = 3/4 − u²` for `u ≤ 1/2`,
    /// `(3/2 − u)²/2` for `1/2 ≤ u ≤ 3/2`. Value `3/4` at the centre; C1 (its second
    /// derivative jumps at `t = 1/3` and `t = 1`). The thesis default for surfaces.
    #[default]
    QuadraticBSpline,
    /// Truncated Gaussian `exp(−t²/(2κ²))` for `t < 1`, κ = [`GAUSSIAN_KAPPA`] (thesis
    /// eq. 3.10). Discontinuous at `t = 1` (it jumps from `exp(−4.5) ≈ 0.011` to 0). The
    /// thesis default for volumes.
    TruncatedGaussian,
    /// Wendland's C2 function `(1 − t)⁴(4t + 1)`. C2 everywhere, including the sphere
    /// `t = 1`: the choice wherever Hessians of `f` are taken.
    WendlandC2,
}

impl Kernel {
    /// Every kernel, in declaration order.
    pub const ALL: [Kernel; 3] = [
        Kernel::QuadraticBSpline,
        Kernel::TruncatedGaussian,
        Kernel::WendlandC2,
    ];

    /// The kernel's name as accepted by [`Kernel::from_str`].
    pub fn name(self) -> &'static str {
        match self {
            Kernel::QuadraticBSpline => "bspline2",
            Kernel::TruncatedGaussian => "gaussian",
            Kernel::WendlandC2 => "wendland",
        }
    }

    /// The scaled distances `t` at which the weight is not C∞, ascending. Away from the
    /// spheres `‖x − c‖ = t r` for these `t` the weight is infinitely smooth; finite-difference
    /// checks and anything else that assumes smoothness must keep clear of them. (Wendland's
    /// odd powers of `t` make it only C2 at the centre, `t = 0`.)
    pub fn nonsmooth_radii(self) -> &'static [f64] {
        match self {
            Kernel::QuadraticBSpline => &[1.0 / 3.0, 1.0],
            Kernel::TruncatedGaussian => &[1.0],
            Kernel::WendlandC2 => &[0.0, 1.0],
        }
    }

    /// The `k` for which the weight is C^k everywhere (and not C^(k+1)), or `None` when it is
    /// discontinuous (the truncated Gaussian at `t = 1`).
    pub fn smoothness(self) -> Option<u32> {
        match self {
            Kernel::QuadraticBSpline => Some(1),
            Kernel::TruncatedGaussian => None,
            Kernel::WendlandC2 => Some(2),
        }
    }

    /// The profile `ψ(t)` at scaled distance `t = ‖x − c‖ / r ≥ 0` (0 for `t ≥ 1` and for a
    /// NaN `t`).
    pub fn profile(self, t: f64) -> f64 {
        let t = t.abs();
        if t >= 1.0 || t.is_nan() {
            return 0.0;
        }
        match self {
            Kernel::QuadraticBSpline => {
                if t <= 1.0 / 3.0 {
                    0.75 - 2.25 * t * t
                } else {
                    let m = 1.0 - t;
                    1.125 * m * m
                }
            }
            Kernel::TruncatedGaussian => (-GAUSSIAN_RATE * t * t).exp(),
            Kernel::WendlandC2 => {
                let m = 1.0 - t;
                let m2 = m * m;
                m2 * m2 * (4.0 * t + 1.0)
            }
        }
    }

    /// The weight at `x` of a support with centre `centre` and radius `radius > 0`.
    pub fn weight(self, x: DVec3, centre: DVec3, radius: f64) -> f64 {
        // Multiplying by the reciprocal, like the derivative paths, keeps them bitwise equal.
        let u = (x - centre) * (1.0 / radius);
        self.value_sq(u.length_squared())
    }

    /// The weight and its gradient with respect to `x`.
    pub fn weight_gradient(self, x: DVec3, centre: DVec3, radius: f64) -> (f64, DVec3) {
        let inv_r = 1.0 / radius;
        let u = (x - centre) * inv_r;
        let (w, a) = self.value_slope_sq(u.length_squared());
        (w, u * (a * inv_r))
    }

    /// The weight, its gradient and its Hessian with respect to `x`.
    pub fn weight_gradient_hessian(
        self,
        x: DVec3,
        centre: DVec3,
        radius: f64,
    ) -> (f64, DVec3, DMat3) {
        let inv_r = 1.0 / radius;
        let u = (x - centre) * inv_r;
        let (w, a, b) = self.value_slope_curvature_sq(u.length_squared());
        let (grad, hess) = gradient_hessian(u, inv_r, a, b);
        (w, grad, hess)
    }

    /// `ψ` as a function of `s = t²`.
    #[inline]
    pub(crate) fn value_sq(self, s: f64) -> f64 {
        if s >= 1.0 || s.is_nan() {
            return 0.0;
        }
        match self {
            Kernel::QuadraticBSpline => {
                if s <= 1.0 / 9.0 {
                    0.75 - 2.25 * s
                } else {
                    let m = 1.0 - s.sqrt();
                    1.125 * m * m
                }
            }
            Kernel::TruncatedGaussian => (-GAUSSIAN_RATE * s).exp(),
            Kernel::WendlandC2 => {
                let t = s.sqrt();
                let m = 1.0 - t;
                let m2 = m * m;
                m2 * m2 * (4.0 * t + 1.0)
            }
        }
    }

    /// [`Kernel::value_sq`] without a branch on `s ≥ 1` for the quadratic B-spline and
    /// Wendland kernels: the same bits for `s < 1`, and 0 for `s ≥ 1` (and NaN). The
    /// partition-of-unity sums test candidates of which many lie outside their ball, in no
    /// order a branch predictor can follow; these kernels reach 0 at `t = 1` anyway, so `t`
    /// is clamped to 1 instead. (The Gaussian keeps the branch: its exponential
    /// costs more than a missed prediction.)
    #[inline(always)]
    pub(crate) fn value_sq_clamped(self, s: f64) -> f64 {
        match self {
            Kernel::QuadraticBSpline => {
                let m = 1.0 - root_clamped(s);
                let far = 1.125 * m * m;
                if s <= 1.0 / 9.0 { 0.75 - 2.25 * s } else { far }
            }
            Kernel::TruncatedGaussian => self.value_sq(s),
            Kernel::WendlandC2 => {
                let t = root_clamped(s);
                let m = 1.0 - t;
                let m2 = m * m;
                m2 * m2 * (4.0 * t + 1.0)
            }
        }
    }

    /// `(ψ, A)` as functions of `s = t²`, with `A = ψ'(t)/t` (see [`Kernel`]).
    #[inline]
    pub(crate) fn value_slope_sq(self, s: f64) -> (f64, f64) {
        if s >= 1.0 || s.is_nan() {
            return (0.0, 0.0);
        }
        match self {
            Kernel::QuadraticBSpline => {
                if s <= 1.0 / 9.0 {
                    (0.75 - 2.25 * s, -4.5)
                } else {
                    let t = s.sqrt();
                    let m = 1.0 - t;
                    (1.125 * m * m, -2.25 * m / t)
                }
            }
            Kernel::TruncatedGaussian => {
                let w = (-GAUSSIAN_RATE * s).exp();
                (w, -2.0 * GAUSSIAN_RATE * w)
            }
            Kernel::WendlandC2 => {
                let t = s.sqrt();
                let m = 1.0 - t;
                let m2 = m * m;
                // Same operation order as `value_sq`, so every query path agrees bitwise.
                (m2 * m2 * (4.0 * t + 1.0), -20.0 * m2 * m)
            }
        }
    }

    /// `(ψ, A, B)` as functions of `s = t²`, with `A = ψ'(t)/t`, `B = (ψ''(t) − A)/t²`.
    ///
    /// Where `B` is singular at `t = 0` (Wendland) it is returned as 0 at exactly `t = 0`,
    /// which is the limit of `B u uᵀ` there.
    #[inline]
    pub(crate) fn value_slope_curvature_sq(self, s: f64) -> (f64, f64, f64) {
        if s >= 1.0 || s.is_nan() {
            return (0.0, 0.0, 0.0);
        }
        match self {
            Kernel::QuadraticBSpline => {
                if s <= 1.0 / 9.0 {
                    (0.75 - 2.25 * s, -4.5, 0.0)
                } else {
                    let t = s.sqrt();
                    let m = 1.0 - t;
                    // ψ = 9/8 m², ψ' = −9/4 m, ψ'' = 9/4, so B = 9/(4 t³).
                    (1.125 * m * m, -2.25 * m / t, 2.25 / (s * t))
                }
            }
            Kernel::TruncatedGaussian => {
                let w = (-GAUSSIAN_RATE * s).exp();
                let k = 2.0 * GAUSSIAN_RATE;
                (w, -k * w, k * k * w)
            }
            Kernel::WendlandC2 => {
                let t = s.sqrt();
                let m = 1.0 - t;
                let m2 = m * m;
                // ψ' = −20 t m³, ψ'' = −20 m³ + 60 t m², so B = 60 m² / t.
                let b = if t > 0.0 { 60.0 * m2 / t } else { 0.0 };
                (m2 * m2 * (4.0 * t + 1.0), -20.0 * m2 * m, b)
            }
        }
    }
}

/// `t = √s` for `s < 1`, else 1 (also for NaN), as a select rather than a branch.
#[inline(always)]
fn root_clamped(s: f64) -> f64 {
    let t = s.sqrt();
    if t < 1.0 { t } else { 1.0 }
}

/// Gradient `A u / r` and Hessian `(A I + B u uᵀ) / r²` of a radial weight from the terms
/// `(A, B)` of [`Kernel::value_slope_curvature_sq`], the scaled offset `u` and `1/r`. The
/// Hessian is exactly symmetric (`u uᵀ` is formed before scaling by `B`), and the gradient is
/// the same expression as in [`Kernel::weight_gradient`], so both agree bitwise.
#[inline]
pub(crate) fn gradient_hessian(u: DVec3, inv_r: f64, a: f64, b: f64) -> (DVec3, DMat3) {
    let hess = (DMat3::from_diagonal(DVec3::splat(a)) + outer(u, u) * b) * (inv_r * inv_r);
    (u * (a * inv_r), hess)
}

/// `a bᵀ` as a matrix (glam has no outer product for `DVec3`).
#[inline]
pub(crate) fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

impl fmt::Display for Kernel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A kernel name that [`Kernel::from_str`] does not know.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown kernel {0:?} (expected one of: bspline2, gaussian, wendland)")]
pub struct ParseKernelError(pub String);

impl FromStr for Kernel {
    type Err = ParseKernelError;

    fn from_str(s: &str) -> Result<Kernel, ParseKernelError> {
        Kernel::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| ParseKernelError(s.to_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The clamped weight has the bits of the plain one inside the ball and is 0 on and
        /// outside its sphere, whatever the kernel.
        #[test]
        fn the_clamped_weight_is_the_weight(
            kernel in prop::sample::select(Kernel::ALL.to_vec()),
            inside in 0.0..1.0f64,
            outside in 1.0..1e300f64,
        ) {
            prop_assert_eq!(
                kernel.value_sq_clamped(inside).to_bits(),
                kernel.value_sq(inside).to_bits()
            );
            prop_assert_eq!(kernel.value_sq_clamped(outside).to_bits(), 0.0f64.to_bits());
        }
    }

    #[test]
    fn the_clamped_weight_at_the_edges() {
        for kernel in Kernel::ALL {
            for s in [0.0, 1.0 / 9.0, f64::from_bits((1.0f64).to_bits() - 1)] {
                assert_eq!(
                    kernel.value_sq_clamped(s).to_bits(),
                    kernel.value_sq(s).to_bits(),
                    "{kernel} at {s}"
                );
            }
            for s in [1.0, f64::INFINITY, f64::NAN] {
                assert_eq!(kernel.value_sq_clamped(s).to_bits(), 0, "{kernel} at {s}");
            }
        }
    }
}
