//! Sphere intersection graph build (shrink 0.7) on an adaptive octree cover of a sphere with
//! about one million supports (998,656; radii over four octaves).
//!
//! `cargo bench -p sphcover-core --bench sig_build`

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use sphcover_core::synthetic::{
    AdaptiveCoverParams, Surface, SyntheticCover, adaptive_surface_cover,
};
use sphcover_core::{DVec3, SphereIntersectionGraph};

/// The thesis shrink factor (Appendix B).
const SHRINK: f64 = 0.7;

/// The adaptive cover shared by the `sig_build` and `ball_query` benchmarks.
fn million_support_cover() -> SyntheticCover {
    let params = AdaptiveCoverParams {
        surface: Surface::Sphere {
            centre: DVec3::ZERO,
            radius: 0.225,
        },
        max_depth: 9,
        ..AdaptiveCoverParams::default()
    };
    let start = Instant::now();
    let cover = adaptive_surface_cover(&params).expect("valid parameters");
    eprintln!(
        "adaptive cover: {} supports, radii {:.3e}..{:.3e}, generated in {:.2?}",
        cover.len(),
        cover.radii.iter().copied().fold(f64::INFINITY, f64::min),
        cover.radii.iter().copied().fold(0.0, f64::max),
        start.elapsed()
    );
    cover
}

fn sig_build(c: &mut Criterion) {
    let cover = million_support_cover();
    let graph =
        SphereIntersectionGraph::build(&cover.centres, &cover.radii, SHRINK).expect("valid cover");
    let max_degree = (0..graph.len()).map(|i| graph.degree(i)).max().unwrap_or(0);
    eprintln!(
        "SIG (s = {SHRINK}): {} nodes, {} edges, mean degree {:.2}, max degree {max_degree}, \
         {} threads",
        graph.len(),
        graph.num_edges(),
        graph.mean_degree(),
        rayon::current_num_threads()
    );
    c.bench_function("sig_build_adaptive_1m_s0.7", |b| {
        b.iter(|| {
            black_box(
                SphereIntersectionGraph::build(
                    black_box(&cover.centres),
                    black_box(&cover.radii),
                    SHRINK,
                )
                .expect("valid cover"),
            )
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = sig_build
}
criterion_main!(benches);
