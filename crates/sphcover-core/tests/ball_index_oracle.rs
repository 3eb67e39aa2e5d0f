//! `BallIndex` against the brute-force scan it replaced, on random and degenerate ball sets.

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use sphcover_core::synthetic::{AdaptiveCoverParams, adaptive_surface_cover};
use sphcover_core::{BallIndex, BallIndexError, DVec3};

/// The interim implementation, kept as the oracle: every ball with
/// `c_j.distance(x) < scale * r_j + extra`, ascending.
fn brute_within(centres: &[DVec3], radii: &[f64], x: DVec3, scale: f64, extra: f64) -> Vec<u32> {
    let mut out: Vec<u32> = centres
        .iter()
        .zip(radii)
        .enumerate()
        .filter(|(_, (c, r))| c.distance(x) < scale * **r + extra)
        .map(|(j, _)| j as u32)
        .collect();
    out.sort_unstable();
    out
}

/// What the index visits, in visiting order.
fn visited(index: &BallIndex, x: DVec3, scale: f64, extra: f64) -> Vec<u32> {
    let mut out = Vec::new();
    index.for_each_within(x, scale, extra, |j| out.push(j));
    out
}

/// Balls in `got` but not in `want`, and in `want` but not in `got` (both ascending).
fn difference(got: &[u32], want: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let extra = got.iter().filter(|j| want.binary_search(j).is_err());
    let missing = want.iter().filter(|j| got.binary_search(j).is_err());
    (extra.copied().collect(), missing.copied().collect())
}

/// Checks `for_each_within` (as a set, each ball once) and `containing` against the oracle,
/// at the given points and at points placed just inside, on and just outside the query
/// sphere `‖x − c_j‖ = scale·r_j + extra` of a few balls for every `(scale, extra)`.
fn check_queries(
    centres: &[DVec3],
    radii: &[f64],
    queries: &[DVec3],
    scales: &[(f64, f64)],
    seed: u64,
) -> Result<(), TestCaseError> {
    let index = BallIndex::new(centres, radii);
    prop_assert_eq!(index.len(), centres.len());
    prop_assert_eq!(index.is_empty(), centres.is_empty());
    let mut rng = Pcg64::seed_from_u64(seed);
    // The largest balls set the reach of their level, so their query spheres are where a
    // reach computed too short would show.
    let mut by_radius: Vec<usize> = (0..centres.len()).collect();
    by_radius.sort_by(|&a, &b| radii[b].total_cmp(&radii[a]));
    by_radius.truncate(12);
    let mut out = Vec::new();
    for &(scale, extra) in scales {
        let mut points = queries.to_vec();
        for k in 0..(if centres.is_empty() { 0 } else { 36 }) {
            let j = if k % 3 == 0 {
                by_radius[k / 3 % by_radius.len()]
            } else {
                rng.random_range(0..centres.len())
            };
            let dir = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize_or(DVec3::Z);
            let t = scale * radii[j] + extra;
            for factor in [1.0 - 1e-3, 1.0 - 1e-12, 1.0, 1.0 + 1e-12] {
                points.push(centres[j] + dir * (t * factor));
            }
            points.push(centres[j] + DVec3::X * t);
        }
        for &x in &points {
            let mut got = Vec::new();
            index.for_each_within(x, scale, extra, |j| got.push(j));
            let len = got.len();
            got.sort_unstable();
            got.dedup();
            prop_assert_eq!(got.len(), len, "a ball was visited twice");
            let want = brute_within(centres, radii, x, scale, extra);
            let (extra_balls, missing) = difference(&got, &want);
            prop_assert!(
                extra_balls.is_empty() && missing.is_empty(),
                "x = {}, scale = {}, extra = {}: {} found, extra {:?}, missing {:?}",
                x,
                scale,
                extra,
                want.len(),
                extra_balls,
                missing
            );
            index.containing(x, &mut out);
            let want = brute_within(centres, radii, x, 1.0, 0.0);
            let (extra_balls, missing) = difference(&out, &want);
            prop_assert!(
                extra_balls.is_empty() && missing.is_empty(),
                "containing({}): extra {:?}, missing {:?}",
                x,
                extra_balls,
                missing
            );
            prop_assert!(out.windows(2).all(|w| w[0] < w[1]), "not ascending");
        }
    }
    Ok(())
}

