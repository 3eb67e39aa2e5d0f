//! The evaluator against brute-force oracles: domain (None outside every ball), support
//! queries, determinism across batch/single calls and thread counts; cover validation.

mod pu_common;

use proptest::prelude::*;
use pu_common::*;
use sphcover_core::{
    Cover, CoverError, DMat3, DVec3, Kernel, LengthMismatch, LinearFunction, LocalFunctions,
    PuEvaluator, QuadraticFunction, SupportLists,
};

fn brute_force_containing(cover: &Cover, sigma: f64, x: DVec3) -> Vec<u32> {
    (0..cover.len() as u32)
        .filter(|&i| x.distance(cover.centres()[i as usize]) < sigma * cover.radii()[i as usize])
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn matches_brute_force_and_is_undefined_outside(
        (supports, funcs) in supports_strategy(30)
            .prop_flat_map(|s| { let n = s.len(); (Just(s), random_quadratic(n)) }),
        kernel in kernel_strategy(),
        sigma in sigma_strategy(),
        inner in inner_points_strategy(6),
        free in prop::collection::vec(vec3(3.0), 6),
    ) {
        let cover = build(&supports, LocalFunctions::from_quadratic(funcs), kernel);
        let eval = PuEvaluator::new(&cover, sigma).unwrap();
        let mut ids = Vec::new();
        let mut weights = Vec::new();
        for x in place(&supports, sigma, &inner).into_iter().chain(free) {
            eval.supports_containing(x, &mut ids);
            prop_assert_eq!(&ids, &brute_force_containing(&cover, sigma, x));
            eval.weights(x, &mut weights);
            prop_assert!(weights.iter().map(|w| w.0).eq(ids.iter().copied()));
            let oracle = oracle_value(&cover, sigma, x);
            let value = eval.value(x);
            let vg = eval.value_gradient(x);
            let vgh = eval.value_gradient_hessian(x);
            if ids.is_empty() {
                prop_assert_eq!(value, None);
                prop_assert_eq!(vg, None);
                prop_assert_eq!(vgh, None);
                prop_assert_eq!(oracle, None);
            } else {
                let (o, v) = (oracle.unwrap(), value.unwrap());
                prop_assert!((o - v).abs() <= 1e-12 * (1.0 + o.abs()), "{v} vs oracle {o}");
                prop_assert_eq!(vg.unwrap().value.to_bits(), v.to_bits());
                prop_assert_eq!(vgh.unwrap().value.to_bits(), v.to_bits());
                prop_assert_eq!(vgh.unwrap().gradient, vg.unwrap().gradient);
            }
        }
    }
}

/// The supports whose sums count at `x`: `‖(x − c_i) / (σ r_i)‖² < 1` computed as the
/// evaluator computes it, every support tested.
fn brute_force_summed(cover: &Cover, sigma: f64, x: DVec3) -> Vec<u32> {
    (0..cover.len() as u32)
        .filter(|&i| {
            let inv_r = 1.0 / (sigma * cover.radii()[i as usize]);
            ((x - cover.centres()[i as usize]) * inv_r).length_squared() < 1.0
        })
        .collect()
}

