//! Random covers and brute-force oracles shared by the partition-of-unity tests.
#![allow(dead_code)]

use proptest::prelude::*;
use sphcover_core::{
    Cover, DMat3, DVec3, Kernel, LinearFunction, LocalFunctions, QuadraticFunction,
};

/// Expansion factors the tests cover: the plain cover, a mild and the thesis' skeleton one.
pub const SIGMAS: [f64; 3] = [1.0, 1.5, 4.0];

pub fn kernel_strategy() -> impl Strategy<Value = Kernel> {
    prop::sample::select(Kernel::ALL.to_vec())
}

pub fn sigma_strategy() -> impl Strategy<Value = f64> {
    prop::sample::select(SIGMAS.to_vec())
}

pub fn vec3(range: f64) -> impl Strategy<Value = DVec3> {
    (-range..range, -range..range, -range..range).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

pub fn unit_vector() -> impl Strategy<Value = DVec3> {
    vec3(1.0)
        .prop_filter("away from zero", |v| v.length() > 0.1)
        .prop_map(|v| v.normalize())
}

/// Supports clustered in a small box with radii spanning two orders of magnitude
/// (0.01 … 1), so small balls nest in and straddle large ones.
pub fn supports_strategy(max: usize) -> impl Strategy<Value = Vec<(DVec3, f64)>> {
    prop::collection::vec((vec3(0.3), -2.0..0.0f64), 1..max)
        .prop_map(|v| v.into_iter().map(|(c, e)| (c, 10f64.powf(e))).collect())
}

/// Points each drawn inside the expanded ball of a chosen support: `(support selector,
/// direction, fraction of the expanded radius)`.
pub fn inner_points_strategy(
    n: usize,
) -> impl Strategy<Value = Vec<(prop::sample::Index, DVec3, f64)>> {
    prop::collection::vec(
        (any::<prop::sample::Index>(), unit_vector(), 0.0..1.0f64),
        n,
    )
}

pub fn place(
    supports: &[(DVec3, f64)],
    sigma: f64,
    picks: &[(prop::sample::Index, DVec3, f64)],
) -> Vec<DVec3> {
    picks
        .iter()
        .map(|(sel, dir, frac)| {
            let (c, r) = supports[sel.index(supports.len())];
            c + *dir * (frac * sigma * r)
        })
        .collect()
}

pub fn random_symmetric() -> impl Strategy<Value = DMat3> {
    (vec3(1.0), vec3(1.0)).prop_map(|(d, o)| {
        DMat3::from_cols(
            DVec3::new(d.x, o.x, o.y),
            DVec3::new(o.x, d.y, o.z),
            DVec3::new(o.y, o.z, d.z),
        )
    })
}

/// Independent random local functions, one per support.
pub fn random_linear(n: usize) -> impl Strategy<Value = Vec<LinearFunction>> {
    prop::collection::vec((vec3(1.0), -1.0..1.0f64), n).prop_map(|v| {
        v.into_iter()
            .map(|(alpha, beta)| LinearFunction { alpha, beta })
            .collect()
    })
}

pub fn random_quadratic(n: usize) -> impl Strategy<Value = Vec<QuadraticFunction>> {
    prop::collection::vec((random_symmetric(), vec3(1.0), -1.0..1.0f64), n).prop_map(|v| {
        v.into_iter()
            .map(|(a, b, k)| QuadraticFunction { a, b, k })
            .collect()
    })
}

pub fn build(supports: &[(DVec3, f64)], funcs: LocalFunctions, kernel: Kernel) -> Cover {
    let centres = supports.iter().map(|s| s.0).collect();
    let radii = supports.iter().map(|s| s.1).collect();
    Cover::new(centres, radii, funcs, kernel).expect("valid random cover")
}

/// Brute-force sums of the weights at `x` (radius `σ r_i`): `W = Σ w_i`, `Σ ‖∇w_i‖`,
/// `Σ ‖∇²w_i‖_F`. They bound how much rounding in the local functions can be amplified.
#[derive(Clone, Copy, Debug)]
pub struct WeightStats {
    pub w: f64,
    pub grad_sum: f64,
    pub hess_sum: f64,
    pub count: usize,
}

pub fn weight_stats(cover: &Cover, sigma: f64, x: DVec3) -> WeightStats {
    let mut s = WeightStats {
        w: 0.0,
        grad_sum: 0.0,
        hess_sum: 0.0,
        count: 0,
    };
    for (c, r) in cover.centres().iter().zip(cover.radii()) {
        let (w, g, h) = cover.kernel().weight_gradient_hessian(x, *c, sigma * r);
        if w > 0.0 {
            s.w += w;
            s.grad_sum += g.length();
            s.hess_sum += frobenius(h);
            s.count += 1;
        }
    }
    s
}

/// Brute-force partition of unity from the public kernel and local-function API.
pub fn oracle_value(cover: &Cover, sigma: f64, x: DVec3) -> Option<f64> {
    let mut w_sum = 0.0;
    let mut n_sum = 0.0;
    for i in 0..cover.len() {
        let c = cover.centres()[i];
        let w = cover.kernel().weight(x, c, sigma * cover.radii()[i]);
        if w > 0.0 {
            w_sum += w;
            n_sum += w * cover.func(i).unwrap().value(x - c);
        }
    }
    (w_sum > 0.0).then(|| n_sum / w_sum)
}

/// Distance from `x` to the nearest sphere on which the cover's weights are not smooth
/// (kernel kinks and the support boundaries, at radius `σ r_i`).
pub fn distance_to_nonsmooth(cover: &Cover, sigma: f64, x: DVec3) -> f64 {
    let mut best = f64::INFINITY;
    for (c, r) in cover.centres().iter().zip(cover.radii()) {
        let dist = x.distance(*c);
        for &k in cover.kernel().nonsmooth_radii().iter().chain([1.0].iter()) {
            best = best.min((dist - k * sigma * r).abs());
        }
    }
    best
}

pub fn frobenius(m: DMat3) -> f64 {
    (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared()).sqrt()
}

pub const EPS: f64 = f64::EPSILON;
