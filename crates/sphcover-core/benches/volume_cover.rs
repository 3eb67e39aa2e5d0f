//! Volume cover construction (thesis §3.4.2) on a generated thin-plate CT phantom:
//! 96×96×48 voxels, plate 4 voxels thick, tilted, partial volume and PSF blur.

#[path = "../tests/volume_common/mod.rs"]
mod volume_common;

use criterion::{Criterion, criterion_group, criterion_main};
use sphcover_core::{
    CentreOrder, DVec3, Elimination, Threshold, Volume, VolumeCoverParams, VolumeCoverVariant,
    VoxelValues, build_volume_cover,
};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let dims = [96, 96, 48];
    let values = volume_common::thin_plate(dims, 4.0, 20.0, 0.8);
    let volume = Volume::axis_aligned(
        dims,
        VoxelValues::F32(values.iter().map(|&v| v as f32).collect()),
        DVec3::splat(0.1),
        DVec3::ZERO,
    )
    .expect("valid phantom");
    let params = VolumeCoverParams {
        threshold: Threshold::Raw(500.0),
        ..VolumeCoverParams::default()
    };
    let mut group = c.benchmark_group("volume_cover");
    group.sample_size(10);
    group.bench_function("plate_96x96x48_quadratic", |b| {
        b.iter(|| build_volume_cover(black_box(&volume), &params).expect("cover"))
    });
    let thesis = VolumeCoverParams {
        elimination: Elimination::Off,
        ..params.clone()
    };
    group.bench_function("plate_96x96x48_quadratic_no_elimination", |b| {
        b.iter(|| build_volume_cover(black_box(&volume), &thesis).expect("cover"))
    });
    let greedy = VolumeCoverParams {
        centre_order: CentreOrder::MostUncovered,
        ..params.clone()
    };
    group.bench_function("plate_96x96x48_quadratic_greedy", |b| {
        b.iter(|| build_volume_cover(black_box(&volume), &greedy).expect("cover"))
    });
    let linear = VolumeCoverParams {
        variant: VolumeCoverVariant::BoundingBoxLinear,
        ..params.clone()
    };
    group.bench_function("plate_96x96x48_linear_bounding_box", |b| {
        b.iter(|| build_volume_cover(black_box(&volume), &linear).expect("cover"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
