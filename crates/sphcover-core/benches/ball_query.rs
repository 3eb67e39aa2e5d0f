//! Containment queries ("which supports contain x") for one million random points on the
//! adaptive cover of the `sig_build` benchmark (998,656 supports), and the index build.
//!
//! `cargo bench -p sphcover-core --bench ball_query`

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use sphcover_core::synthetic::{AdaptiveCoverParams, Surface, adaptive_surface_cover};
use sphcover_core::{BallIndex, DVec3};

const QUERIES: usize = 1_000_000;
const SPHERE_RADIUS: f64 = 0.225;

/// Total number of containing supports over `points`, queried in parallel.
fn count_containing(index: &BallIndex, points: &[DVec3]) -> usize {
    points
        .par_iter()
        .map_init(Vec::new, |out, &x| {
            index.containing(x, out);
            out.len()
        })
        .sum()
}

fn ball_query(c: &mut Criterion) {
    let params = AdaptiveCoverParams {
        surface: Surface::Sphere {
            centre: DVec3::ZERO,
            radius: SPHERE_RADIUS,
        },
        max_depth: 9,
        ..AdaptiveCoverParams::default()
    };
    let cover = adaptive_surface_cover(&params).expect("valid parameters");
    let start = Instant::now();
    let index = BallIndex::new(&cover.centres, &cover.radii);
    eprintln!(
        "adaptive cover: {} supports; index built in {:.2?}",
        cover.len(),
        start.elapsed()
    );

    // Uniform in the unit cube (mostly where the cover is coarse), and within 0.01 of the
    // sphere (where it is finest), both in random order.
    let mut rng = Pcg64::seed_from_u64(7);
    let mut cube_point = || {
        DVec3::new(
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.5..0.5),
        )
    };
    let uniform: Vec<DVec3> = (0..QUERIES).map(|_| cube_point()).collect();
    let mut rng = Pcg64::seed_from_u64(8);
    let near_surface: Vec<DVec3> = (0..QUERIES)
        .map(|_| {
            let dir = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize_or(DVec3::X);
            dir * (SPHERE_RADIUS + rng.random_range(-0.01..0.01))
        })
        .collect();
    // The near-surface points in octree (Morton) order, as a caller evaluating many points
    // would sort them: consecutive queries then share cache lines.
    let mut sorted = near_surface.clone();
    sorted.sort_by_key(|p| morton_code(*p));
    for (name, points) in [("uniform", &uniform), ("near-surface", &near_surface)] {
        eprintln!(
            "{QUERIES} {name} points: mean {:.2} containing supports",
            count_containing(&index, points) as f64 / QUERIES as f64
        );
    }

    c.bench_function("ball_index_build_adaptive_1m", |b| {
        b.iter(|| {
            black_box(BallIndex::new(
                black_box(&cover.centres),
                black_box(&cover.radii),
            ))
        })
    });
    c.bench_function("containing_1m_uniform_points", |b| {
        b.iter(|| black_box(count_containing(&index, black_box(&uniform))))
    });
    c.bench_function("containing_1m_near_surface_points", |b| {
        b.iter(|| black_box(count_containing(&index, black_box(&near_surface))))
    });
    c.bench_function("containing_1m_near_surface_points_sorted", |b| {
        b.iter(|| black_box(count_containing(&index, black_box(&sorted))))
    });
}

/// Morton code of a point of the unit cube `[−0.5, 0.5]³` at 2^21 cells per axis.
fn morton_code(p: DVec3) -> u64 {
    let cell = ((p + DVec3::splat(0.5)) * (1u64 << 21) as f64)
        .clamp(DVec3::ZERO, DVec3::splat(((1u64 << 21) - 1) as f64))
        .as_u64vec3();
    let spread = |v: u64| (0..21).fold(0u64, |code, bit| code | (((v >> bit) & 1) << (3 * bit)));
    spread(cell.x) | (spread(cell.y) << 1) | (spread(cell.z) << 2)
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = ball_query
}
criterion_main!(benches);