/// How the centres of a random ball set are laid out.
#[derive(Clone, Copy, Debug)]
enum Layout {
    /// Uniform in a box of the given edge.
    Spread(f64),
    /// Gaussian-ish clusters of the given spread around a few random points.
    Clustered(f64),
    /// Few distinct centres, many balls on each.
    Coincident,
}

fn layout() -> impl Strategy<Value = Layout> {
    prop_oneof![
        (0.1f64..100.0).prop_map(Layout::Spread),
        (1e-4f64..0.1).prop_map(Layout::Clustered),
        Just(Layout::Coincident),
    ]
}

/// A random ball set: radii log-uniform over three orders of magnitude (`r_min·[1, 1000]`),
/// a few radii zero, and query points near the balls (on their spheres, inside, outside)
/// and anywhere in the box.
fn ball_set(seed: u64, n: usize, layout: Layout, r_min: f64) -> (Vec<DVec3>, Vec<f64>, Vec<DVec3>) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut unit = || DVec3::new(rng.random(), rng.random(), rng.random()) * 2.0 - DVec3::ONE;
    let anchors: Vec<DVec3> = (0..4).map(|_| unit() * 10.0).collect();
    let mut rng = Pcg64::seed_from_u64(seed ^ 0x5eed);
    let mut centres = Vec::with_capacity(n);
    let mut radii = Vec::with_capacity(n);
    for k in 0..n {
        let jitter = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let c = match layout {
            Layout::Spread(edge) => jitter * 0.5 * edge,
            Layout::Clustered(spread) => {
                anchors[k % anchors.len()] + jitter * jitter.abs() * spread
            }
            Layout::Coincident => anchors[k % 3],
        };
        centres.push(c);
        let r = if rng.random_bool(0.03) {
            0.0
        } else {
            r_min * 10f64.powf(rng.random_range(0.0..3.0))
        };
        radii.push(r);
    }
    let mut queries = Vec::new();
    for _ in 0..24 {
        if n > 0 {
            let j = rng.random_range(0..n);
            let dir = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize_or(DVec3::X);
            let t: f64 = rng.random_range(0.0..1.5);
            queries.push(centres[j] + dir * radii[j] * t);
        }
        queries.push(DVec3::new(
            rng.random_range(-20.0..20.0),
            rng.random_range(-20.0..20.0),
            rng.random_range(-20.0..20.0),
        ));
    }
    (centres, radii, queries)
}

const SCALES: &[(f64, f64)] = &[
    (1.0, 0.0),
    (0.7, 0.0),
    (2.0, 0.0),
    (0.7, 0.01),
    (1.0, 0.5),
    (0.5, 3.0),
    (4.0, 1e-9),
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn queries_equal_brute_force(
        seed in any::<u64>(),
        n in 0usize..300,
        layout in layout(),
        r_min in prop_oneof![Just(1e-3), Just(0.01), Just(0.1), 1e-4f64..1.0],
        scale in 0.1f64..3.0,
        extra in prop_oneof![Just(0.0), 0.0f64..0.1, 0.0f64..10.0],
    ) {
        let (centres, radii, queries) = ball_set(seed, n, layout, r_min);
        let mut scales = SCALES.to_vec();
        scales.push((scale, extra));
        check_queries(&centres, &radii, &queries, &scales, seed)?;
    }
}

#[test]
fn adaptive_cover_queries_equal_brute_force() {
    let params = AdaptiveCoverParams {
        min_depth: 1,
        max_depth: 5,
        ..AdaptiveCoverParams::default()
    };
    let cover = adaptive_surface_cover(&params).unwrap();
    assert!(cover.len() > 1000);
    let mut rng = Pcg64::seed_from_u64(3);
    let queries: Vec<DVec3> = (0..300)
        .map(|_| {
            DVec3::new(
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
            )
        })
        .chain(cover.centres.iter().step_by(97).copied())
        .collect();
    check_queries(&cover.centres, &cover.radii, &queries, SCALES, 1).unwrap();
}

