//! Surface cover construction (thesis §3.4.1) on a synthetic torus of 362K oriented points —
//! the point count of the thesis bunny (Table 5.1) — at ε = 2.5e-3, with and without the
//! expansion stage.

use criterion::{Criterion, criterion_group, criterion_main};
use sphcover_core::{DVec3, SurfaceCoverParams, SurfaceSamples, build_surface_cover};
use std::hint::black_box;

const POINTS: usize = 362_000;
/// Torus radii in the unit frame: the bounding box is 0.96 × 0.96 × 0.24.
const MAJOR: f64 = 0.36;
const MINOR: f64 = 0.12;

/// Points on the torus, uniform by area (rejection on the tube angle), with outward normals,
/// from a fixed 64-bit LCG so the bench needs no data file and no RNG crate.
fn torus(n: usize) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut points = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    while points.len() < n {
        let u = std::f64::consts::TAU * uniform();
        let v = std::f64::consts::TAU * uniform();
        // Area element ∝ MAJOR + MINOR cos v.
        if uniform() * (MAJOR + MINOR) > MAJOR + MINOR * v.cos() {
            continue;
        }
        let normal = DVec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
        let ring = DVec3::new(u.cos(), u.sin(), 0.0) * MAJOR;
        points.push(ring + MINOR * normal);
        normals.push(normal);
    }
    (points, normals)
}

fn bench(c: &mut Criterion) {
    let (points, normals) = torus(POINTS);
    let mut group = c.benchmark_group("surface_cover_torus_362k");
    group.sample_size(10);
    for expansion in [false, true] {
        let params = SurfaceCoverParams {
            expansion,
            ..SurfaceCoverParams::default()
        };
        let (cover, stats) =
            build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).expect("cover");
        eprintln!(
            "expansion {expansion}: {} supports ({} before expansion)",
            cover.len(),
            stats.supports_before_expansion
        );
        let name = if expansion {
            "with_expansion"
        } else {
            "octree_only"
        };
        group.bench_function(name, |b| {
            b.iter(|| {
                build_surface_cover(
                    &SurfaceSamples::new(black_box(&points), black_box(&normals)),
                    &params,
                )
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
