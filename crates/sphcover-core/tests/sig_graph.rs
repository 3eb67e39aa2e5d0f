//! The sphere intersection graph against the all-pairs oracle, its CSR invariants, and its
//! independence from the thread count.

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use sphcover_core::synthetic::{
    AdaptiveCoverParams, Surface, adaptive_surface_cover, jittered_grid,
};
use sphcover_core::{Aabb, DVec3, SigError, SphereIntersectionGraph, balls_nested};

/// All pairs `i < j` with `‖c_i − c_j‖ < s·(r_i + r_j)`, the test written out literally.
fn brute_edges(centres: &[DVec3], radii: &[f64], shrink: f64) -> Vec<(u32, u32)> {
    let mut edges = Vec::new();
    for i in 0..centres.len() {
        for j in i + 1..centres.len() {
            let reach = shrink * (radii[i] + radii[j]);
            if (centres[i] - centres[j]).length_squared() < reach * reach {
                edges.push((i as u32, j as u32));
            }
        }
    }
    edges
}

/// CSR invariants: offsets start at 0 and never decrease, rows strictly ascending, no self
/// loops, symmetric, and the accessors agree with each other.
fn check_invariants(graph: &SphereIntersectionGraph) -> Result<(), TestCaseError> {
    let n = graph.len();
    let offsets = graph.offsets();
    prop_assert_eq!(offsets.len(), n + 1);
    prop_assert_eq!(offsets[0], 0);
    prop_assert_eq!(offsets[n] as usize, graph.neighbour_array().len());
    prop_assert_eq!(graph.neighbour_array().len(), 2 * graph.num_edges());
    for i in 0..n {
        prop_assert!(offsets[i] <= offsets[i + 1]);
        let row = graph.neighbours(i);
        prop_assert_eq!(row.len(), graph.degree(i));
        prop_assert!(
            row.windows(2).all(|w| w[0] < w[1]),
            "row {} not ascending",
            i
        );
        prop_assert!(!row.contains(&(i as u32)), "self loop at {}", i);
        for &j in row {
            prop_assert!((j as usize) < n);
            prop_assert!(
                graph
                    .neighbours(j as usize)
                    .binary_search(&(i as u32))
                    .is_ok(),
                "{} ~ {} but not {} ~ {}",
                i,
                j,
                j,
                i
            );
        }
    }
    let edges: Vec<(u32, u32)> = graph.edges().collect();
    prop_assert_eq!(edges.len(), graph.num_edges());
    prop_assert!(edges.windows(2).all(|w| w[0] < w[1]));
    prop_assert!(edges.iter().all(|&(i, j)| i < j));
    Ok(())
}

fn check_against_oracle(
    centres: &[DVec3],
    radii: &[f64],
    shrink: f64,
) -> Result<SphereIntersectionGraph, TestCaseError> {
    let graph = SphereIntersectionGraph::build(centres, radii, shrink)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(graph.len(), centres.len());
    prop_assert_eq!(graph.shrink(), shrink);
    check_invariants(&graph)?;
    let want = brute_edges(centres, radii, shrink);
    let got: Vec<(u32, u32)> = graph.edges().collect();
    if got != want {
        let extra: Vec<_> = got
            .iter()
            .filter(|e| want.binary_search(e).is_err())
            .collect();
        let missing: Vec<_> = want
            .iter()
            .filter(|e| got.binary_search(e).is_err())
            .collect();
        return Err(TestCaseError::fail(format!(
            "shrink {shrink}: extra edges {extra:?}, missing edges {missing:?}"
        )));
    }
    Ok(graph)
}

/// Random balls: centres uniform in a box of edge `spread`, or stacked on a few points;
/// radii log-uniform over `r_min·[1, 1000]`, some zero.
fn random_balls(
    seed: u64,
    n: usize,
    spread: f64,
    stacked: bool,
    r_min: f64,
) -> (Vec<DVec3>, Vec<f64>) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let anchors = [DVec3::ZERO, DVec3::splat(0.3), DVec3::new(0.1, -0.2, 0.05)];
    let centres = (0..n)
        .map(|k| {
            if stacked && k % 2 == 0 {
                anchors[k % 3]
            } else {
                DVec3::new(rng.random(), rng.random(), rng.random()) * spread
            }
        })
        .collect();
    let radii = (0..n)
        .map(|_| {
            if rng.random_bool(0.05) {
                0.0
            } else {
                r_min * 10f64.powf(rng.random_range(0.0..3.0))
            }
        })
        .collect();
    (centres, radii)
}

