//! The surface cover of exactly sampled shapes (thesis §3.4.1): `f` approximates the signed
//! distance near the surface, has the right sign away from it, and stays within 2ε on every
//! sample; the same seed gives a bit-identical cover on 1 and 2 threads.

use proptest::prelude::*;
use sphcover_core::synthetic::{Surface, fibonacci_sphere};
use sphcover_core::{
    Cover, DVec3, Kernel, PointCloud, PointIndex, PuEvaluator, SupportSamples, SurfaceCoverParams,
    SurfaceSamples, build_surface_cover, build_surface_cover_from_cloud,
    build_surface_cover_with_samples,
};

const SPHERE_R: f64 = 0.5;
const MAJOR: f64 = 0.36;
const MINOR: f64 = 0.12;

/// Points on the sphere of radius `SPHERE_R` (the unit frame's sphere) with outward normals.
fn sphere(n: usize) -> (Vec<DVec3>, Vec<DVec3>) {
    let normals = fibonacci_sphere(n);
    (normals.iter().map(|&u| SPHERE_R * u).collect(), normals)
}

/// Signed distance to the sphere, positive inside (the cover's sign convention).
fn sphere_distance(x: DVec3) -> f64 {
    -Surface::Sphere {
        centre: DVec3::ZERO,
        radius: SPHERE_R,
    }
    .signed_distance(x)
}

/// Points on a torus around the z axis, on a lattice uniform by area (the tube angle follows
/// the inverse of its area distribution), with outward normals.
fn torus(n_u: usize, n_v: usize) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for j in 0..n_v {
        // Solve v + (r/R) sin v = 2π s for the tube angle v (Newton), s uniform.
        let target = std::f64::consts::TAU * (j as f64 + 0.5) / n_v as f64;
        let mut v = target;
        for _ in 0..30 {
            v -= (v + MINOR / MAJOR * v.sin() - target) / (1.0 + MINOR / MAJOR * v.cos());
        }
        let ring = MAJOR + MINOR * v.cos();
        let count = ((n_u as f64) * ring / MAJOR).round().max(3.0) as usize;
        for i in 0..count {
            let u = std::f64::consts::TAU * (i as f64 + 0.5 * (j % 2) as f64) / count as f64;
            let normal = DVec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
            points.push(DVec3::new(u.cos(), u.sin(), 0.0) * MAJOR + MINOR * normal);
            normals.push(normal);
        }
    }
    (points, normals)
}

/// Signed distance to the torus, positive inside (the cover's sign convention).
fn torus_distance(x: DVec3) -> f64 {
    -Surface::Torus {
        centre: DVec3::ZERO,
        major_radius: MAJOR,
        minor_radius: MINOR,
    }
    .signed_distance(x)
}

/// A deterministic point sequence filling the cube of side `side` around the origin.
fn box_points(n: usize, side: f64) -> impl Iterator<Item = DVec3> {
    (0..n).map(move |i| {
        let t = i as f64 + 0.5;
        (DVec3::new(
            (t * 0.618_033_988_749_895).fract(),
            (t * 0.754_877_666_246_693).fract(),
            (t * 0.569_840_290_998_053).fract(),
        ) - 0.5)
            * side
    })
}

