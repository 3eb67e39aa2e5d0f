//! Criterion benchmark: dual complex (triangulation + filter) of an adaptive octree cover of
//! a torus. `SPHCOVER_BENCH_LARGE=1` adds the 1M-sphere case, which is slow enough to be left
//! out by default.

#[path = "../examples/common/octree_torus.rs"]
mod octree_torus;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use octree_torus::octree_torus_cover_of_size;
use sphcover_tetra::{DualComplexParams, TetMesh, dual_complex};

fn bench(c: &mut Criterion) {
    let mut sizes = vec![100_000usize];
    if std::env::var_os("SPHCOVER_BENCH_LARGE").is_some() {
        sizes.push(1_000_000);
    }
    let mut group = c.benchmark_group("octree_torus");
    group.sample_size(10);
    for n in sizes {
        let (_, _, centres, radii) = octree_torus_cover_of_size(n);
        let params = DualComplexParams::default();
        group.bench_with_input(
            BenchmarkId::new("dual_complex", centres.len()),
            &(&centres, &radii),
            |b, (c, r)| b.iter(|| dual_complex(c, r, &params).expect("cover")),
        );
        let dc = dual_complex(&centres, &radii, &params).expect("cover");
        group.bench_with_input(BenchmarkId::new("tet_mesh", centres.len()), &dc, |b, dc| {
            b.iter(|| TetMesh::from_dual_complex(dc))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
