//! The volume cover of scattered samples with values (beyond thesis §3.4.2), checked by brute
//! force: the voxel centres of a CT phantom given as scattered samples, jittered samples of
//! an analytic field, determinism, and bad input.

mod volume_common;

use sphcover_core::random::XorShift64;
use sphcover_core::{
    Cover, DVec3, Threshold, VolumeCoverError, VolumeCoverParams, VolumeCoverStats,
    build_scattered_cover, build_volume_cover,
};
use volume_common::{AIR, MATERIAL, in_open_ball, test_phantom};

/// Every object sample lies strictly inside some support's ball (brute force).
fn assert_all_inside(cover: &Cover, points: &[DVec3], object: &[bool]) {
    for (x, _) in points.iter().zip(object).filter(|&(_, &o)| o) {
        let inside = cover
            .centres()
            .iter()
            .zip(cover.radii())
            .any(|(c, &r)| in_open_ball(*x, *c, r));
        assert!(inside, "object sample {x} lies in no support");
    }
}

/// Largest RMS residual of a support over the samples strictly inside its ball, recomputed from
/// the samples and the cover alone.
fn max_support_rms(
    points: &[DVec3],
    values: &[f64],
    cover: &Cover,
    stats: &VolumeCoverStats,
) -> f64 {
    let (lo, hi) = stats.value_range;
    let mut worst: f64 = 0.0;
    for i in 0..cover.len() {
        let (c, r) = (cover.centres()[i], cover.radii()[i]);
        let g = cover.func(i).unwrap();
        let (mut sum, mut n) = (0.0, 0);
        for (x, v) in points.iter().zip(values) {
            if in_open_ball(*x, c, r) {
                sum += (g.value(*x - c) - (v - lo) / (hi - lo)).powi(2);
                n += 1;
            }
        }
        assert!(n > 0);
        worst = worst.max((sum / n as f64).sqrt());
    }
    worst
}

fn hu_params() -> VolumeCoverParams {
    VolumeCoverParams {
        threshold: Threshold::Raw(0.5 * (AIR + MATERIAL)),
        ..VolumeCoverParams::default()
    }
}

#[test]
fn voxel_centres_as_scattered_samples_cover_like_the_grid() {
    let volume = test_phantom();
    let points: Vec<DVec3> = (0..volume.len())
        .map(|i| volume.voxel_centre(volume.ijk(i)))
        .collect();
    let values: Vec<f64> = (0..volume.len()).map(|i| volume.value(i)).collect();
    let params = hu_params();
    let (cover, stats) = build_scattered_cover(&points, &values, &params).unwrap();
    let (grid_cover, grid_stats) = build_volume_cover(&volume, &params).unwrap();
    let object: Vec<bool> = values.iter().map(|&v| v > 500.0).collect();
    assert_eq!(stats.object_points, grid_stats.object_points);
    // The same spacing, radius bounds and thickness as the grid builder.
    assert!((stats.sample_spacing - volume.voxel_diagonal()).abs() < 1e-12);
    assert!((stats.r_min - grid_stats.r_min).abs() < 1e-12);
    assert!((stats.r_max - grid_stats.r_max).abs() < 1e-9);
    assert_all_inside(&cover, &points, &object);
    let rms = max_support_rms(&points, &values, &cover, &stats);
    assert!(rms <= params.tolerance, "max RMS {rms}");
    assert!(
        (rms - stats.max_rms).abs() < 1e-9,
        "{rms} vs {}",
        stats.max_rms
    );
    assert_eq!(stats.above_tolerance, 0);
    // As compact as the grid cover, within a quarter (the covering rules differ).
    let (n, g) = (cover.len() as f64, grid_cover.len() as f64);
    assert!(n <= 1.25 * g, "{n} scattered supports vs {g} on the grid");
}

/// Jittered samples (uniform ±0.35 spacing per axis) of a blurred ball: `1/(1 + e^{(d−R)/w})`.
fn jittered_ball(n: usize, seed: u64) -> (Vec<DVec3>, Vec<f64>) {
    let mut rng = XorShift64::new(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let mut uniform = move || rng.uniform();
    let centre = DVec3::splat(0.5 * (n as f64 - 1.0));
    let (mut points, mut values) = (Vec::new(), Vec::new());
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let jitter = DVec3::new(uniform(), uniform(), uniform()) * 0.7 - 0.35;
                let p = (DVec3::new(i as f64, j as f64, k as f64) + jitter) * 0.5;
                let d = p.distance(centre * 0.5);
                points.push(p);
                values.push(100.0 / (1.0 + ((d - 0.15 * n as f64) / 0.6).exp()));
            }
        }
    }
    (points, values)
}