fn shrink_factor() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.6), Just(0.7), Just(0.8), Just(1.0), 0.05f64..1.5]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn random_balls_equal_brute_force(
        seed in any::<u64>(),
        n in 0usize..400,
        spread in prop_oneof![Just(1.0), 0.01f64..100.0],
        stacked in any::<bool>(),
        r_min in prop_oneof![Just(1e-3), 1e-4f64..0.1],
        shrink in shrink_factor(),
    ) {
        let (centres, radii) = random_balls(seed, n, spread, stacked, r_min);
        check_against_oracle(&centres, &radii, shrink)?;
    }

    #[test]
    fn jittered_grids_equal_brute_force(
        seed in any::<u64>(),
        spacing in 0.08f64..0.3,
        radius_factor in 0.5f64..1.6,
        jitter in 0.0f64..0.5,
        shrink in shrink_factor(),
    ) {
        let domain = Aabb { min: DVec3::ZERO, max: DVec3::ONE };
        let cover = jittered_grid(domain, spacing, radius_factor, jitter, seed).unwrap();
        check_against_oracle(&cover.centres, &cover.radii, shrink)?;
    }
}

#[test]
fn adaptive_covers_equal_brute_force() {
    for (surface, shrink) in [
        (
            Surface::Sphere {
                centre: DVec3::new(0.05, -0.02, 0.01),
                radius: 0.3,
            },
            0.7,
        ),
        (
            Surface::Torus {
                centre: DVec3::ZERO,
                major_radius: 0.25,
                minor_radius: 0.1,
            },
            1.0,
        ),
    ] {
        let params = AdaptiveCoverParams {
            surface,
            min_depth: 1,
            max_depth: 5,
            ..AdaptiveCoverParams::default()
        };
        let cover = adaptive_surface_cover(&params).unwrap();
        assert!(cover.len() > 1500, "{} supports", cover.len());
        let graph = check_against_oracle(&cover.centres, &cover.radii, shrink).unwrap();
        assert!(graph.mean_degree() > 10.0);
    }
}

#[test]
fn graph_is_identical_for_any_thread_count() {
    // Enough supports for many row chunks.
    let params = AdaptiveCoverParams {
        max_depth: 6,
        ..AdaptiveCoverParams::default()
    };
    let cover = adaptive_surface_cover(&params).unwrap();
    assert!(cover.len() > 20_000);
    let graphs: Vec<SphereIntersectionGraph> = [1, 2, 8]
        .into_iter()
        .map(|threads| {
            sphcover_core::on_threads(threads, || {
                SphereIntersectionGraph::build(&cover.centres, &cover.radii, 0.7)
            })
            .unwrap()
        })
        .collect();
    check_invariants(&graphs[0]).unwrap();
    assert!(graphs[0].num_edges() > 0);
    assert_eq!(graphs[0], graphs[1]);
    assert_eq!(graphs[0], graphs[2]);
}

#[test]
fn symmetric_despite_rounding() {
    // Pairs at distance s·(r_i + r_j) up to rounding, in both index orders: the two
    // directions must agree exactly.
    let mut rng = Pcg64::seed_from_u64(17);
    let mut centres = Vec::new();
    let mut radii = Vec::new();
    for _ in 0..500 {
        let c = DVec3::new(rng.random(), rng.random(), rng.random()) * 1e3;
        let (r1, r2): (f64, f64) = (rng.random_range(0.1..1.0), rng.random_range(0.1..1.0));
        let dir = DVec3::new(rng.random(), rng.random(), rng.random()).normalize_or(DVec3::X);
        centres.push(c);
        radii.push(r1);
        centres.push(c + dir * (0.7 * (r1 + r2)));
        radii.push(r2);
    }
    let graph = check_against_oracle(&centres, &radii, 0.7).unwrap();
    assert!(graph.num_edges() > 0);
}