/// Every list of `lists` against the brute-force oracle at `points`.
fn check_lists(lists: &SupportLists, cover: &Cover, sigma: f64, points: &[DVec3]) {
    assert_eq!(lists.len(), points.len());
    for (i, &x) in points.iter().enumerate() {
        let expected = if x.is_finite() {
            brute_force_summed(cover, sigma, x)
        } else {
            Vec::new()
        };
        assert_eq!(lists.supports(i), &expected[..], "point {i} at {x}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Support lists hold exactly the supports the sums count, and evaluate any local
    /// functions on the same balls as a new evaluator does, bitwise.
    #[test]
    fn support_lists_match_brute_force_and_the_evaluator(
        (supports, funcs) in supports_strategy(30)
            .prop_flat_map(|s| { let n = s.len(); (Just(s), random_quadratic(n)) }),
        linear in random_linear(30),
        kernel in kernel_strategy(),
        sigma in sigma_strategy(),
        inner in inner_points_strategy(6),
        free in prop::collection::vec(vec3(3.0), 6),
    ) {
        let cover = build(&supports, LocalFunctions::from_quadratic(funcs), kernel);
        let mut points = place(&supports, sigma, &inner);
        points.extend(free);
        points.push(DVec3::new(f64::NAN, 0.0, 0.0));
        let lists = PuEvaluator::new(&cover, sigma).unwrap().support_lists(&points);
        check_lists(&lists, &cover, sigma, &points);
        let mut relinear = cover.clone();
        relinear
            .set_funcs(LocalFunctions::from_linear(linear[..cover.len()].iter().copied()))
            .unwrap();
        for other in [&cover, &relinear] {
            let eval = PuEvaluator::new(other, sigma).unwrap();
            prop_assert_eq!(lists.values(other, &points).unwrap(), eval.values(&points));
            prop_assert_eq!(
                lists.values_gradients(other, &points).unwrap(),
                eval.values_gradients(&points)
            );
        }
    }
}

/// Batches long enough to run in Morton order (and short ones, one query per point): the
/// lists do not depend on the thread count and serve new local functions on the same balls.
#[test]
fn support_lists_serve_new_functions_for_any_thread_count() {
    for (kernel, spread) in Kernel::ALL.into_iter().flat_map(|k| [(k, 0.2), (k, 3.0)]) {
        let (cover, mut points) = sample_cover(kernel, spread);
        points[17] = DVec3::new(0.5, f64::INFINITY, 0.5);
        let sigma = 1.5;
        let eval = PuEvaluator::new(&cover, sigma).unwrap();
        let lists_at = |threads: usize, points: &[DVec3]| {
            sphcover_core::on_threads(threads, || eval.support_lists(points))
        };
        let lists = lists_at(1, &points);
        let three = lists_at(3, &points);
        check_lists(&lists, &cover, sigma, &points);
        for i in 0..points.len() {
            assert_eq!(lists.supports(i), three.supports(i));
        }
        let few = lists_at(2, &points[..100]);
        check_lists(&few, &cover, sigma, &points[..100]);

        let mut changed = cover.clone();
        changed
            .set_funcs(LocalFunctions::from_linear((0..cover.len()).map(|i| {
                LinearFunction {
                    alpha: DVec3::new((i as f64).sin(), 1.0, -0.5),
                    beta: (i as f64 * 0.1).cos(),
                }
            })))
            .unwrap();
        let new_eval = PuEvaluator::new(&changed, sigma).unwrap();
        let values = lists.values(&changed, &points).unwrap();
        assert!(values.iter().any(Option::is_none) && values.iter().any(Option::is_some));
        assert_eq!(
            values,
            new_eval.values(&points),
            "{kernel}, spread {spread}"
        );
        assert_eq!(
            lists.values_gradients(&changed, &points).unwrap(),
            new_eval.values_gradients(&points)
        );
        assert_eq!(
            few.values_gradients(&changed, &points[..100]).unwrap(),
            new_eval.values_gradients(&points[..100])
        );
    }
}

#[test]
fn support_lists_refuse_other_balls() {
    let (cover, points) = sample_cover(Kernel::default(), 0.2);
    let lists = PuEvaluator::new(&cover, 1.0)
        .unwrap()
        .support_lists(&points);
    let cover_again = cover.clone();
    let (mut centres, mut radii, funcs, kernel) = cover.into_parts();
    radii[123] *= 1.0 + f64::EPSILON;
    let moved = Cover::new(centres.clone(), radii.clone(), funcs.clone(), kernel).unwrap();
    assert_eq!(
        lists.values(&moved, &points),
        Err(CoverError::OtherBalls { index: 123 })
    );
    let mut shifted = points.clone();
    shifted[77].y = -shifted[77].y;
    assert_eq!(
        lists.values(&cover_again, &shifted),
        Err(CoverError::OtherPoints { index: 77 })
    );
    assert!(matches!(
        lists.values(&cover_again, &points[1..]),
        Err(CoverError::LengthMismatch(_))
    ));
    assert!(lists.values(&cover_again, &points).is_ok());
    centres.pop();
    radii.pop();
    let fewer = Cover::new(
        centres,
        radii,
        LocalFunctions::zero_linear(funcs.len() - 1),
        kernel,
    )
    .unwrap();
    assert!(matches!(
        lists.values_gradients(&fewer, &points),
        Err(CoverError::LengthMismatch(_))
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Only the symmetric part of `A` enters `g`, so a non-symmetric `A` must give the same
    /// `f`, `∇f`, `∇²f` as `(A + Aᵀ)/2`.
    #[test]
    fn quadratic_uses_the_symmetric_part_of_a(
        supports in supports_strategy(20),
        kernel in kernel_strategy(),
        sigma in sigma_strategy(),
        skew in vec3(1.0),
        sym in random_symmetric(),
        picks in inner_points_strategy(6),
    ) {
        let skew_mat = DMat3::from_cols(
            DVec3::new(0.0, skew.z, -skew.y),
            DVec3::new(-skew.z, 0.0, skew.x),
            DVec3::new(skew.y, -skew.x, 0.0),
        );
        let make = |a: DMat3| {
            let funcs = LocalFunctions::from_quadratic(supports.iter().map(|&(c, _)| {
                QuadraticFunction { a, b: c, k: c.x }
            }));
            build(&supports, funcs, kernel)
        };
        let plain = make(sym);
        let skewed = make(sym + skew_mat);
        let (e1, e2) = (
            PuEvaluator::new(&plain, sigma).unwrap(),
            PuEvaluator::new(&skewed, sigma).unwrap(),
        );
        for x in place(&supports, sigma, &picks) {
            let (Some(a), Some(b)) = (e1.value_gradient_hessian(x), e2.value_gradient_hessian(x))
            else {
                continue;
            };
            let stats = weight_stats(&plain, sigma, x);
            let gw = stats.grad_sum / stats.w;
            let tol = 1e-12 * (1.0 + gw + gw * gw + stats.hess_sum / stats.w);
            prop_assert!((a.value - b.value).abs() <= tol);
            prop_assert!((a.gradient - b.gradient).length() <= tol);
            prop_assert!(frobenius(a.hessian - b.hessian) <= tol);
        }
    }
}

/// A fixed random cover big enough that rayon splits the batch, with points spread over its
/// box enlarged by `spread` on every side (about 5000 over the box with `spread` 0).
fn sample_cover(kernel: Kernel, spread: f64) -> (Cover, Vec<DVec3>) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let n = 400;
    let centres: Vec<DVec3> = (0..n)
        .map(|_| DVec3::new(rng.random(), rng.random(), rng.random()))
        .collect();
    let radii: Vec<f64> = (0..n).map(|_| 0.05 + 0.2 * rng.random::<f64>()).collect();
    let funcs = LocalFunctions::from_quadratic((0..n).map(|_| QuadraticFunction {
        a: DMat3::from_diagonal(DVec3::new(rng.random(), rng.random(), rng.random())),
        b: DVec3::new(rng.random(), rng.random(), rng.random()),
        k: rng.random(),
    }));
    let cover = Cover::new(centres, radii, funcs, kernel).unwrap();
    let side = 1.0 + 2.0 * spread;
    let points = (0..5000)
        .map(|_| DVec3::new(rng.random(), rng.random(), rng.random()) * side - spread)
        .collect();
    (cover, points)
}

/// Spread 0.2: blocks of up to 256 points in runs of 16, each within the span of a few
/// radii. Spread 3: points a few radii apart, so most blocks close early
/// (`BLOCK_SPAN_PER_RADIUS`).
#[test]
fn batch_equals_single_and_is_independent_of_thread_count() {
    for (kernel, spread) in Kernel::ALL.into_iter().flat_map(|k| [(k, 0.2), (k, 3.0)]) {
        let (cover, points) = sample_cover(kernel, spread);
        let eval = PuEvaluator::new(&cover, 1.5).unwrap();
        let run = |threads: usize| {
            sphcover_core::on_threads(threads, || {
                (
                    eval.values(&points),
                    eval.values_gradients(&points),
                    eval.values_gradients_hessians(&points),
                )
            })
        };
        let one = run(1);
        let three = run(3);
        assert_eq!(one, three, "{kernel}, spread {spread}");
        let (values, vgs, vghs) = one;
        assert!(values.iter().any(Option::is_none) && values.iter().any(Option::is_some));
        for (i, &x) in points.iter().enumerate() {
            assert_eq!(values[i], eval.value(x));
            assert_eq!(vgs[i], eval.value_gradient(x));
            assert_eq!(vghs[i], eval.value_gradient_hessian(x));
        }
    }
}

#[test]
fn expansion_enlarges_the_domain_but_keeps_local_functions() {
    let c = DVec3::ZERO;
    let g = LinearFunction {
        alpha: DVec3::new(1.0, 2.0, 3.0),
        beta: -0.5,
    };
    let cover = Cover::new(
        vec![c],
        vec![1.0],
        LocalFunctions::from_linear([g]),
        Kernel::WendlandC2,
    )
    .unwrap();
    let x = DVec3::new(0.0, 2.5, 0.0);
    assert_eq!(PuEvaluator::new(&cover, 1.0).unwrap().value(x), None);
    let four = PuEvaluator::new(&cover, 4.0).unwrap();
    let fg = four.value_gradient(x).unwrap();
    assert!((fg.value - g.value(x - c)).abs() < 1e-14);
    assert!((fg.gradient - g.alpha).length() < 1e-13);
    assert_eq!(four.sigma(), 4.0);
}

#[test]
fn empty_cover_is_undefined_everywhere() {
    let cover = Cover::new(
        vec![],
        vec![],
        LocalFunctions::zero_linear(0),
        Kernel::default(),
    )
    .unwrap();
    assert!(cover.is_empty());
    let eval = PuEvaluator::new(&cover, 1.0).unwrap();
    assert_eq!(eval.value(DVec3::ZERO), None);
    assert_eq!(
        eval.values_gradients(&[DVec3::ZERO, DVec3::ONE]),
        vec![None, None]
    );
}

#[test]
fn invalid_input_is_reported_with_its_index() {
    let ok_funcs = || LocalFunctions::zero_linear(2);
    let c = vec![DVec3::ZERO, DVec3::ONE];
    let k = Kernel::default();
    assert_eq!(
        Cover::new(c.clone(), vec![1.0], ok_funcs(), k),
        Err(CoverError::LengthMismatch(LengthMismatch {
            array: "radii",
            expected: 2,
            found: 1
        }))
    );
    assert_eq!(
        Cover::new(c.clone(), vec![1.0, 1.0], LocalFunctions::zero_linear(3), k),
        Err(CoverError::LengthMismatch(LengthMismatch {
            array: "alpha",
            expected: 2,
            found: 3
        }))
    );
    let short_k = LocalFunctions::Quadratic {
        a: vec![DMat3::ZERO; 2],
        b: vec![DVec3::ZERO; 2],
        k: vec![0.0],
    };
    assert_eq!(
        Cover::new(c.clone(), vec![1.0, 1.0], short_k, k),
        Err(CoverError::LengthMismatch(LengthMismatch {
            array: "k",
            expected: 2,
            found: 1
        }))
    );
    let bad_centre = vec![DVec3::ZERO, DVec3::new(0.0, f64::NAN, 0.0)];
    assert!(matches!(
        Cover::new(bad_centre, vec![1.0, 1.0], ok_funcs(), k),
        Err(CoverError::NonFiniteCentre { index: 1, .. })
    ));
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-320] {
        assert!(
            matches!(
                Cover::new(c.clone(), vec![1.0, bad], ok_funcs(), k),
                Err(CoverError::InvalidRadius { index: 1, .. })
            ),
            "radius {bad}"
        );
    }
    let nan_func = LocalFunctions::from_linear([
        LinearFunction::default(),
        LinearFunction {
            alpha: DVec3::new(0.0, 0.0, f64::INFINITY),
            beta: 0.0,
        },
    ]);
    assert_eq!(
        Cover::new(c.clone(), vec![1.0, 1.0], nan_func.clone(), k),
        Err(CoverError::NonFiniteFunction { index: 1 })
    );
    let mut cover = Cover::new(c, vec![1.0, 1e300], ok_funcs(), k).unwrap();
    assert_eq!(
        cover.set_funcs(nan_func),
        Err(CoverError::NonFiniteFunction { index: 1 })
    );
    assert_eq!(cover.funcs(), &ok_funcs());
    for sigma in [0.5, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            PuEvaluator::new(&cover, sigma),
            Err(CoverError::InvalidExpansion { .. })
        ));
    }
    assert!(matches!(
        PuEvaluator::new(&cover, 1e10),
        Err(CoverError::ExpandedRadiusOverflow { index: 1, .. })
    ));
}

