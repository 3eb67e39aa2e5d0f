//! Criterion benchmarks of the operators.
//!
//! * `laplacian_apply_1m`: `y = L_W x` on a jittered lattice of 101³ ≈ 1.03M supports with
//!   radius 1.5 h (SIG shrink 0.7, mean degree ≈ 40), on one and on two threads. Divide the
//!   time by the stored entries (printed) for the cost per stored neighbour.
//! * `memory_read`: a dot product of two 32M-entry vectors (512 MB read), the bandwidth
//!   reference: the apply streams 12 bytes per stored neighbour (φ and the u32 index).
//! * `cg_200k`: Poisson `Lap u = f` (thesis mass, one anchor) to a 1e-8 relative residual, and
//!   one implicit smoothing step, on a jittered lattice of 59³ ≈ 205K supports (r = 1.3 h),
//!   with the Jacobi and the multicolour symmetric Gauss–Seidel preconditioners.
//!
//! Run: `cargo bench -p sphcover-ops --bench operators` (add `-- 'laplacian|memory'` to skip
//! the criterion CG runs; the one-shot CG timings are printed either way).

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use sphcover_core::{Aabb, SphereIntersectionGraph, synthetic};
use sphcover_ops::{
    CgParams, MassKind, PairGeometry, PoissonBoundary, Preconditioner, implicit_smoothing,
    solve_poisson,
};

fn jittered(cells: usize, radius_factor: f64) -> PairGeometry {
    let domain = Aabb {
        min: DVec3::ZERO,
        max: DVec3::ONE,
    };
    let cover =
        synthetic::jittered_grid(domain, 1.0 / cells as f64, radius_factor, 0.25, 1).unwrap();
    let graph = SphereIntersectionGraph::build(&cover.centres, &cover.radii, 0.7).unwrap();
    PairGeometry::build(&cover.centres, &cover.radii, &graph).unwrap()
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

fn laplacian_apply(c: &mut Criterion) {
    let g = jittered(100, 1.5);
    eprintln!(
        "laplacian_apply_1m: {} supports, {} stored entries, mean degree {:.1}",
        g.len(),
        g.stored_entries(),
        g.stored_entries() as f64 / g.len() as f64
    );
    let x: Vec<f64> = g.centres().iter().map(|p| p.x.sin() + p.y * p.z).collect();
    let mut y = vec![0.0; g.len()];
    let mut group = c.benchmark_group("laplacian_apply_1m");
    group.sample_size(20);
    for threads in [1, 2] {
        let pool = pool(threads);
        group.bench_function(format!("{threads}_threads"), |b| {
            b.iter(|| pool.install(|| g.apply_stiffness(black_box(&x), &mut y)))
        });
    }
    group.finish();

    let a = vec![1.0f64; 32 << 20];
    let b = vec![0.5f64; 32 << 20];
    let mut group = c.benchmark_group("memory_read");
    group.sample_size(10);
    for threads in [1, 2] {
        let pool = pool(threads);
        group.bench_function(format!("dot_512MB_{threads}_threads"), |bench| {
            bench.iter(|| pool.install(|| sphcover_ops::dot(&a, &b)))
        });
    }
    group.finish();
}

fn cg(c: &mut Criterion) {
    let g = jittered(58, 1.3);
    let f: Vec<f64> = g
        .centres()
        .iter()
        .map(|p| (3.0 * p.x).sin() * (2.0 * p.y).cos() + p.z)
        .collect();
    let anchor = PoissonBoundary::Anchor {
        support: 0,
        value: 0.0,
    };
    let mut group = c.benchmark_group("cg_200k");
    group.sample_size(10);
    for (name, preconditioner) in [
        ("jacobi", Preconditioner::Jacobi),
        ("sgs", Preconditioner::SymmetricGaussSeidel),
        ("two_level", Preconditioner::TwoLevel),
    ] {
        let params = CgParams {
            preconditioner,
            ..CgParams::default()
        };
        // One timed solve each, printed even when a filter skips the criterion runs below.
        let start = Instant::now();
        let (_, info) = solve_poisson(&g, MassKind::Thesis, &f, &anchor, &params).unwrap();
        let poisson_time = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let (_, smooth_info) = implicit_smoothing(&g, MassKind::Thesis, 1e-4, &f, &params).unwrap();
        let smooth_time = start.elapsed().as_secs_f64();
        eprintln!(
            "cg_200k ({name}): {} supports, {} stored entries; Poisson {} iterations \
             (residual {:.1e}) in {poisson_time:.2} s; smoothing t = 1e-4: {} iterations in \
             {smooth_time:.3} s",
            g.len(),
            g.stored_entries(),
            info.iterations,
            info.relative_residual,
            smooth_info.iterations
        );
        group.bench_function(format!("poisson_anchor_1e-8_{name}"), |b| {
            b.iter(|| solve_poisson(&g, MassKind::Thesis, black_box(&f), &anchor, &params).unwrap())
        });
        group.bench_function(format!("implicit_smoothing_t1e-4_1e-8_{name}"), |b| {
            b.iter(|| {
                implicit_smoothing(&g, MassKind::Thesis, 1e-4, black_box(&f), &params).unwrap()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, laplacian_apply, cg);
criterion_main!(benches);
