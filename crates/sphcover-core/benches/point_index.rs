//! The point index on a scan-like input: 362,000 points on a bumpy sphere (the size of the
//! benchmark bunny scan), its build, and the fixed-radius neighbourhoods of 224,000 query
//! points near the surface (the size of the reconstructed mesh's vertex set), one tree query
//! per point against [`PointIndex::map_within`].
//!
//! `cargo bench -p sphcover-core --bench point_index`; the current figures are in the
//! *sphcover-core* table of `docs/benchmarks.md`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use rayon::prelude::*;
use sphcover_core::synthetic::fibonacci_sphere;
use sphcover_core::{DVec3, PointIndex};

const POINTS: usize = 362_000;
const QUERIES: usize = 224_000;
/// About two sample spacings, as the vertex refinement of a reconstruction asks.
const RADIUS: f64 = 0.0078;

/// `n` Fibonacci points on a sphere of radius 0.4 with a bump, offset by `lift`.
fn bumpy_sphere(n: usize, lift: f64) -> Vec<DVec3> {
    fibonacci_sphere(n)
        .into_iter()
        .map(|u| (0.4 + 0.02 * (7.0 * u.x).sin() * (5.0 * u.y).cos() + lift) * u)
        .collect()
}

fn point_index(c: &mut Criterion) {
    let points = bumpy_sphere(POINTS, 0.0);
    // In the order of a polygonised mesh's vertices: by grid cell, x fastest.
    let mut queries = bumpy_sphere(QUERIES, 0.001);
    let cell = |p: &DVec3| (p / (2.0 * RADIUS)).floor().to_array().map(|c| c as i64);
    queries.sort_by_key(|p| {
        let [x, y, z] = cell(p);
        (z, y, x)
    });
    // What a caller does with the neighbours: read them.
    let index_points = |index: &PointIndex, near: &mut dyn Iterator<Item = usize>| {
        near.map(|s| index.slot_points()[s]).sum::<DVec3>()
    };
    let index = PointIndex::new(&points).expect("fewer than 2^32 points");
    let mut group = c.benchmark_group("point_index");
    group.sample_size(10);
    group.bench_function("build 362K", |b| {
        b.iter(|| PointIndex::new(black_box(&points)).expect("fewer than 2^32 points"))
    });
    group.bench_function("224K balls, one query each", |b| {
        b.iter(|| {
            queries
                .par_iter()
                .map_init(Vec::new, |near, &x| {
                    near.clear();
                    index.for_each_slot_within(x, RADIUS, |s, _| near.push(s));
                    index_points(&index, &mut near.iter().copied())
                })
                .sum::<DVec3>()
        })
    });
    group.bench_function("224K balls, map_within", |b| {
        b.iter(|| {
            index
                .map_within(
                    &queries,
                    RADIUS,
                    || (),
                    |_, _, near| index_points(&index, &mut near.iter().map(|&(s, _)| s as usize)),
                )
                .into_iter()
                .sum::<DVec3>()
        })
    });
    group.finish();
}

criterion_group!(benches, point_index);
criterion_main!(benches);