/// [`sample_cover`] with 200 more points on the spheres of radius 1.5 r around the first
/// supports, where the support set at σ = 1.5 is decided by rounding.
fn sample_cover_with_sphere_points(kernel: Kernel) -> (Cover, Vec<DVec3>) {
    let (cover, mut points) = sample_cover(kernel, 0.2);
    for i in 0..200 {
        let c = cover.centres()[i];
        let r = 1.5 * cover.radii()[i];
        points.push(c + DVec3::new(0.6, -0.48, 0.64) * r);
    }
    (cover, points)
}

#[test]
fn blend_equals_the_weighted_mean_of_weights_for_any_thread_count() {
    for kernel in Kernel::ALL {
        let (cover, points) = sample_cover_with_sphere_points(kernel);
        let values: Vec<f64> = (0..cover.len()).map(|i| (i as f64 * 0.37).sin()).collect();
        let eval = PuEvaluator::new(&cover, 1.5).unwrap();
        let run = |threads: usize| {
            sphcover_core::on_threads(threads, || eval.blend(&points, &values).unwrap())
        };
        let one = run(1);
        assert_eq!(one, run(3), "{kernel}");
        assert!(one.iter().any(Option::is_none) && one.iter().any(Option::is_some));
        let mut weights = Vec::new();
        for (x, blended) in points.iter().zip(&one) {
            eval.weights(*x, &mut weights);
            let (num, den) = weights.iter().fold((0.0, 0.0), |(n, d), &(i, w)| {
                (n + w * values[i as usize], d + w)
            });
            assert_eq!(*blended, (den > 0.0).then(|| num / den), "{kernel} at {x}");
            assert_eq!(blended.is_some(), eval.value(*x).is_some());
        }
        // The same points one by one (below the batch threshold) agree too.
        let few = eval.blend(&points[..100], &values).unwrap();
        assert_eq!(few, one[..100]);
    }
    let (cover, points) = sample_cover(Kernel::default(), 0.2);
    let eval = PuEvaluator::new(&cover, 1.0).unwrap();
    assert_eq!(
        eval.blend(&points, &[1.0]),
        Err(CoverError::LengthMismatch(LengthMismatch {
            array: "blended values",
            expected: cover.len(),
            found: 1
        }))
    );
}