/// Checks `f` against the signed distance `d`: `|f − d| ≤ band_tol` where `|d| < band`,
/// the sign of `d` where `|d| ≥ band`, and `|f| ≤ 2ε` on the samples.
fn check_shape(
    cover: &Cover,
    samples: &[DVec3],
    distance: impl Fn(DVec3) -> f64,
    eps: f64,
    band: f64,
    band_tol: f64,
) {
    let f = PuEvaluator::new(cover, 1.0).unwrap();
    let worst_sample = samples
        .iter()
        .step_by(7)
        .map(|&p| f.value(p).expect("samples are covered").abs())
        .fold(0.0, f64::max);
    assert!(
        worst_sample <= 2.0 * eps,
        "max |f| on samples {worst_sample:e} > 2ε"
    );
    let mut band_points = 0;
    let mut worst_band: f64 = 0.0;
    let mut wrong_sign = Vec::new();
    // Everything inside the unit cube must be covered.
    for x in box_points(4000, 1.0) {
        let fx = f.value(x).expect("the cover spans the unit cube");
        let d = distance(x);
        if d.abs() < band {
            band_points += 1;
            worst_band = worst_band.max((fx - d).abs());
        } else if fx.signum() != d.signum() {
            wrong_sign.push((x, d, fx));
        }
    }
    assert!(band_points > 50, "too few points in the band");
    assert!(
        worst_band <= band_tol,
        "|f − d| = {worst_band:e} in the band (tolerance {band_tol:e})"
    );
    assert!(
        wrong_sign.is_empty(),
        "{} points with the wrong sign, e.g. {:?}",
        wrong_sign.len(),
        &wrong_sign[..wrong_sign.len().min(5)]
    );
}

#[test]
fn sphere_cover_approximates_the_signed_distance() {
    let (points, normals) = sphere(20_000);
    let params = SurfaceCoverParams::default();
    let (cover, stats) =
        build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).unwrap();
    assert_eq!(stats.used_points, points.len());
    assert!(stats.supports_after_expansion < stats.supports_before_expansion);
    assert_eq!(stats.supports_over_eps, 0);
    assert!(stats.max_error <= params.eps);
    // Inside a band of 0.02 around the surface, f follows the distance closely.
    check_shape(
        &cover,
        &points,
        sphere_distance,
        params.eps,
        0.02,
        4.0 * params.eps,
    );
}

#[test]
fn torus_cover_approximates_the_signed_distance() {
    let (points, normals) = torus(300, 100);
    let params = SurfaceCoverParams {
        eps: 2e-3,
        ..SurfaceCoverParams::default()
    };
    let (cover, stats) =
        build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).unwrap();
    assert!(stats.supports_after_expansion > 100);
    check_shape(
        &cover,
        &points,
        torus_distance,
        params.eps,
        0.02,
        4.0 * params.eps,
    );
}

#[test]
fn same_seed_gives_the_same_cover_on_one_and_two_threads() {
    let (points, normals) = torus(150, 50);
    let params = SurfaceCoverParams {
        eps: 4e-3,
        seed: 7,
        ..SurfaceCoverParams::default()
    };
    let build = |threads| {
        sphcover_core::on_threads(threads, || {
            build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).unwrap()
        })
    };
    let (one, stats_one) = build(1);
    let (two, stats_two) = build(2);
    let bits = |c: &Cover| -> Vec<u64> {
        let (centres, radii, funcs, _) = c.clone().into_parts();
        let mut v: Vec<u64> = centres
            .iter()
            .flat_map(|p| p.to_array())
            .map(f64::to_bits)
            .collect();
        v.extend(radii.iter().map(|r| r.to_bits()));
        for i in 0..funcs.len() {
            let g = funcs.get(i).unwrap();
            v.push(g.value(DVec3::ZERO).to_bits());
            v.extend(g.gradient(DVec3::ZERO).to_array().map(f64::to_bits));
        }
        v
    };
    assert_eq!(bits(&one), bits(&two));
    assert_eq!(
        stats_one.supports_before_expansion,
        stats_two.supports_before_expansion
    );
    // Another seed visits the supports in another order: a different cover, same quality.
    let other = build_surface_cover(
        &SurfaceSamples::new(&points, &normals),
        &SurfaceCoverParams {
            seed: 8,
            ..params.clone()
        },
    )
    .unwrap()
    .0;
    assert_ne!(bits(&one), bits(&other));
}