#[test]
fn empty_index_visits_nothing() {
    let index = BallIndex::new(&[], &[]);
    assert!(index.is_empty());
    assert_eq!(index.len(), 0);
    assert!(visited(&index, DVec3::ZERO, 1.0, 1e300).is_empty());
    let mut out = vec![7];
    index.containing(DVec3::ONE, &mut out);
    assert!(out.is_empty());
}

#[test]
fn identical_balls_are_all_found() {
    let centres = vec![DVec3::new(1.0, 2.0, 3.0); 1000];
    let radii = vec![0.5; 1000];
    let index = BallIndex::new(&centres, &radii);
    let mut out = Vec::new();
    index.containing(DVec3::new(1.2, 2.0, 3.0), &mut out);
    assert_eq!(out, (0..1000).collect::<Vec<u32>>());
    index.containing(DVec3::new(1.5, 2.0, 3.0), &mut out);
    assert!(out.is_empty(), "the boundary is not inside");
}

#[test]
fn zero_radius_contains_nothing_but_is_reached_with_extra() {
    let centres = vec![DVec3::ZERO, DVec3::X];
    let radii = vec![0.0, 0.0];
    let index = BallIndex::new(&centres, &radii);
    let mut out = Vec::new();
    index.containing(DVec3::ZERO, &mut out);
    assert!(out.is_empty());
    let mut got = visited(&index, DVec3::ZERO, 1.0, 0.5);
    got.sort_unstable();
    assert_eq!(got, vec![0]);
    got = visited(&index, DVec3::new(0.5, 0.0, 0.0), 1.0, 0.5 + 1e-12);
    got.sort_unstable();
    assert_eq!(got, vec![0, 1]);
}

#[test]
fn huge_coordinate_spreads() {
    // Tiny balls near the origin, one far away, and a cluster at 1e12: the grid must not
    // blow up and the answers must stay exact.
    let mut rng = Pcg64::seed_from_u64(11);
    let mut centres = Vec::new();
    let mut radii = Vec::new();
    for _ in 0..500 {
        centres.push(DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ));
        radii.push(rng.random_range(1e-3..1e-1));
    }
    for _ in 0..200 {
        centres.push(
            DVec3::splat(1e12)
                + DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ),
        );
        radii.push(rng.random_range(1e-2..1.0));
    }
    centres.push(DVec3::new(-1e300, 1e300, 0.0));
    radii.push(1.0);
    centres.push(DVec3::new(f64::MAX, -f64::MAX, f64::MAX));
    radii.push(1e300);
    let queries: Vec<DVec3> = centres
        .iter()
        .step_by(7)
        .copied()
        .chain([
            DVec3::ZERO,
            DVec3::splat(1e12),
            DVec3::new(-1e300, 1e300, 0.5),
        ])
        .collect();
    check_queries(&centres, &radii, &queries, SCALES, 2).unwrap();
}

#[test]
fn reaches_without_finite_square() {
    // Radii of 1e199 and reaches of 1e200, whose squares overflow (as do the squared
    // distances of the literal test beyond about 1e154): the index must still agree.
    let mut rng = Pcg64::seed_from_u64(9);
    let centres: Vec<DVec3> = (0..1500)
        .map(|_| {
            DVec3::new(
                rng.random_range(-1e201..1e201),
                0.0,
                rng.random_range(-2e201..2e201),
            )
        })
        .collect();
    let radii = vec![1e199; centres.len()];
    let queries = [DVec3::ZERO, DVec3::new(3e200, 0.0, -2e200)];
    check_queries(&centres, &radii, &queries, &[(1.0, 1e200), (3.0, 0.0)], 4).unwrap();
}

