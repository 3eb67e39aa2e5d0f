//! `PointIndex` against brute force: fixed-radius and k-nearest queries, on random clouds
//! with many duplicate coordinates (ties in distance and in split coordinates).

use proptest::prelude::*;
use sphcover_core::{DVec3, PointIndex};

/// Coordinates on a coarse grid, so that equal coordinates and equal distances are common.
fn grid_point() -> impl Strategy<Value = DVec3> {
    (0..8i32, 0..8i32, 0..8i32)
        .prop_map(|(x, y, z)| DVec3::new(x as f64, y as f64, z as f64) * 0.125)
}

fn any_point() -> impl Strategy<Value = DVec3> {
    prop_oneof![
        grid_point(),
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z)),
    ]
}

fn cloud() -> impl Strategy<Value = Vec<DVec3>> {
    prop::collection::vec(any_point(), 0..400)
}

fn brute_within(points: &[DVec3], x: DVec3, r: f64) -> Vec<u32> {
    (0..points.len() as u32)
        .filter(|&i| (points[i as usize] - x).length_squared() < r * r)
        .collect()
}

fn brute_nearest(points: &[DVec3], x: DVec3, k: usize) -> Vec<u32> {
    let mut all: Vec<(f64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| ((*p - x).length_squared(), i as u32))
        .collect();
    all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    all.into_iter().take(k).map(|(_, i)| i).collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn within_matches_brute_force(points in cloud(), x in any_point(), r in 0.0..1.5f64) {
        let index = PointIndex::new(&points).unwrap();
        let mut got = Vec::new();
        index.within(x, r, &mut got);
        prop_assert_eq!(&got, &brute_within(&points, x, r));
        // The visitors report the same set, each point once, with its own position.
        let mut visited = Vec::new();
        index.for_each_within(x, r, |i, p| {
            assert_eq!(p, points[i as usize]);
            visited.push(i);
        });
        visited.sort_unstable();
        prop_assert_eq!(visited, got);
    }

    #[test]
    fn nearest_k_matches_brute_force(
        points in cloud(),
        // Also queries well off the data, as from the empty cells of a cover's octree.
        x in prop_oneof![any_point(), any_point().prop_map(|p| 4.0 * p)],
        // Past 48 the search keeps its best points in a heap instead of a sorted list.
        k in prop_oneof![0usize..40, 40usize..160],
    ) {
        let index = PointIndex::new(&points).unwrap();
        let mut got = Vec::new();
        index.nearest_k(x, k, &mut got);
        prop_assert_eq!(got, brute_nearest(&points, x, k));
    }

    #[test]
    fn nearest_k_run_matches_single_queries(
        points in cloud(),
        extra in prop::collection::vec(any_point(), 0..40),
        k in 0usize..40,
        from_slots in any::<bool>(),
    ) {
        let index = PointIndex::new(&points).unwrap();
        // Slot order (the intended use: consecutive queries close together) or an arbitrary
        // sequence, with far jumps, a non-finite query and repeated queries.
        let mut queries: Vec<DVec3> = if from_slots {
            index.slot_points().to_vec()
        } else {
            points.clone()
        };
        queries.extend(&extra);
        queries.push(DVec3::new(f64::NAN, 0.0, 0.0));
        queries.extend(extra.iter().take(3));
        let mut seen = 0;
        index.nearest_k_run(&queries, k, |q, got| {
            assert_eq!(q, seen, "queries are visited in order");
            seen += 1;
            let mut expected = Vec::new();
            index.nearest_k_with_distances(queries[q], k, &mut expected);
            assert_eq!(got, &expected[..], "query {q} at {}", queries[q]);
        });
        prop_assert_eq!(seen, queries.len());
    }

    #[test]
    fn nearest_k_run_at_slots_matches_single_queries(
        points in cloud(),
        jumps in prop::collection::vec(any::<prop::sample::Index>(), 0..40),
        k in 0usize..60,
    ) {
        let index = PointIndex::new(&points).unwrap();
        // Every slot in order (the intended use), then arbitrary ones, repeats included.
        let mut slots: Vec<u32> = (0..index.len() as u32).collect();
        if !index.is_empty() {
            slots.extend(jumps.iter().map(|j| j.index(index.len()) as u32));
        }
        let mut seen = 0;
        index.nearest_k_run_at_slots(&slots, k, |q, got| {
            assert_eq!(q, seen, "queries are visited in order");
            seen += 1;
            let x = index.slot_points()[slots[q] as usize];
            let mut expected = Vec::new();
            index.nearest_k_with_distances(x, k, &mut expected);
            assert_eq!(got, &expected[..], "query {q} at slot {}", slots[q]);
        });
        prop_assert_eq!(seen, slots.len());
    }

    #[test]
    fn slot_order_is_a_permutation(points in cloud()) {
        let index = PointIndex::new(&points).unwrap();
        let mut order = index.order().to_vec();
        for (s, &i) in order.iter().enumerate() {
            prop_assert_eq!(index.slot_points()[s], points[i as usize]);
        }
        order.sort_unstable();
        prop_assert_eq!(order, (0..points.len() as u32).collect::<Vec<_>>());
    }
}

