//! Insertion by regions (the parallel rounds) against the sequential construction and the
//! brute-force validity check: the same tetrahedra and the same hidden points, on random
//! weighted sets and on degenerate grids, with thresholds small enough that many rounds run
//! by regions, up to the most regions a round takes. And the slots do not depend on the
//! number of threads.
mod common;
use common::*;
use proptest::prelude::*;
use sphcover_core::random::SplitMix64;
use sphcover_tetra::{RegularTriangulation, TriangulationParams, VertexStatus};

/// Every round of at least an eighth of `region_points` points by regions of about that many.
fn by_regions(seed: u64, region_points: usize) -> TriangulationParams {
    TriangulationParams {
        seed,
        parallel_from: 0,
        region_points,
    }
}

/// One point after another.
fn sequential(seed: u64) -> TriangulationParams {
    TriangulationParams {
        seed,
        parallel_from: usize::MAX,
        ..Default::default()
    }
}

fn tets_and_status(t: &RegularTriangulation) -> (Vec<[u32; 4]>, Vec<VertexStatus>) {
    let tets: Vec<[u32; 4]> = t.finite_tets().map(|c| t.tet(c)).collect();
    (canonical(&tets), t.vertex_status().to_vec())
}

/// Valid by brute force, and the sequential construction's tetrahedra and statuses.
fn assert_same_as_sequential(p: &[[f64; 3]], w: &[f64], params: &TriangulationParams) {
    let parallel = RegularTriangulation::new(p, w, params).unwrap();
    parallel.check_validity().unwrap();
    let one_by_one = RegularTriangulation::new(p, w, &sequential(params.seed)).unwrap();
    assert!(tets_and_status(&parallel) == tets_and_status(&one_by_one));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn random_sets_by_regions_match_the_sequential_construction(
        n in 40usize..500,
        wmax in 0.0f64..0.02,
        region_points in 1usize..80,
        seed in 0u64..1000,
    ) {
        let (p, w) = random_points(n, wmax, seed);
        assert_same_as_sequential(&p, &w, &by_regions(seed, region_points));
    }

    #[test]
    fn degenerate_grids_by_regions_match_the_sequential_construction(
        k in 0u64..1000,
        region_points in 1usize..40,
    ) {
        // Co-spherical and co-planar ties everywhere, hull facets with coplanar points.
        let (p, _) = grid(7, 0.25, 0.0);
        let mut rng = SplitMix64::new(k);
        let w: Vec<f64> = p
            .iter()
            .map(|_| [0.0, 0.0121, 4.0 * 0.0121][rng.below(3) as usize])
            .collect();
        assert_same_as_sequential(&p, &w, &by_regions(k, region_points));
    }
}

#[test]
fn default_rounds_by_regions_give_the_sequential_tetrahedra() {
    // Large enough for the default thresholds: the last rounds run by regions.
    let (p, w) = random_points(140_000, 1e-6, 3);
    let parallel = RegularTriangulation::new(&p, &w, &TriangulationParams::default()).unwrap();
    assert!(parallel.stats().deferred > 0);
    parallel.check_local_regularity().unwrap();
    let one_by_one = RegularTriangulation::new(&p, &w, &sequential(0x5eed_7e7a)).unwrap();
    assert!(tets_and_status(&parallel) == tets_and_status(&one_by_one));
}

#[test]
fn slots_by_regions_do_not_depend_on_the_thread_count() {
    let (p, w) = random_points(3000, 0.001, 5);
    let run = |threads: usize| {
        sphcover_core::on_threads(threads, || {
            let t = RegularTriangulation::new(&p, &w, &by_regions(1, 80)).unwrap();
            (t.tet_slots().collect::<Vec<_>>(), t.stats().deferred)
        })
    };
    let one = run(1);
    assert!(one.1 > 0);
    for threads in [2, 8] {
        assert!(run(threads) == one, "{threads} threads differ from one");
    }
}
