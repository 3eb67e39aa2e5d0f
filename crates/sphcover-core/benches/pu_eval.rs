//! Partition-of-unity evaluation on a surface-like cover: 200K supports around a sphere with
//! radii varying by a factor 8, linear local functions from the sphere's signed distance,
//! `f` and `∇f` at 1M points near the surface (in parallel), plus single-point queries.

use criterion::{Criterion, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use sphcover_core::{Cover, DVec3, Kernel, LinearFunction, LocalFunctions, PuEvaluator};
use std::hint::black_box;

const SUPPORTS: usize = 200_000;
const POINTS: usize = 1_000_000;
/// Sphere radius in the unit box.
const SPHERE: f64 = 0.4;
/// Smallest support radius; the largest is 8 times this. Chosen so that about 30 supports
/// overlap at a point near the surface (`density · 4/3 π r³` is constant along the sphere).
const R_MIN: f64 = 5.8e-3;

/// Support radius along direction `n`: fine at the north pole, 8× coarser at the south pole,
/// like an adaptive cover refined on one side.
fn radius_along(n: DVec3) -> f64 {
    R_MIN * 8f64.powf(0.5 * (1.0 - n.z))
}

fn random_direction(rng: &mut impl Rng) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let l = v.length_squared();
        if l > 1e-6 && l <= 1.0 {
            return v / l.sqrt();
        }
    }
}

/// Supports in a shell of half-width `r(n)` around the sphere, with density `∝ 1/r³` (rejection
/// with acceptance `(r_min/r)²`, the shell width supplying the remaining `1/r`), each carrying
/// the tangent plane of the signed distance `R − ‖x‖` (positive inside).
fn sphere_cover(rng: &mut impl Rng) -> Cover {
    let mut centres = Vec::with_capacity(SUPPORTS);
    let mut radii = Vec::with_capacity(SUPPORTS);
    while centres.len() < SUPPORTS {
        let n = random_direction(rng);
        let r = radius_along(n);
        if rng.random::<f64>() >= (R_MIN / r).powi(2) {
            continue;
        }
        let offset = rng.random_range(-1.0..1.0) * r;
        centres.push(n * (SPHERE + offset));
        radii.push(r);
    }
    let funcs = LocalFunctions::from_linear(centres.iter().map(|&c| LinearFunction {
        alpha: -c.normalize(),
        beta: SPHERE - c.length(),
    }));
    Cover::new(centres, radii, funcs, Kernel::QuadraticBSpline).expect("valid cover")
}

fn near_surface_points(rng: &mut impl Rng, count: usize) -> Vec<DVec3> {
    (0..count)
        .map(|_| {
            let n = random_direction(rng);
            n * (SPHERE + rng.random_range(-0.5..0.5) * radius_along(n))
        })
        .collect()
}

fn bench_pu_eval(c: &mut Criterion) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(2010);
    let cover = sphere_cover(&mut rng);
    let points = near_surface_points(&mut rng, POINTS);
    let eval = PuEvaluator::new(&cover, 1.0).expect("valid expansion");

    let mut ids = Vec::new();
    let (mut covered, mut overlap) = (0usize, 0usize);
    for &x in points.iter().step_by(1000) {
        eval.supports_containing(x, &mut ids);
        covered += usize::from(!ids.is_empty());
        overlap += ids.len();
    }
    eprintln!(
        "pu_eval: {} supports, {} points; sampled: {covered}/{} covered, mean overlap {:.1}",
        cover.len(),
        points.len(),
        points.len() / 1000,
        overlap as f64 / covered.max(1) as f64
    );

    let mut group = c.benchmark_group("pu_eval");
    group.sample_size(10);
    group.bench_function("value_gradient_1M_points_200K_supports", |b| {
        b.iter(|| black_box(eval.values_gradients(black_box(&points))))
    });
    group.bench_function("value_gradient_single_point", |b| {
        let mut k = 0;
        b.iter(|| {
            k = (k + 7919) % points.len();
            black_box(eval.value_gradient(black_box(points[k])))
        })
    });
    group.bench_function("value_gradient_hessian_single_point", |b| {
        let mut k = 0;
        b.iter(|| {
            k = (k + 7919) % points.len();
            black_box(eval.value_gradient_hessian(black_box(points[k])))
        })
    });
    group.bench_function("supports_containing_single_point", |b| {
        let mut k = 0;
        let mut v = Vec::new();
        b.iter(|| {
            k = (k + 7919) % points.len();
            eval.supports_containing(black_box(points[k]), &mut v);
            black_box(v.len())
        })
    });
    group.finish();
}

criterion_group!(benches, bench_pu_eval);
criterion_main!(benches);
