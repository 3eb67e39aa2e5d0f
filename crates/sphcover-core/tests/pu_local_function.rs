//! Local functions in centred form: derivatives, conversion from raw coordinates, storage.

mod pu_common;

use proptest::prelude::*;
use pu_common::*;
use sphcover_core::{
    DMat3, DVec3, LinearFunction, LocalFunction, LocalFunctions, QuadraticFunction,
};

proptest! {
    #[test]
    fn quadratic_derivatives_match_differences(
        a in random_symmetric(),
        skew in vec3(1.0),
        b in vec3(1.0),
        k in -1.0..1.0f64,
        d in vec3(1.0),
    ) {
        // A non-symmetric A on purpose: derivatives come from its symmetric part.
        let a = a + DMat3::from_cols(DVec3::new(0.0, skew.z, 0.0), DVec3::ZERO, DVec3::new(skew.x, 0.0, 0.0));
        let g = QuadraticFunction { a, b, k };
        let h = 1e-5;
        for axis in 0..3 {
            let e = DVec3::AXES[axis] * h;
            let fd = (g.value(d + e) - g.value(d - e)) / (2.0 * h);
            prop_assert!((fd - g.gradient(d)[axis]).abs() < 1e-8);
            let fd_col = (g.gradient(d + e) - g.gradient(d - e)) / (2.0 * h);
            prop_assert!((fd_col - g.hessian().col(axis)).length() < 1e-8);
        }
        prop_assert_eq!(g.hessian(), g.hessian().transpose());
    }

    #[test]
    fn centred_forms_equal_the_global_functions(
        q in random_symmetric(),
        p in vec3(1.0),
        c0 in -1.0..1.0f64,
        centre in vec3(2.0),
        x in vec3(2.0),
    ) {
        let quad = QuadraticFunction::from_global(q, p, c0, centre);
        let global = x.dot(q * x) + p.dot(x) + c0;
        prop_assert!((quad.value(x - centre) - global).abs() < 1e-12 * (1.0 + global.abs()) * 16.0);
        prop_assert!((quad.gradient(x - centre) - (q * x * 2.0 + p)).length() < 1e-12 * 64.0);
        let lin = LinearFunction::from_global(p, c0, centre);
        prop_assert!((lin.value(x - centre) - (p.dot(x) + c0)).abs() < 1e-13 * 16.0);
        let lifted = QuadraticFunction::from_linear(lin);
        prop_assert_eq!(lifted.value(x - centre), lin.value(x - centre));
        prop_assert_eq!(lifted.gradient(x - centre), lin.gradient());
    }
}

#[test]
fn storage_round_trips() {
    let lin = [
        LinearFunction {
            alpha: DVec3::X,
            beta: 1.0,
        },
        LinearFunction {
            alpha: DVec3::Y,
            beta: -2.0,
        },
    ];
    let funcs = LocalFunctions::from_linear(lin);
    assert_eq!(funcs.len(), 2);
    assert!(funcs.is_linear() && !funcs.is_empty());
    assert_eq!(funcs.get(1), Some(LocalFunction::Linear(lin[1])));
    assert_eq!(funcs.get(2), None);
    let quad = funcs.to_quadratic();
    assert!(!quad.is_linear());
    assert_eq!(
        quad.get(0),
        Some(LocalFunction::Quadratic(QuadraticFunction::from_linear(
            lin[0]
        )))
    );
    assert_eq!(quad.to_quadratic(), quad);
    assert_eq!(
        LocalFunctions::zero_linear(3)
            .get(2)
            .unwrap()
            .value(DVec3::ONE),
        0.0
    );
    assert_eq!(LocalFunction::Linear(lin[0]).hessian(), DMat3::ZERO);
}
