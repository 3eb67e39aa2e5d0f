//! Bad input to the surface cover builder gives typed errors, never a panic; unusable
//! normals are skipped and counted.

use sphcover_core::LengthMismatch;
use sphcover_core::{
    DVec3, ParameterError, PointCloud, SurfaceCoverError, SurfaceCoverParams, SurfaceSamples,
    build_surface_cover, build_surface_cover_from_cloud,
};

/// A small plane patch z = 0 with upward normals.
fn patch() -> (Vec<DVec3>, Vec<DVec3>) {
    let points: Vec<DVec3> = (0..400)
        .map(|i| {
            DVec3::new(
                (i % 20) as f64 / 40.0 - 0.25,
                (i / 20) as f64 / 40.0 - 0.25,
                0.0,
            )
        })
        .collect();
    let normals = vec![DVec3::Z; points.len()];
    (points, normals)
}

#[test]
fn cloud_without_normals_is_refused() {
    let cloud = PointCloud::from_positions(patch().0);
    let err = build_surface_cover_from_cloud(&cloud, &SurfaceCoverParams::default()).unwrap_err();
    assert_eq!(err, SurfaceCoverError::MissingNormals);
    assert!(err.to_string().contains("needs a normal per point"));
}

#[test]
fn inconsistent_or_non_finite_input_is_refused() {
    let (mut points, normals) = patch();
    let p = SurfaceCoverParams::default();
    assert!(matches!(
        build_surface_cover(&SurfaceSamples::new(&points, &normals[1..]), &p),
        Err(SurfaceCoverError::LengthMismatch(LengthMismatch {
            array: "normals",
            ..
        }))
    ));
    assert!(matches!(
        build_surface_cover(
            &SurfaceSamples::new(&points, &normals).with_confidence(Some(&[1.0])),
            &p
        ),
        Err(SurfaceCoverError::LengthMismatch(LengthMismatch {
            array: "confidence",
            ..
        }))
    ));
    let mut conf = vec![1.0; points.len()];
    conf[3] = -1.0;
    assert!(matches!(
        build_surface_cover(
            &SurfaceSamples::new(&points, &normals).with_confidence(Some(&conf)),
            &p
        ),
        Err(SurfaceCoverError::InvalidConfidence { index: 3, .. })
    ));
    points[5] = DVec3::new(f64::NAN, 0.0, 0.0);
    assert!(matches!(
        build_surface_cover(&SurfaceSamples::new(&points, &normals), &p),
        Err(SurfaceCoverError::NonFinitePoint { index: 5, .. })
    ));
    points[5] = DVec3::new(2.0, 0.0, 0.0);
    let err = build_surface_cover(&SurfaceSamples::new(&points, &normals), &p).unwrap_err();
    assert!(matches!(
        err,
        SurfaceCoverError::NotNormalised { index: 5, .. }
    ));
    assert!(err.to_string().contains("normalise"));
}

#[test]
fn invalid_parameters_are_named() {
    let (points, normals) = patch();
    let bad = [
        SurfaceCoverParams {
            eps: 0.0,
            ..Default::default()
        },
        SurfaceCoverParams {
            eps: f64::NAN,
            ..Default::default()
        },
        SurfaceCoverParams {
            n_min: 0,
            ..Default::default()
        },
        SurfaceCoverParams {
            max_depth: 21,
            ..Default::default()
        },
        SurfaceCoverParams {
            box_margin: -0.1,
            ..Default::default()
        },
        SurfaceCoverParams {
            max_growth: 0.5,
            ..Default::default()
        },
        SurfaceCoverParams {
            growth_tolerance: 0.0,
            ..Default::default()
        },
    ];
    let names = [
        "eps",
        "eps",
        "n_min",
        "max_depth",
        "box_margin",
        "max_growth",
        "growth_tolerance",
    ];
    for (params, name) in bad.iter().zip(names) {
        match build_surface_cover(&SurfaceSamples::new(&points, &normals), params) {
            Err(SurfaceCoverError::InvalidParameter(ParameterError { name: got, .. })) => {
                assert_eq!(got, name)
            }
            other => panic!("{name}: expected InvalidParameter, got {other:?}"),
        }
    }
}