#[test]
fn cloud_convenience_normalises_and_returns_the_map() {
    // A sphere of radius 3 around (10, −2, 5): the unit frame maps it to radius 0.5.
    let (points, normals) = sphere(5_000);
    let centre = DVec3::new(10.0, -2.0, 5.0);
    let cloud = PointCloud {
        positions: points.iter().map(|&p| centre + 6.0 * p).collect(),
        normals: Some(normals),
        ..PointCloud::default()
    };
    let params = SurfaceCoverParams {
        eps: 5e-3,
        ..SurfaceCoverParams::default()
    };
    let (cover, norm, _) = build_surface_cover_from_cloud(&cloud, &params).unwrap();
    // The lattice misses the exact extremes by a little.
    assert!((norm.scale - 6.0).abs() < 1e-2, "{norm:?}");
    assert!((norm.centre - centre).length() < 1e-2, "{norm:?}");
    let f = PuEvaluator::new(&cover, 1.0).unwrap();
    for &p in cloud.positions.iter().step_by(50) {
        assert!(f.value(norm.to_unit(p)).unwrap().abs() <= 2.0 * params.eps);
    }
    assert!(f.value(norm.to_unit(centre)).unwrap() > 0.0);
}

#[test]
fn without_expansion_the_cover_is_the_octree() {
    let (points, normals) = sphere(5_000);
    let params = SurfaceCoverParams {
        eps: 5e-3,
        expansion: false,
        ..SurfaceCoverParams::default()
    };
    let (cover, stats) =
        build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).unwrap();
    assert_eq!(cover.len(), stats.supports_before_expansion);
    assert_eq!(
        stats.supports_after_expansion,
        stats.supports_before_expansion
    );
    assert_eq!(
        stats.leaves_per_level.iter().sum::<usize>(),
        stats.supports_before_expansion
    );
    assert_eq!(stats.grown_supports, 0);
}

/// `n` points of a Fibonacci lattice on the sphere of radius 0.45, with outward normals.
fn fibonacci_sphere_of(n: usize) -> (Vec<DVec3>, Vec<DVec3>) {
    let normals = fibonacci_sphere(n);
    (normals.iter().map(|&u| 0.45 * u).collect(), normals)
}

#[test]
fn sampling_stop_keeps_a_sparse_scan_below_its_point_count_and_reports_the_error() {
    let (points, normals) = fibonacci_sphere_of(2000);
    let base = SurfaceCoverParams {
        eps: 2.5e-3,
        ..SurfaceCoverParams::default()
    };
    let (plain, plain_stats) =
        build_surface_cover(&SurfaceSamples::new(&points, &normals), &base).unwrap();
    let stop = SurfaceCoverParams {
        sampling_stop: true,
        ..base.clone()
    };
    let (cover, stats) =
        build_surface_cover(&SurfaceSamples::new(&points, &normals), &stop).unwrap();
    // ε is below what 2,000 points support: without the rule the cover outnumbers them.
    assert!(plain.len() > points.len(), "{} supports", plain.len());
    assert!(cover.len() < points.len(), "{} supports", cover.len());
    assert!(stats.sampling_limited_octants > 0);
    assert_eq!(plain_stats.sampling_limited_octants, 0);
    // The error of the unrefined octants is reported: recount it from the cover.
    let over = (0..cover.len())
        .filter(|&i| {
            let (c, r) = (cover.centres()[i], cover.radii()[i]);
            let g = cover.func(i).unwrap();
            points
                .iter()
                .any(|p| p.distance(c) < r && g.value(*p - c).abs() > stop.eps * (1.0 + 1e-9))
        })
        .count();
    assert_eq!(over, stats.supports_over_eps);
    assert!(stats.supports_over_eps > 0);
    // Every sample still lies inside a support.
    for p in &points {
        assert!(
            cover
                .centres()
                .iter()
                .zip(cover.radii())
                .any(|(c, &r)| p.distance(*c) < r)
        );
    }
}

