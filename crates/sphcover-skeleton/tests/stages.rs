//! The pipeline as a list of stages: progress reports every stage in order, each repair can
//! be switched off on its own, and parameters that contradict each other are refused.

use std::sync::Mutex;

use sphcover_core::ParameterError;
use sphcover_evaluation::thin_phantoms::{PhantomParams, ThinShape, thin_phantom};
use sphcover_skeleton::{
    SheetRepairs, SkeletonError, SkeletonParams, extract_skeleton, stage_names,
};

fn plate() -> sphcover_core::Volume {
    thin_phantom(
        ThinShape::CurvedPlate,
        &PhantomParams {
            noise: 0.1,
            seed: 3,
            ..PhantomParams::default()
        },
    )
    .volume
}

#[test]
fn progress_reports_every_stage_in_order_and_each_is_timed() {
    let volume = plate();
    let params = SkeletonParams::default();
    let seen = Mutex::new(Vec::new());
    let (_, stats) = extract_skeleton(&volume, &params, &|stage| {
        seen.lock()
            .unwrap()
            .push((stage.name, stage.index, stage.count));
    })
    .unwrap();
    let names = stage_names(&params);
    let seen = seen.into_inner().unwrap();
    let expected: Vec<_> = names
        .iter()
        .enumerate()
        .map(|(i, &n)| (n, i, names.len()))
        .collect();
    assert_eq!(seen, expected);
    let timed: Vec<_> = stats.stages.iter().map(|s| s.0).collect();
    assert_eq!(timed, names);
    for repair in [
        "rim trimming",
        "junction holes",
        "tunnels",
        "centring",
        "junction planes",
    ] {
        assert!(names.contains(&repair), "{repair} missing from {names:?}");
    }
    assert!(!names.contains(&"smoothing"), "smoothing is off by default");
}

#[test]
fn each_repair_switches_off_alone() {
    let volume = plate();
    let full = SkeletonParams::default();
    let (_, full_stats) = extract_skeleton(&volume, &full, &|_| {}).unwrap();
    assert!(full_stats.rim_triangles > 0 && full_stats.centred_vertices > 0);

    let mut no_rims = SkeletonParams::default();
    no_rims.repairs.rim_trimming = None;
    let names = stage_names(&no_rims);
    assert!(!names.contains(&"rim trimming") && !names.contains(&"cleaning again"));
    let (sheet, stats) = extract_skeleton(&volume, &no_rims, &|_| {}).unwrap();
    assert_eq!(stats.rim_triangles, 0);
    assert!(stats.centred_vertices > 0, "the other repairs still run");
    // Without trimming the sheet keeps its rims: more area, as many or more triangles.
    assert!(
        sheet.triangles.len() > full_stats.triangles,
        "{} vs {}",
        sheet.triangles.len(),
        full_stats.triangles
    );

    let mut bare = SkeletonParams::default();
    bare.repairs = SheetRepairs::cleaning_only();
    let (_, stats) = extract_skeleton(&volume, &bare, &|_| {}).unwrap();
    assert_eq!(
        (
            stats.rim_triangles,
            stats.centred_vertices,
            stats.junction_snapped_vertices,
            stats.junction_corner_vertices
        ),
        (0, 0, 0, 0)
    );
    assert!(stage_names(&bare).ends_with(&["patches", "cleaning", "topology"]));

    let mut smooth = SkeletonParams::default();
    smooth.repairs.smoothing = Some(Default::default());
    assert!(stage_names(&smooth).contains(&"smoothing"));
    let (smoothed, _) = extract_skeleton(&volume, &smooth, &|_| {}).unwrap();
    let (plain, _) = extract_skeleton(&volume, &full, &|_| {}).unwrap();
    assert_eq!(
        smoothed.triangles, plain.triangles,
        "smoothing moves vertices only"
    );
    assert_ne!(smoothed.vertices, plain.vertices);
}

#[test]
fn contradicting_or_invalid_repairs_are_refused_before_any_work() {
    let volume = plate();
    let mut fold_alone = SkeletonParams::default();
    fold_alone.repairs.centring = None;
    let err = extract_skeleton(&volume, &fold_alone, &|_| panic!("no stage may run")).unwrap_err();
    assert!(
        matches!(
            err,
            SkeletonError::InvalidParameter(ParameterError {
                name: "junction_fold",
                ..
            })
        ),
        "{err}"
    );
    let mut still = SkeletonParams::default();
    if let Some(centring) = &mut still.repairs.centring {
        centring.step_voxels = 0.0;
    }
    let err = extract_skeleton(&volume, &still, &|_| panic!("no stage may run")).unwrap_err();
    assert!(
        matches!(
            err,
            SkeletonError::InvalidParameter(ParameterError {
                name: "centring.step_voxels",
                ..
            })
        ),
        "{err}"
    );
    let mut negative = SkeletonParams::default();
    negative.repairs.cleaning.max_hole_perimeter_voxels = -1.0;
    assert!(matches!(
        extract_skeleton(&volume, &negative, &|_| panic!("no stage may run")),
        Err(SkeletonError::InvalidParameter(_))
    ));
}