#[test]
fn unusable_normals_are_skipped_and_counted() {
    let (points, mut normals) = patch();
    normals[0] = DVec3::ZERO;
    normals[1] = DVec3::new(f64::NAN, 0.0, 1.0);
    // Normals need not be unit length.
    normals[2] = DVec3::new(0.0, 0.0, 7.0);
    let params = SurfaceCoverParams {
        eps: 1e-3,
        ..Default::default()
    };
    let (cover, stats) =
        build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).unwrap();
    assert_eq!(stats.skipped_normals, 2);
    assert_eq!(stats.used_points, points.len() - 2);
    assert!(!cover.is_empty());
    // A plane is fitted exactly.
    assert_eq!(stats.supports_over_eps, 0);
    assert!(stats.max_error < 1e-12);

    let all_zero = vec![DVec3::ZERO; points.len()];
    assert!(matches!(
        build_surface_cover(&SurfaceSamples::new(&points, &all_zero), &params),
        Err(SurfaceCoverError::NoUsablePoints {
            skipped_normals: 400,
            ..
        })
    ));
    assert!(matches!(
        build_surface_cover(&SurfaceSamples::new(&[], &[]), &params),
        Err(SurfaceCoverError::NoUsablePoints { points: 0, .. })
    ));
}

#[test]
fn tiny_inputs_still_give_a_cover_of_the_box() {
    // Fewer points than n_min: every support reaches all of them.
    let points = [
        DVec3::new(0.1, 0.0, 0.0),
        DVec3::new(-0.1, 0.0, 0.0),
        DVec3::new(0.0, 0.1, 0.0),
    ];
    let normals = [DVec3::Z; 3];
    let (cover, stats) = build_surface_cover(
        &SurfaceSamples::new(&points, &normals),
        &SurfaceCoverParams::default(),
    )
    .unwrap();
    assert!(!cover.is_empty());
    assert_eq!(stats.used_points, 3);
    let f = sphcover_core::PuEvaluator::new(&cover, 1.0).unwrap();
    for x in [DVec3::splat(0.5), DVec3::splat(-0.5), DVec3::ZERO] {
        assert!(f.value(x).is_some(), "{x} is not covered");
    }
    // Below the plane is inside (normals point up, outward).
    assert!(f.value(DVec3::new(0.0, 0.0, -0.2)).unwrap() > 0.0);
    assert!(f.value(DVec3::new(0.0, 0.0, 0.2)).unwrap() < 0.0);
}

#[test]
fn confidence_weights_the_fit() {
    let (points, normals) = patch();
    let params = SurfaceCoverParams {
        eps: 1e-3,
        ..Default::default()
    };
    let ones = vec![1.0; points.len()];
    let (a, _) = build_surface_cover(
        &SurfaceSamples::new(&points, &normals).with_confidence(Some(&ones)),
        &params,
    )
    .unwrap();
    let (b, _) = build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).unwrap();
    assert_eq!(a, b, "unit confidence changes nothing");
    // Zero confidence removes points entirely.
    let mut half = ones.clone();
    half.iter_mut().step_by(2).for_each(|c| *c = 0.0);
    let (_, stats) = build_surface_cover(
        &SurfaceSamples::new(&points, &normals).with_confidence(Some(&half)),
        &params,
    )
    .unwrap();
    assert_eq!(stats.used_points, points.len() / 2);
}

#[test]
fn points_left_out_are_as_if_never_given() {
    // A curved patch, so that the fits depend on which points they see.
    let (mut points, mut normals) = patch();
    for (p, m) in points.iter_mut().zip(&mut normals) {
        p.z = 0.8 * (p.x * p.x + p.y * p.y);
        *m = DVec3::new(-1.6 * p.x, -1.6 * p.y, 1.0);
    }
    let params = SurfaceCoverParams {
        eps: 1e-4,
        ..Default::default()
    };
    let left_out = |i: usize| i % 7 == 3;
    let kept = |v: &[DVec3]| -> Vec<DVec3> {
        (0..v.len())
            .filter(|&i| !left_out(i))
            .map(|i| v[i])
            .collect()
    };
    let (reference, _) = build_surface_cover(
        &SurfaceSamples::new(&kept(&points), &kept(&normals)),
        &params,
    )
    .unwrap();
    // Left out for their normal, or for zero confidence.
    let mut broken = normals.clone();
    let mut confidence = vec![1.0; points.len()];
    for i in (0..points.len()).filter(|&i| left_out(i)) {
        broken[i] = DVec3::ZERO;
        confidence[i] = 0.0;
    }
    let (by_normal, _) =
        build_surface_cover(&SurfaceSamples::new(&points, &broken), &params).unwrap();
    assert_eq!(by_normal, reference);
    let (by_confidence, _) = build_surface_cover(
        &SurfaceSamples::new(&points, &normals).with_confidence(Some(&confidence)),
        &params,
    )
    .unwrap();
    let unit = vec![1.0; kept(&points).len()];
    let (reference_unit, _) = build_surface_cover(
        &SurfaceSamples::new(&kept(&points), &kept(&normals)).with_confidence(Some(&unit)),
        &params,
    )
    .unwrap();
    assert_eq!(by_confidence, reference_unit);
}