#[test]
fn degenerate_inputs() {
    let empty = SphereIntersectionGraph::build(&[], &[], 0.7).unwrap();
    assert!(empty.is_empty());
    assert_eq!(empty.offsets(), &[0]);
    assert_eq!(empty.num_edges(), 0);
    assert_eq!(empty.edges().count(), 0);
    assert_eq!(empty.mean_degree(), 0.0);

    // Identical balls: the complete graph.
    let centres = vec![DVec3::ONE; 50];
    let graph = SphereIntersectionGraph::build(&centres, &[0.1; 50], 0.7).unwrap();
    assert_eq!(graph.num_edges(), 50 * 49 / 2);
    check_invariants(&graph).unwrap();

    // Points (radius 0) never meet, even when they coincide.
    let graph = SphereIntersectionGraph::build(&centres, &[0.0; 50], 1.0).unwrap();
    assert_eq!(graph.num_edges(), 0);
}

#[test]
fn invalid_inputs_are_typed_errors() {
    let c = [DVec3::ZERO, DVec3::X];
    let r = [1.0, 1.0];
    assert_eq!(
        SphereIntersectionGraph::build(&c, &r[..1], 0.7),
        Err(SigError::LengthMismatch {
            centres: 2,
            radii: 1
        })
    );
    for shrink in [0.0, -0.7, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            SphereIntersectionGraph::build(&c, &r, shrink),
            Err(SigError::InvalidShrink { .. })
        ));
    }
    assert!(matches!(
        SphereIntersectionGraph::build(&[DVec3::ZERO, DVec3::NAN], &r, 0.7),
        Err(SigError::InvalidCentre { index: 1, .. })
    ));
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            SphereIntersectionGraph::build(&c, &[1.0, bad], 0.7),
            Err(SigError::InvalidRadius { index: 1, .. })
        ));
    }
}

#[test]
fn nested_balls() {
    let (a, b) = (DVec3::ZERO, DVec3::new(0.5, 0.0, 0.0));
    assert!(balls_nested(a, 1.0, b, 0.5)); // internally tangent
    assert!(balls_nested(b, 0.5, a, 1.0));
    assert!(balls_nested(a, 1.0, b, 0.2));
    assert!(balls_nested(a, 1.0, a, 1.0)); // the same ball
    assert!(!balls_nested(a, 1.0, b, 0.6)); // crossing spheres
    assert!(!balls_nested(a, 0.1, DVec3::X, 0.1)); // disjoint
}

proptest! {
    #[test]
    fn nested_is_symmetric_and_geometric(
        c1 in prop::array::uniform3(-1.0f64..1.0),
        c2 in prop::array::uniform3(-1.0f64..1.0),
        r1 in 0.0f64..2.0,
        r2 in 0.0f64..2.0,
    ) {
        let (c1, c2) = (DVec3::from(c1), DVec3::from(c2));
        prop_assert_eq!(balls_nested(c1, r1, c2, r2), balls_nested(c2, r2, c1, r1));
        let d = c1.distance(c2);
        // Nested pairs have no intersection circle; crossing pairs do.
        if d > (r1 - r2).abs() * (1.0 + 1e-12) {
            prop_assert!(!balls_nested(c1, r1, c2, r2));
        }
        if r1 >= r2 && d + r2 <= r1 * (1.0 - 1e-12) {
            prop_assert!(balls_nested(c1, r1, c2, r2));
        }
    }
}

#[test]
fn dense_equal_radii_equal_brute_force() {
    // One radius, so every ball sets its level's reach and candidates crowd cell bounds.
    let mut rng = Pcg64::seed_from_u64(23);
    let centres: Vec<DVec3> = (0..4000)
        .map(|_| DVec3::new(rng.random(), rng.random(), rng.random()))
        .collect();
    let radii = vec![0.04; centres.len()];
    for shrink in [0.6, 0.7, 1.0] {
        check_against_oracle(&centres, &radii, shrink).unwrap();
    }
}
