//! The analytic `∇f` and `∇²f` of the partition of unity match central finite differences of
//! `f` and `∇f` wherever `f` is smooth.

mod pu_common;

use proptest::prelude::*;
use pu_common::*;
use sphcover_core::{Cover, DMat3, DVec3, LocalFunctions, PuEvaluator};

/// Stencil step as a fraction of the distance to the nearest non-smooth sphere: the whole
/// stencil stays a thousand steps away from every kink, and the truncation error
/// `O((h/ℓ)²)` stays near 1e-6 of the derivative scale.
const STEP_FRACTION: f64 = 1e-3;

fn check_against_differences(cover: &Cover, sigma: f64, x: DVec3) -> Result<(), TestCaseError> {
    let eval = PuEvaluator::new(cover, sigma).unwrap();
    let ell = distance_to_nonsmooth(cover, sigma, x);
    let r_max = cover.radii().iter().fold(0.0f64, |a, &r| a.max(r)) * sigma;
    // Too close to a kink to resolve with a sane step: not a smooth point for this test.
    if ell <= 1e-6 * r_max {
        return Ok(());
    }
    let h = STEP_FRACTION * ell;
    let Some(at_x) = eval.value_gradient_hessian(x) else {
        return Ok(());
    };
    let stats = weight_stats(cover, sigma, x);
    // Scales of f's derivatives: the local functions (|g| ≤ s, |∇g| ≤ g1, |∇²g| ≤ h1 on the
    // sampled region) multiplied by the relative weight derivatives.
    let (s, g1, h1) = (4.0, 4.0, 4.0);
    let gw = stats.grad_sum / stats.w;
    let hw = stats.hess_sum / stats.w;
    let grad_scale = s * gw + g1;
    let hess_scale = s * hw + s * gw * gw + g1 * gw + h1;
    for axis in 0..3 {
        let e = DVec3::AXES[axis] * h;
        let (Some(plus), Some(minus)) = (eval.value_gradient(x + e), eval.value_gradient(x - e))
        else {
            return Ok(());
        };
        let fd_grad = (plus.value - minus.value) / (2.0 * h);
        let tol_g = 1e-4 * grad_scale + 1e3 * EPS * s / h;
        prop_assert!(
            (fd_grad - at_x.gradient[axis]).abs() <= tol_g,
            "∂f/∂x{axis}: analytic {} vs difference {fd_grad} (tol {tol_g}, h {h})",
            at_x.gradient[axis]
        );
        let fd_hess_col = (plus.gradient - minus.gradient) / (2.0 * h);
        let tol_h = 1e-4 * hess_scale + 1e3 * EPS * grad_scale / h;
        let col = at_x.hessian.col(axis);
        prop_assert!(
            (fd_hess_col - col).length() <= tol_h,
            "∇²f column {axis}: analytic {col} vs difference {fd_hess_col} (tol {tol_h}, h {h})"
        );
    }
    // The analytic Hessian is exactly symmetric.
    prop_assert_eq!(at_x.hessian, at_x.hessian.transpose());
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn derivatives_match_differences_linear(
        (supports, funcs) in supports_strategy(30)
            .prop_flat_map(|s| { let n = s.len(); (Just(s), random_linear(n)) }),
        kernel in kernel_strategy(),
        sigma in sigma_strategy(),
        picks in inner_points_strategy(6),
    ) {
        let cover = build(&supports, LocalFunctions::from_linear(funcs), kernel);
        for x in place(&supports, sigma, &picks) {
            check_against_differences(&cover, sigma, x)?;
        }
    }

    #[test]
    fn derivatives_match_differences_quadratic(
        (supports, funcs) in supports_strategy(30)
            .prop_flat_map(|s| { let n = s.len(); (Just(s), random_quadratic(n)) }),
        kernel in kernel_strategy(),
        sigma in sigma_strategy(),
        picks in inner_points_strategy(6),
    ) {
        let cover = build(&supports, LocalFunctions::from_quadratic(funcs), kernel);
        for x in place(&supports, sigma, &picks) {
            check_against_differences(&cover, sigma, x)?;
        }
    }
}

/// At a support centre the weight's gradient is 0 and its Hessian finite: `f` stays smooth
/// there, including for Wendland whose radial curvature term is singular in `t`.
#[test]
fn derivatives_are_finite_at_centres() {
    for kernel in sphcover_core::Kernel::ALL {
        for sigma in SIGMAS {
            let supports = [
                (DVec3::ZERO, 1.0),
                (DVec3::new(0.3, 0.1, 0.0), 0.5),
                (DVec3::new(-0.2, 0.0, 0.25), 0.05),
            ];
            let funcs = LocalFunctions::from_quadratic([0.5, -1.0, 2.0].into_iter().map(|k| {
                sphcover_core::QuadraticFunction {
                    a: DMat3::from_diagonal(DVec3::new(k, 1.0, -k)),
                    b: DVec3::new(k, -k, 0.5),
                    k,
                }
            }));
            let cover = build(&supports, funcs, kernel);
            let eval = PuEvaluator::new(&cover, sigma).unwrap();
            for &(c, _) in &supports {
                let r = eval.value_gradient_hessian(c).expect("centre is covered");
                assert!(r.value.is_finite() && r.gradient.is_finite() && r.hessian.is_finite());
            }
        }
    }
}