#[test]
fn non_finite_inputs_match_the_literal_test() {
    let centres = vec![
        DVec3::ZERO,
        DVec3::new(f64::NAN, 0.0, 0.0),
        DVec3::new(f64::INFINITY, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(3.0, 0.0, 0.0),
        DVec3::new(4.0, 0.0, 0.0),
    ];
    let radii = vec![
        1.0,
        1.0,
        1.0,
        f64::INFINITY,
        f64::NAN,
        -0.5,
        f64::NEG_INFINITY,
    ];
    let queries = [
        DVec3::ZERO,
        DVec3::new(3.0, 0.0, 0.0),
        DVec3::new(1e200, 0.0, 0.0),
        DVec3::new(f64::NAN, 0.0, 0.0),
        DVec3::new(f64::INFINITY, 0.0, 0.0),
    ];
    let index = BallIndex::new(&centres, &radii);
    for x in queries {
        for (scale, extra) in [
            (1.0, 0.0),
            (1.0, 1.0),
            (1.0, f64::INFINITY),
            (f64::INFINITY, 0.0),
            (-1.0, 2.0),
            (0.0, 0.0),
            (1.0, f64::NAN),
            (f64::NAN, 1.0),
        ] {
            let mut got = visited(&index, x, scale, extra);
            got.sort_unstable();
            assert_eq!(
                got,
                brute_within(&centres, &radii, x, scale, extra),
                "x = {x}, scale = {scale}, extra = {extra}"
            );
        }
    }
}

#[test]
fn mismatched_lengths_are_an_error() {
    assert_eq!(
        BallIndex::try_new(&[DVec3::ZERO], &[]).unwrap_err(),
        BallIndexError::LengthMismatch {
            centres: 1,
            radii: 0
        }
    );
}

#[test]
fn visiting_order_is_the_same_for_any_thread_count() {
    let params = AdaptiveCoverParams {
        max_depth: 5,
        ..AdaptiveCoverParams::default()
    };
    let cover = adaptive_surface_cover(&params).unwrap();
    let orders: Vec<Vec<u32>> = [1, 2, 8]
        .into_iter()
        .map(|threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let index = pool.install(|| BallIndex::new(&cover.centres, &cover.radii));
            cover
                .centres
                .iter()
                .step_by(31)
                .flat_map(|&x| visited(&index, x, 1.0, 0.01))
                .collect()
        })
        .collect();
    assert!(!orders[0].is_empty());
    assert_eq!(orders[0], orders[1]);
    assert_eq!(orders[0], orders[2]);
}

/// Many balls per radius level, so the grid is fine and its bounds decide often.
#[test]
fn dense_levels_near_the_boundaries() {
    let mut rng = Pcg64::seed_from_u64(5);
    let n = 4000;
    let centres: Vec<DVec3> = (0..n)
        .map(|_| {
            DVec3::new(
                rng.random_range(0.0..1.0),
                rng.random_range(0.0..1.0),
                rng.random_range(0.0..1.0),
            )
        })
        .collect();
    // Two levels: one radius octave around 0.03 and one around 0.003.
    let radii: Vec<f64> = (0..n)
        .map(|k| rng.random_range(0.03..0.059) * if k % 2 == 0 { 1.0 } else { 0.1 })
        .collect();
    let queries: Vec<DVec3> = centres.iter().step_by(41).copied().collect();
    check_queries(&centres, &radii, &queries, SCALES, 3).unwrap();
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Dense random sets within a single radius octave: fine grids, many candidates near
    /// cell boundaries.
    #[test]
    fn dense_single_octave_equals_brute_force(
        seed in any::<u64>(),
        n in 500usize..3000,
        r in 0.01f64..0.1,
        scale in 0.1f64..3.0,
        extra in prop_oneof![Just(0.0), 0.0f64..0.05],
    ) {
        let mut rng = Pcg64::seed_from_u64(seed);
        let centres: Vec<DVec3> = (0..n)
            .map(|_| DVec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let radii: Vec<f64> = (0..n).map(|_| r * rng.random_range(1.0..2.0)).collect();
        check_queries(&centres, &radii, &[], &[(scale, extra), (1.0, 0.0)], seed)?;
    }
}