#[test]
fn fused_gradient_and_blend_equal_the_separate_queries() {
    for kernel in Kernel::ALL {
        let (cover, points) = sample_cover_with_sphere_points(kernel);
        let values: Vec<f64> = (0..cover.len()).map(|i| (i as f64 * 0.37).cos()).collect();
        let eval = PuEvaluator::new(&cover, 1.5).unwrap();
        let run = |threads: usize| {
            sphcover_core::on_threads(threads, || {
                eval.values_gradients_blends(&points, &values).unwrap()
            })
        };
        let fused = run(1);
        assert_eq!(fused, run(3), "{kernel}");
        let gradients = eval.values_gradients(&points);
        let blends = eval.blend(&points, &values).unwrap();
        assert!(fused.iter().any(Option::is_none) && fused.iter().any(Option::is_some));
        for ((f, g), b) in fused.iter().zip(&gradients).zip(&blends) {
            assert_eq!(f.map(|(vg, _)| vg), *g, "{kernel}");
            assert_eq!(f.map(|(_, b)| b), *b, "{kernel}");
        }
        // Below the batch threshold (one query per point) too.
        let few = eval
            .values_gradients_blends(&points[..100], &values)
            .unwrap();
        assert_eq!(few, fused[..100]);
    }
    let (cover, points) = sample_cover(Kernel::default(), 0.2);
    let eval = PuEvaluator::new(&cover, 1.0).unwrap();
    assert!(matches!(
        eval.values_gradients_blends(&points, &[1.0]),
        Err(CoverError::LengthMismatch(LengthMismatch { found: 1, .. }))
    ));
}
