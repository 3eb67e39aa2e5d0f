//! The volume cover builder (thesis §3.4.2, §6.2.3) on synthetic CT phantoms, checked by
//! brute force: coverage of every object voxel, the RMS tolerance of every support,
//! compactness, determinism, and its errors.

mod volume_common;

use sphcover_core::{
    Cover, DVec3, Threshold, Volume, VolumeCoverError, VolumeCoverParams, VolumeCoverStats,
    VolumeCoverVariant, VoxelValues, build_volume_cover,
};
use volume_common::{AIR, MATERIAL, test_phantom};

/// Normalised value of voxel `idx`.
fn normalised(volume: &Volume, stats: &VolumeCoverStats, idx: usize) -> f64 {
    let (lo, hi) = stats.value_range;
    (volume.value(idx) - lo) / (hi - lo)
}

/// Every point of `points` lies strictly inside some support's ball (brute force).
fn assert_all_inside(cover: &Cover, points: impl Iterator<Item = DVec3>) {
    for x in points {
        let inside = cover
            .centers()
            .iter()
            .zip(cover.radii())
            .any(|(c, &r)| x.distance(*c) < r);
        assert!(inside, "point {x} lies in no support");
    }
}

/// RMS residual of every support over all finite samples within its radius, recomputed from
/// the volume and the cover alone; returns the largest.
fn max_support_rms(volume: &Volume, cover: &Cover, stats: &VolumeCoverStats) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..cover.len() {
        let (c, r) = (cover.centers()[i], cover.radii()[i]);
        let g = cover.func(i).unwrap();
        let (mut sum, mut n) = (0.0, 0);
        for idx in 0..volume.len() {
            let x = volume.voxel_center(volume.ijk(idx));
            if x.distance(c) <= r {
                let v = normalised(volume, stats, idx);
                if v.is_finite() {
                    sum += (g.value(x - c) - v).powi(2);
                    n += 1;
                }
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
fn thin_plate_phantom_is_covered_compactly_within_tolerance() {
    let volume = test_phantom();
    let params = hu_params();
    let (cover, stats) = build_volume_cover(&volume, &params).unwrap();
    eprintln!("{stats:#?}");
    let threshold = 0.5 * (AIR + MATERIAL);
    let object: Vec<usize> = (0..volume.len())
        .filter(|&i| volume.value(i) > threshold)
        .collect();
    assert_eq!(stats.object_points, object.len());
    assert_eq!(stats.supports, cover.len());
    assert_all_inside(
        &cover,
        object.iter().map(|&i| volume.voxel_center(volume.ijk(i))),
    );
    let rms = max_support_rms(&volume, &cover, &stats);
    assert!(rms <= params.tolerance, "max RMS {rms}");
    assert!((rms - stats.max_rms).abs() < 1e-9, "{rms} vs {}", stats.max_rms);
    assert_eq!(stats.above_tolerance, 0);
    let ratio = object.len() as f64 / cover.len() as f64;
    eprintln!("object {} supports {} ratio {ratio:.1}", object.len(), cover.len());
    assert!(ratio >= 20.0, "ratio {ratio}");
}

#[test]
#[ignore]
fn explore_ratio() {
    for &(t, blur) in &[(4.0, 0.0), (4.0, 0.8), (4.0, 1.2), (6.0, 0.8), (8.0, 0.8)] {
        for &eps in &[0.05, 0.1] {
            let dims = [40, 40, 24];
            let values = volume_common::thin_plate(dims, t, 20.0, blur);
            let volume = Volume::axis_aligned(
                dims,
                VoxelValues::F64(values),
                DVec3::splat(0.1),
                DVec3::ZERO,
            )
            .unwrap();
            let params = VolumeCoverParams { tolerance: eps, ..hu_params() };
            let (cover, stats) = build_volume_cover(&volume, &params).unwrap();
            eprintln!(
                "t {t} blur {blur} eps {eps}: object {} supports {} ratio {:.1} rmean {:.3} above {}",
                stats.object_points,
                cover.len(),
                stats.object_points as f64 / cover.len() as f64,
                stats.radius_mean / 0.1,
                stats.above_tolerance
            );
        }
    }
}