#[test]
fn sampling_stop_changes_nothing_where_the_sampling_supports_eps() {
    let (points, normals) = fibonacci_sphere_of(2000);
    let base = SurfaceCoverParams {
        eps: 1e-2,
        ..SurfaceCoverParams::default()
    };
    let stop = SurfaceCoverParams {
        sampling_stop: true,
        ..base.clone()
    };
    let (plain, _) = build_surface_cover(&SurfaceSamples::new(&points, &normals), &base).unwrap();
    let (cover, stats) =
        build_surface_cover(&SurfaceSamples::new(&points, &normals), &stop).unwrap();
    assert_eq!(stats.sampling_limited_octants, 0);
    assert_eq!(stats.supports_over_eps, 0);
    assert_eq!(plain, cover);
}

#[test]
fn a_given_index_gives_the_same_cover_and_a_wrong_one_is_ignored() {
    let (points, mut normals) = sphere(3000);
    let params = SurfaceCoverParams {
        eps: 5e-3,
        ..SurfaceCoverParams::default()
    };
    let (plain, _) = build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).unwrap();
    let own = PointIndex::new(&points).unwrap();
    let (reused, _) = build_surface_cover(
        &SurfaceSamples::new(&points, &normals).with_index(&own),
        &params,
    )
    .unwrap();
    assert!(plain == reused, "covers differ");
    // An index over other points (same count, one moved) is not used.
    let mut moved = points.clone();
    moved[17] *= 0.9;
    let other = PointIndex::new(&moved).unwrap();
    let (ignored, _) = build_surface_cover(
        &SurfaceSamples::new(&points, &normals).with_index(&other),
        &params,
    )
    .unwrap();
    assert!(plain == ignored, "covers differ");
    // With a point left out (zero normal) the index cannot serve either.
    normals[5] = DVec3::ZERO;
    let (filtered, stats) =
        build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).unwrap();
    let (filtered_given, _) = build_surface_cover(
        &SurfaceSamples::new(&points, &normals).with_index(&own),
        &params,
    )
    .unwrap();
    assert_eq!(stats.skipped_normals, 1);
    assert!(filtered == filtered_given, "covers differ");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// The samples the build gives (rows of grown supports taken from their growth) are the
    /// gather of its cover over the given index, slot for slot; the cover is the plain one.
    #[test]
    fn the_build_s_support_samples_are_the_gather(
        n in 300usize..3000,
        bump in 0.0f64..0.05,
        eps in 1e-3f64..2e-2,
        growth_tolerance in prop::sample::select(vec![1e-7, 0.05, 0.3]),
        max_growth in 1.0f64..6.0,
        kernel in prop::sample::select(Kernel::ALL.to_vec()),
        expansion in any::<bool>(),
        confidence in prop::option::of(0.1f64..1.0),
        seed in any::<u64>(),
    ) {
        let (points, normals): (Vec<DVec3>, Vec<DVec3>) = fibonacci_sphere(n)
            .into_iter()
            .map(|u| ((0.3 + bump * (7.0 * u.x).sin() * (5.0 * u.y).cos()) * u, u))
            .unzip();
        let trust: Option<Vec<f64>> = confidence
            .map(|c| (0..n).map(|i| if i % 3 == 0 { c } else { 1.0 }).collect());
        let params = SurfaceCoverParams {
            eps,
            growth_tolerance,
            max_growth,
            kernel,
            expansion,
            seed,
            ..SurfaceCoverParams::default()
        };
        let index = PointIndex::new(&points).unwrap();
        let samples = SurfaceSamples::new(&points, &normals)
            .with_confidence(trust.as_deref())
            .with_index(&index);
        let (cover, stats, incidence) = build_surface_cover_with_samples(&samples, &params).unwrap();
        let (plain, plain_stats) = build_surface_cover(&samples, &params).unwrap();
        prop_assert!(cover == plain, "covers differ");
        prop_assert_eq!(stats.supports_after_expansion, plain_stats.supports_after_expansion);
        prop_assert_eq!(incidence, Some(SupportSamples::gather(&cover, &index)));
        // Without an index the build has none to give samples over.
        let unindexed = SurfaceSamples::new(&points, &normals).with_confidence(trust.as_deref());
        let (_, _, none) = build_surface_cover_with_samples(&unindexed, &params).unwrap();
        prop_assert!(none.is_none());
    }
}
