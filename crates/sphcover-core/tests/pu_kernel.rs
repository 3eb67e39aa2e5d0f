//! Weight kernels: formulas, support, analytic derivatives against finite differences, and
//! continuity at the kinks.

mod pu_common;

use proptest::prelude::*;
use pu_common::*;
use sphcover_core::{DMat3, DVec3, Kernel};

/// The quadratic B-spline of thesis eq. 3.3, written independently of the crate.
fn b2(u: f64) -> f64 {
    let u = u.abs();
    if u <= 0.5 {
        0.75 - u * u
    } else if u <= 1.5 {
        0.5 * (1.5 - u) * (1.5 - u)
    } else {
        0.0
    }
}

fn reference_profile(kernel: Kernel, t: f64) -> f64 {
    match kernel {
        Kernel::QuadraticBSpline => b2(1.5 * t),
        Kernel::TruncatedGaussian if t < 1.0 => (-t * t / (2.0 / 9.0)).exp(),
        Kernel::TruncatedGaussian => 0.0,
        Kernel::WendlandC2 if t < 1.0 => (1.0 - t).powi(4) * (4.0 * t + 1.0),
        Kernel::WendlandC2 => 0.0,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn profile_matches_formula(kernel in kernel_strategy(), t in 0.0..1.5f64) {
        let expected = reference_profile(kernel, t);
        prop_assert!((kernel.profile(t) - expected).abs() <= 1e-15, "{kernel} at t = {t}");
    }

    #[test]
    fn weight_is_the_profile_of_the_scaled_distance(
        kernel in kernel_strategy(),
        c in vec3(1.0),
        dir in unit_vector(),
        t in 0.0..1.5f64,
        log_r in -3.0..1.0f64,
    ) {
        let r = 10f64.powf(log_r);
        let x = c + dir * (t * r);
        let t_actual = x.distance(c) / r;
        let w = kernel.weight(x, c, r);
        prop_assert!((w - kernel.profile(t_actual)).abs() <= 1e-13);
        // All three evaluation paths agree bitwise on the weight.
        prop_assert_eq!(kernel.weight_gradient(x, c, r).0.to_bits(), w.to_bits());
        let (w_h, g_h, h_h) = kernel.weight_gradient_hessian(x, c, r);
        prop_assert_eq!(w_h.to_bits(), w.to_bits());
        prop_assert_eq!(g_h, kernel.weight_gradient(x, c, r).1);
        prop_assert_eq!(h_h, h_h.transpose());
        if t_actual >= 1.0 {
            prop_assert_eq!(w, 0.0);
            prop_assert_eq!(kernel.weight_gradient(x, c, r).1, DVec3::ZERO);
            prop_assert_eq!(kernel.weight_gradient_hessian(x, c, r).2, DMat3::ZERO);
        } else {
            prop_assert!(w > 0.0);
        }
    }

    #[test]
    fn derivatives_match_differences(
        kernel in kernel_strategy(),
        c in vec3(1.0),
        dir in unit_vector(),
        t in 0.0..1.0f64,
        log_r in -3.0..1.0f64,
    ) {
        let r = 10f64.powf(log_r);
        let x = c + dir * (t * r);
        let dist = x.distance(c);
        // Distance to the nearest sphere where the weight is not smooth.
        let ell = kernel
            .nonsmooth_radii()
            .iter()
            .map(|k| (dist - k * r).abs())
            .fold(f64::INFINITY, f64::min);
        prop_assume!(ell > 1e-4 * r);
        let h = 1e-4 * ell.min(r);
        let (_, grad, hess) = kernel.weight_gradient_hessian(x, c, r);
        for axis in 0..3 {
            let e = DVec3::AXES[axis] * h;
            let (xp, xm) = (x + e, x - e);
            // The step actually taken: `x ± e` is rounded to the spacing of |x|, which near a
            // far-off centre is not small against a tiny `h`; the difference of the two rounded
            // coordinates is exact (Sterbenz).
            let span = xp[axis] - xm[axis];
            let (wp, gp) = kernel.weight_gradient(xp, c, r);
            let (wm, gm) = kernel.weight_gradient(xm, c, r);
            let fd = (wp - wm) / span;
            let tol_g = 1e-5 / r + 1e2 * EPS / h;
            prop_assert!((fd - grad[axis]).abs() <= tol_g, "{kernel}: ∂w/∂x{axis} {} vs {fd}", grad[axis]);
            let fd_col = (gp - gm) / span;
            let tol_h = 1e-5 / (r * r) + 1e2 * EPS / (h * r);
            prop_assert!(
                (fd_col - hess.col(axis)).length() <= tol_h,
                "{kernel}: ∇²w column {axis} {} vs {fd_col}", hess.col(axis)
            );
        }
    }

    /// Where a kernel is C0/C1/C2 across a kink sphere, the one-sided limits of the value,
    /// gradient and Hessian agree; where it is not, they differ by the known jump.
    #[test]
    fn continuity_at_kinks(
        kernel in kernel_strategy(),
        c in vec3(1.0),
        dir in unit_vector(),
        log_r in -2.0..1.0f64,
    ) {
        let r = 10f64.powf(log_r);
        let delta = 1e-9;
        for &k in kernel.nonsmooth_radii().iter().filter(|&&k| k > 0.0) {
            let inside = c + dir * ((k - delta) * r);
            let outside = c + dir * ((k + delta) * r);
            let (w_in, g_in, h_in) = kernel.weight_gradient_hessian(inside, c, r);
            let (w_out, g_out, h_out) = kernel.weight_gradient_hessian(outside, c, r);
            let value_jump = (w_in - w_out).abs();
            let grad_jump = (g_in - g_out).length() * r;
            let hess_jump = frobenius(h_in - h_out) * r * r;
            match (kernel, k == 1.0) {
                (Kernel::TruncatedGaussian, true) => {
                    prop_assert!((value_jump - (-4.5f64).exp()).abs() < 1e-6, "jump {value_jump}");
                }
                (Kernel::QuadraticBSpline, _) => {
                    prop_assert!(value_jump < 1e-6 && grad_jump < 1e-6);
                    // ψ'' jumps from −9/2 to 9/4 at t = 1/3 and from 9/4 to 0 at t = 1.
                    let expected = if k == 1.0 { 2.25 } else { 6.75 };
                    prop_assert!((hess_jump - expected).abs() < 1e-5, "hessian jump {hess_jump}");
                }
                (Kernel::WendlandC2, true) => {
                    prop_assert!(value_jump < 1e-6 && grad_jump < 1e-6 && hess_jump < 1e-6);
                }
                _ => prop_assert!(false, "unexpected kink {k} for {kernel}"),
            }
        }
    }
}

/// Wendland's Hessian is continuous through the centre (C2) although its curvature term
/// `B(t) = 60 (1 − t)² / t` is singular there.
#[test]
fn wendland_hessian_is_continuous_at_the_centre() {
    let c = DVec3::new(0.1, 0.2, 0.3);
    let r = 0.7;
    let at_centre = Kernel::WendlandC2.weight_gradient_hessian(c, c, r).2;
    for step in [1e-6, 1e-9, 1e-12, 1e-300] {
        let x = c + DVec3::new(1.0, -2.0, 0.5).normalize() * step;
        let (_, g, h) = Kernel::WendlandC2.weight_gradient_hessian(x, c, r);
        assert!(g.length() <= 30.0 * step / (r * r));
        assert!(
            frobenius(h - at_centre) <= 1e3 * step / (r * r * r) + 1e-12,
            "{h} at {step}"
        );
    }
}

#[test]
fn centre_values_and_derivatives() {
    let c = DVec3::new(0.3, -0.2, 0.7);
    for r in [1e-3, 0.25, 1.0, 40.0] {
        for kernel in Kernel::ALL {
            let (w, g, h) = kernel.weight_gradient_hessian(c, c, r);
            let (w0, a0) = match kernel {
                // b2(0) = 3/4; ∇² = −2 (3/(2r))² I.
                Kernel::QuadraticBSpline => (0.75, -2.0 * (1.5 / r) * (1.5 / r)),
                // ψ = exp(−t²/(2κ²)), ψ''(0) = −1/κ² = −9.
                Kernel::TruncatedGaussian => (1.0, -9.0 / (r * r)),
                // ψ = (1 − t)⁴(4t + 1), ψ''(0) = −20.
                Kernel::WendlandC2 => (1.0, -20.0 / (r * r)),
            };
            assert_eq!(w, w0, "{kernel}");
            assert_eq!(g, DVec3::ZERO, "{kernel}");
            let expected = DMat3::from_diagonal(DVec3::splat(a0));
            assert!(
                frobenius(h - expected) <= 1e-12 * a0.abs(),
                "{kernel}: {h} vs {expected}"
            );
        }
    }
}

#[test]
fn support_is_the_open_ball() {
    let c = DVec3::new(1.0, 2.0, 3.0);
    let r = 0.5;
    for kernel in Kernel::ALL {
        for dir in [DVec3::X, DVec3::NEG_Y, DVec3::Z] {
            assert_eq!(
                kernel.weight(c + dir * r, c, r),
                0.0,
                "{kernel} on the sphere"
            );
            assert_eq!(
                kernel.weight(c + dir * (2.0 * r), c, r),
                0.0,
                "{kernel} outside"
            );
            assert!(
                kernel.weight(c + dir * (0.999 * r), c, r) > 0.0,
                "{kernel} inside"
            );
        }
        assert_eq!(kernel.profile(f64::NAN), 0.0);
        assert_eq!(kernel.profile(1.0), 0.0);
    }
}

#[test]
fn names_round_trip() {
    for kernel in Kernel::ALL {
        assert_eq!(kernel.name().parse::<Kernel>(), Ok(kernel));
        assert_eq!(
            kernel.to_string().to_uppercase().parse::<Kernel>(),
            Ok(kernel)
        );
    }
    assert!("cubic".parse::<Kernel>().is_err());
    assert_eq!(Kernel::QuadraticBSpline.smoothness(), Some(1));
    assert_eq!(Kernel::WendlandC2.smoothness(), Some(2));
    assert_eq!(Kernel::TruncatedGaussian.smoothness(), None);
    assert_eq!(Kernel::default(), Kernel::QuadraticBSpline);
}
