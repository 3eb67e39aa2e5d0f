//! The partition of unity reproduces any function that every support carries exactly
//! (thesis eq. 3.1: the weights sum to one), with its gradient and Hessian.

mod pu_common;

use proptest::prelude::*;
use pu_common::*;
use sphcover_core::{DMat3, DVec3, LinearFunction, LocalFunctions, PuEvaluator, QuadraticFunction};

/// Error bounds for a reproduced function of magnitude `s` (largest intermediate value),
/// gradient magnitude `g` and Hessian magnitude `h`: rounding in the local functions (a few
/// ulps of `s`) is amplified by `‖∇w‖/W` and `‖∇²w‖/W` in the quotient rule.
struct Tolerance {
    value: f64,
    gradient: f64,
    hessian: f64,
}

fn tolerance(stats: WeightStats, s: f64, g: f64, h: f64) -> Tolerance {
    let c = 64.0 * (stats.count as f64 + 1.0) * EPS;
    let gw = stats.grad_sum / stats.w;
    let hw = stats.hess_sum / stats.w;
    Tolerance {
        value: c * s,
        gradient: c * (s * gw + g),
        hessian: c * (s * hw + s * gw * gw + g * gw + h),
    }
}

fn check_reproduction(
    eval: &PuEvaluator<'_>,
    sigma: f64,
    x: DVec3,
    value: f64,
    gradient: DVec3,
    hessian: DMat3,
    scales: (f64, f64, f64),
) -> Result<(), TestCaseError> {
    let stats = weight_stats(eval.cover(), sigma, x);
    prop_assume!(stats.w > 0.0);
    let tol = tolerance(stats, scales.0, scales.1, scales.2);
    let v = eval.value(x).expect("x inside a support");
    let vg = eval.value_gradient(x).expect("x inside a support");
    let vgh = eval.value_gradient_hessian(x).expect("x inside a support");
    prop_assert!(
        (v - value).abs() <= tol.value,
        "value {v} vs {value}, tol {}",
        tol.value
    );
    prop_assert_eq!(vg.value.to_bits(), v.to_bits());
    prop_assert_eq!(vgh.value.to_bits(), v.to_bits());
    prop_assert!(
        (vg.gradient - gradient).length() <= tol.gradient,
        "gradient {} vs {gradient}, tol {}",
        vg.gradient,
        tol.gradient
    );
    prop_assert_eq!(vgh.gradient, vg.gradient);
    prop_assert!(
        frobenius(vgh.hessian - hessian) <= tol.hessian,
        "hessian {} vs {hessian}, tol {}",
        vgh.hessian,
        tol.hessian
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(192))]

    #[test]
    fn linear_function_is_reproduced(
        supports in supports_strategy(40),
        kernel in kernel_strategy(),
        sigma in sigma_strategy(),
        p in vec3(2.0),
        q in -2.0..2.0f64,
        picks in inner_points_strategy(8),
        quadratic_storage in any::<bool>(),
    ) {
        let linear = LocalFunctions::from_linear(
            supports.iter().map(|&(c, _)| LinearFunction::from_global(p, q, c)),
        );
        let funcs = if quadratic_storage { linear.to_quadratic() } else { linear };
        let cover = build(&supports, funcs, kernel);
        let eval = PuEvaluator::new(&cover, sigma).unwrap();
        for x in place(&supports, sigma, &picks) {
            let reach = x.length() + 1.0;
            let s = p.length() * reach + q.abs();
            check_reproduction(&eval, sigma, x, p.dot(x) + q, p, DMat3::ZERO, (s, p.length(), 0.0))?;
        }
    }

    #[test]
    fn constant_is_reproduced(
        supports in supports_strategy(40),
        kernel in kernel_strategy(),
        sigma in sigma_strategy(),
        k in -5.0..5.0f64,
        picks in inner_points_strategy(8),
        quadratic_storage in any::<bool>(),
    ) {
        let constant = LocalFunctions::from_linear(
            supports.iter().map(|_| LinearFunction { alpha: DVec3::ZERO, beta: k }),
        );
        let funcs = if quadratic_storage { constant.to_quadratic() } else { constant };
        let cover = build(&supports, funcs, kernel);
        let eval = PuEvaluator::new(&cover, sigma).unwrap();
        for x in place(&supports, sigma, &picks) {
            check_reproduction(&eval, sigma, x, k, DVec3::ZERO, DMat3::ZERO, (k.abs(), 0.0, 0.0))?;
        }
    }

    #[test]
    fn quadratic_function_is_reproduced(
        supports in supports_strategy(40),
        kernel in kernel_strategy(),
        sigma in sigma_strategy(),
        q_mat in random_symmetric(),
        p in vec3(1.0),
        q in -1.0..1.0f64,
        picks in inner_points_strategy(8),
    ) {
        let funcs = LocalFunctions::from_quadratic(
            supports.iter().map(|&(c, _)| QuadraticFunction::from_global(q_mat, p, q, c)),
        );
        let cover = build(&supports, funcs, kernel);
        let eval = PuEvaluator::new(&cover, sigma).unwrap();
        let norm_q = frobenius(q_mat);
        for x in place(&supports, sigma, &picks) {
            let reach = x.length() + 1.0;
            let s = norm_q * reach * reach + p.length() * reach + q.abs();
            let g = 2.0 * norm_q * reach + p.length();
            let value = x.dot(q_mat * x) + p.dot(x) + q;
            check_reproduction(&eval, sigma, x, value, q_mat * x * 2.0 + p, q_mat * 2.0, (s, g, 2.0 * norm_q))?;
        }
    }
}