#[test]
fn jittered_samples_of_an_analytic_field_are_covered_within_tolerance() {
    let (points, values) = jittered_ball(20, 3);
    let params = VolumeCoverParams {
        threshold: Threshold::Raw(50.0),
        ..VolumeCoverParams::default()
    };
    let (cover, stats) = build_scattered_cover(&points, &values, &params).unwrap();
    let object: Vec<bool> = values.iter().map(|&v| v > 50.0).collect();
    assert_eq!(stats.object_points, object.iter().filter(|&&o| o).count());
    assert_all_inside(&cover, &points, &object);
    let rms = max_support_rms(&points, &values, &cover, &stats);
    assert!(rms <= params.tolerance, "max RMS {rms}");
    assert_eq!(stats.above_tolerance, 0);
    // Far fewer supports than object samples.
    assert!(
        cover.len() * 5 < stats.object_points,
        "{} supports for {} object samples",
        cover.len(),
        stats.object_points
    );
    // The cover's function follows the field near the boundary (value 0.5 at d = R).
    let f = sphcover_core::PuEvaluator::new(&cover, 1.0).unwrap();
    let centre = DVec3::splat(0.25 * 19.0);
    for dir in [
        DVec3::X,
        DVec3::Y,
        DVec3::Z,
        DVec3::new(1.0, 1.0, 1.0).normalize(),
    ] {
        let x = centre + dir * 3.0;
        if let Some(v) = f.value(x) {
            assert!((v - 0.5).abs() < 0.15, "f = {v} at the level set");
        }
    }
}

#[test]
fn the_linear_variant_covers_every_sample() {
    let (points, values) = jittered_ball(12, 5);
    let params = VolumeCoverParams {
        variant: sphcover_core::VolumeCoverVariant::BoundingBoxLinear,
        ..VolumeCoverParams::default()
    };
    let (cover, stats) = build_scattered_cover(&points, &values, &params).unwrap();
    assert_eq!(stats.candidates, points.len());
    assert_all_inside(&cover, &points, &vec![true; points.len()]);
    assert!(cover.len() < points.len());
}

#[test]
fn same_seed_gives_the_same_cover_whatever_the_thread_count() {
    let (points, values) = jittered_ball(14, 9);
    let run = |threads: usize, seed: u64| {
        sphcover_core::on_threads(threads, || {
            let params = VolumeCoverParams {
                seed,
                ..VolumeCoverParams::default()
            };
            build_scattered_cover(&points, &values, &params).unwrap().0
        })
    };
    let one = run(1, 4);
    assert_eq!(one, run(2, 4));
    assert_ne!(one, run(2, 5));
}

#[test]
fn bad_input_gives_typed_errors() {
    let (mut points, mut values) = jittered_ball(6, 1);
    let params = VolumeCoverParams::default();
    let err = |p: &[DVec3], v: &[f64]| build_scattered_cover(p, v, &params).unwrap_err();
    assert_eq!(
        err(&points, &values[1..]),
        VolumeCoverError::SampleCountMismatch {
            positions: points.len(),
            values: points.len() - 1
        }
    );
    assert_eq!(
        err(&points[..1], &values[..1]),
        VolumeCoverError::TooFewSamples { count: 1 }
    );
    assert_eq!(
        err(&points, &vec![7.0; points.len()]),
        VolumeCoverError::ConstantVolume { value: 7.0 }
    );
    values[10] = f64::NAN;
    assert_eq!(
        err(&points, &values),
        VolumeCoverError::NonFiniteSample {
            index: 10,
            what: "value"
        }
    );
    values[10] = f64::INFINITY;
    assert!(
        err(&points, &values)
            .to_string()
            .contains("non-finite value")
    );
    values[10] = 1.0;
    points[3].y = f64::NAN;
    assert_eq!(
        err(&points, &values),
        VolumeCoverError::NonFiniteSample {
            index: 3,
            what: "position"
        }
    );
    points[3].y = 0.0;
    let high = VolumeCoverParams {
        threshold: Threshold::Raw(1e9),
        ..VolumeCoverParams::default()
    };
    assert!(matches!(
        build_scattered_cover(&points, &values, &high),
        Err(VolumeCoverError::NoObjectPoint { .. })
    ));
    let same = vec![DVec3::ONE; points.len()];
    assert_eq!(err(&same, &values), VolumeCoverError::CoincidentSamples);
}