#[test]
#[should_panic(expected = "slot 3 out of range for 3 indexed points")]
fn nearest_k_run_at_slots_refuses_a_slot_out_of_range() {
    let index = PointIndex::new(&[DVec3::ZERO, DVec3::X, DVec3::Y]).unwrap();
    index.nearest_k_run_at_slots(&[0, 3], 2, |_, _| {});
}

#[test]
fn boundary_is_open_and_non_finite_points_are_skipped() {
    let points = [
        DVec3::ZERO,
        DVec3::X,
        DVec3::new(f64::NAN, 0.0, 0.0),
        DVec3::new(0.5, 0.0, 0.0),
        DVec3::splat(f64::INFINITY),
    ];
    let index = PointIndex::new(&points).unwrap();
    assert_eq!(index.len(), 3);
    assert_eq!(index.input_len(), 5);
    let mut out = Vec::new();
    index.within(DVec3::ZERO, 1.0, &mut out);
    assert_eq!(out, [0, 3], "a point at distance exactly r is outside");
    index.within(DVec3::ZERO, f64::INFINITY, &mut out);
    assert_eq!(out, [0, 1, 3]);
    index.within(DVec3::new(f64::NAN, 0.0, 0.0), 10.0, &mut out);
    assert!(out.is_empty());
    index.within(DVec3::ZERO, -1.0, &mut out);
    assert!(out.is_empty());
    index.nearest_k(DVec3::new(0.9, 0.0, 0.0), 10, &mut out);
    assert_eq!(out, [1, 3, 0]);
    // Equidistant points: the lower index wins.
    index.nearest_k(DVec3::new(0.25, 0.0, 0.0), 1, &mut out);
    assert_eq!(out, [0]);
}

#[test]
fn identical_points_and_large_clouds_are_handled() {
    let same = vec![DVec3::splat(0.3); 1000];
    let index = PointIndex::new(&same).unwrap();
    let mut out = Vec::new();
    index.nearest_k(DVec3::ZERO, 5, &mut out);
    assert_eq!(out, [0, 1, 2, 3, 4]);
    // A `k` past the number of points (here past any allocation) asks for all of them.
    index.nearest_k(DVec3::ZERO, usize::MAX / 2, &mut out);
    assert_eq!(out, (0..1000).collect::<Vec<u32>>());
    index.within(DVec3::splat(0.3), 1e-9, &mut out);
    assert_eq!(out.len(), 1000);

    // Large enough for the parallel build; the tree must not depend on the thread count.
    let n = 100_000;
    let points: Vec<DVec3> = (0..n)
        .map(|i| {
            let t = i as f64;
            DVec3::new(
                (t * 0.618).fract(),
                (t * 0.754).fract(),
                (t * 0.317).fract(),
            )
        })
        .collect();
    let build = |threads| sphcover_core::on_threads(threads, || PointIndex::new(&points).unwrap());
    let (a, b) = (build(1), build(2));
    assert_eq!(a.order(), b.order());
    let x = DVec3::splat(0.5);
    a.within(x, 0.05, &mut out);
    assert_eq!(out, brute_within(&points, x, 0.05));
    a.nearest_k(x, 20, &mut out);
    assert_eq!(out, brute_nearest(&points, x, 20));
}
