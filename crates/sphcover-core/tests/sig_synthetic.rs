//! The synthetic cover generators: lattice layout, seeded jitter, and the adaptive octree's
//! tiling, 2:1 balance and refinement rule.

use proptest::prelude::*;
use sphcover_core::synthetic::{
    AdaptiveCoverParams, MAX_OCTREE_DEPTH, Surface, SyntheticCover, SyntheticError,
    adaptive_surface_cover, jittered_grid, regular_grid,
};
use sphcover_core::{Aabb, DVec3};

fn unit_box() -> Aabb {
    Aabb {
        min: DVec3::splat(-0.5),
        max: DVec3::splat(0.5),
    }
}

#[test]
fn regular_grid_is_a_lattice() {
    let domain = Aabb {
        min: DVec3::new(0.0, 1.0, -2.0),
        max: DVec3::new(1.0, 1.5, -1.0),
    };
    let cover = regular_grid(domain, 0.25, 0.9).unwrap();
    assert_eq!(cover.len(), 5 * 3 * 5);
    assert!(cover.radii.iter().all(|&r| r == 0.9 * 0.25));
    assert_eq!(cover.centres[0], domain.min);
    assert_eq!(cover.centres[1], domain.min + DVec3::new(0.25, 0.0, 0.0));
    assert_eq!(cover.centres[5], domain.min + DVec3::new(0.0, 0.25, 0.0));
    assert_eq!(*cover.centres.last().unwrap(), domain.max);
    assert!(cover.centres.iter().all(|&c| domain.contains(c)));
}

proptest! {
    #[test]
    fn jittered_grid_stays_near_the_lattice(
        seed in any::<u64>(),
        spacing in 0.05f64..0.5,
        radius_factor in 0.5f64..2.0,
        jitter in 0.0f64..0.99,
    ) {
        let lattice = regular_grid(unit_box(), spacing, radius_factor).unwrap();
        let cover = jittered_grid(unit_box(), spacing, radius_factor, jitter, seed).unwrap();
        prop_assert_eq!(cover.len(), lattice.len());
        let radius = radius_factor * spacing;
        for (k, (c, r)) in cover.centres.iter().zip(&cover.radii).enumerate() {
            let offset = (*c - lattice.centres[k]).abs();
            prop_assert!(offset.max_element() <= jitter * spacing * (1.0 + 1e-12));
            prop_assert!(*r > 0.0);
            prop_assert!((*r - radius).abs() <= jitter * radius * (1.0 + 1e-12));
        }
        let again = jittered_grid(unit_box(), spacing, radius_factor, jitter, seed).unwrap();
        prop_assert_eq!(&again, &cover);
    }
}

#[test]
fn jitter_depends_on_the_seed_only() {
    let a = jittered_grid(unit_box(), 0.1, 1.0, 0.3, 1).unwrap();
    let b = jittered_grid(unit_box(), 0.1, 1.0, 0.3, 2).unwrap();
    assert_ne!(a, b);
    let none = jittered_grid(unit_box(), 0.1, 1.0, 0.0, 1).unwrap();
    assert_eq!(none, regular_grid(unit_box(), 0.1, 1.0).unwrap());
}

#[test]
fn grid_parameters_are_checked() {
    let bad = |r: Result<SyntheticCover, SyntheticError>| {
        assert!(
            matches!(r, Err(SyntheticError::InvalidParameter(_))),
            "{r:?}"
        );
    };
    bad(regular_grid(unit_box(), 0.0, 1.0));
    bad(regular_grid(unit_box(), f64::NAN, 1.0));
    bad(regular_grid(unit_box(), -0.1, 1.0));
    bad(regular_grid(unit_box(), 0.1, 0.0));
    bad(jittered_grid(unit_box(), 0.1, 1.0, 1.0, 0));
    bad(jittered_grid(unit_box(), 0.1, 1.0, -0.1, 0));
    assert_eq!(
        regular_grid(Aabb::EMPTY, 0.1, 1.0),
        Err(SyntheticError::InvalidDomain)
    );
    assert!(matches!(
        regular_grid(unit_box(), 1e-6, 1.0),
        Err(SyntheticError::TooManySupports { .. })
    ));
}

/// Leaf cell of a support of an adaptive cover: its depth and its integer coordinates at that
/// depth, recovered from the centre and the radius `0.75 × diagonal`.
fn leaf_cells(cover: &SyntheticCover, params: &AdaptiveCoverParams) -> Vec<(u32, [i64; 3])> {
    let size = params.domain.longest_edge();
    let origin = params.domain.centre() - DVec3::splat(0.5 * size);
    cover
        .centres
        .iter()
        .zip(&cover.radii)
        .map(|(c, r)| {
            let edge = r / (params.radius_factor * 3f64.sqrt());
            let depth = (size / edge).log2().round() as u32;
            let width = size / (1u64 << depth) as f64;
            assert!(
                (edge / width - 1.0).abs() < 1e-9,
                "radius is not 0.75 × diagonal"
            );
            let a = (*c - origin) / width - DVec3::splat(0.5);
            let coords = [a.x.round(), a.y.round(), a.z.round()];
            assert!((a - DVec3::from(coords)).abs().max_element() < 1e-6);
            (depth, coords.map(|v| v as i64))
        })
        .collect()
}

/// Closed cubes of two leaves share at least a point.
fn touching(a: (u32, [i64; 3]), b: (u32, [i64; 3])) -> bool {
    let depth = a.0.max(b.0);
    let (sa, sb) = (1i64 << (depth - a.0), 1i64 << (depth - b.0));
    (0..3).all(|k| {
        let (lo_a, hi_a) = (a.1[k] * sa, (a.1[k] + 1) * sa);
        let (lo_b, hi_b) = (b.1[k] * sb, (b.1[k] + 1) * sb);
        lo_a <= hi_b && lo_b <= hi_a
    })
}

fn overlapping(a: (u32, [i64; 3]), b: (u32, [i64; 3])) -> bool {
    let depth = a.0.max(b.0);
    let (sa, sb) = (1i64 << (depth - a.0), 1i64 << (depth - b.0));
    (0..3).all(|k| a.1[k] * sa < (b.1[k] + 1) * sb && b.1[k] * sb < (a.1[k] + 1) * sa)
}

fn check_octree(params: &AdaptiveCoverParams) {
    let cover = adaptive_surface_cover(params).unwrap();
    let leaves = leaf_cells(&cover, params);
    // The leaves tile the root cube: their volumes add up and no two overlap.
    let volume: f64 = leaves.iter().map(|&(d, _)| 0.125f64.powi(d as i32)).sum();
    assert!((volume - 1.0).abs() < 1e-12, "volume {volume}");
    for (k, &a) in leaves.iter().enumerate() {
        assert!(a.0 >= params.min_depth.min(params.max_depth) && a.0 <= params.max_depth);
        for &b in &leaves[k + 1..] {
            assert!(!overlapping(a, b), "{a:?} overlaps {b:?}");
            if touching(a, b) {
                assert!(a.0.abs_diff(b.0) <= 1, "unbalanced: {a:?} touches {b:?}");
            }
        }
    }
    // A leaf above the maximum depth was not refined: the surface is not near its centre.
    // (With `band ≥ 1` a cell near the surface always has a parent near the surface, so
    // top-down refinement cannot miss it; a narrower band may.)
    let size = params.domain.longest_edge();
    for (&(depth, _), &c) in leaves.iter().zip(&cover.centres) {
        if depth < params.max_depth && params.band >= 1.0 {
            let half_diagonal = 0.5 * 3f64.sqrt() * size / (1u64 << depth) as f64;
            assert!(params.surface.signed_distance(c).abs() >= params.band * half_diagonal);
        }
    }
    // And the surface is resolved at the maximum depth.
    assert!(leaves.iter().any(|&(d, _)| d == params.max_depth));
}

#[test]
fn adaptive_octree_tiles_balances_and_refines() {
    check_octree(&AdaptiveCoverParams {
        max_depth: 4,
        ..AdaptiveCoverParams::default()
    });
    check_octree(&AdaptiveCoverParams {
        domain: Aabb {
            min: DVec3::new(1.0, 2.0, 3.0),
            max: DVec3::new(3.0, 2.5, 3.5),
        },
        surface: Surface::Torus {
            centre: DVec3::new(2.0, 2.2, 3.1),
            major_radius: 0.5,
            minor_radius: 0.2,
        },
        min_depth: 0,
        max_depth: 5,
        band: 1.5,
        radius_factor: 0.75,
    });
    check_octree(&AdaptiveCoverParams {
        min_depth: 1,
        max_depth: 5,
        band: 0.5,
        ..AdaptiveCoverParams::default()
    });
    check_octree(&AdaptiveCoverParams {
        min_depth: 3,
        max_depth: 3,
        ..AdaptiveCoverParams::default()
    });
}

#[test]
fn adaptive_cover_spans_radius_levels_and_is_deterministic() {
    let params = AdaptiveCoverParams {
        max_depth: 6,
        ..AdaptiveCoverParams::default()
    };
    let cover = adaptive_surface_cover(&params).unwrap();
    // The documented count of the default sphere at depth 6.
    assert!((35_000..37_000).contains(&cover.len()), "{}", cover.len());
    let r_min = cover.radii.iter().copied().fold(f64::INFINITY, f64::min);
    let r_max = cover.radii.iter().copied().fold(0.0, f64::max);
    // Leaves from depth 4 to 6: the sphere fills most of the box, and the 2:1 balance
    // refines the rest down to depth 4.
    assert_eq!(r_max / r_min, 4.0);
    for threads in [1, 3] {
        let again = sphcover_core::on_threads(threads, || adaptive_surface_cover(&params).unwrap());
        assert_eq!(again, cover);
    }
}

#[test]
fn adaptive_parameters_are_checked() {
    let bad = |params: AdaptiveCoverParams| {
        let r = adaptive_surface_cover(&params);
        assert!(
            matches!(r, Err(SyntheticError::InvalidParameter(_))),
            "{r:?}"
        );
    };
    let base = AdaptiveCoverParams::default();
    bad(AdaptiveCoverParams {
        max_depth: MAX_OCTREE_DEPTH + 1,
        ..base
    });
    bad(AdaptiveCoverParams {
        min_depth: 5,
        max_depth: 4,
        ..base
    });
    bad(AdaptiveCoverParams { band: -1.0, ..base });
    bad(AdaptiveCoverParams {
        radius_factor: f64::NAN,
        ..base
    });
    bad(AdaptiveCoverParams {
        surface: Surface::Sphere {
            centre: DVec3::ZERO,
            radius: 0.0,
        },
        ..base
    });
    bad(AdaptiveCoverParams {
        surface: Surface::Torus {
            centre: DVec3::INFINITY,
            major_radius: 0.3,
            minor_radius: 0.1,
        },
        ..base
    });
    assert_eq!(
        adaptive_surface_cover(&AdaptiveCoverParams {
            domain: Aabb::EMPTY,
            ..base
        }),
        Err(SyntheticError::InvalidDomain)
    );
    // Uniform refinement to depth 11 would be 8^11 supports.
    assert!(matches!(
        adaptive_surface_cover(&AdaptiveCoverParams {
            min_depth: 11,
            max_depth: 11,
            ..base
        }),
        Err(SyntheticError::TooManySupports { .. })
    ));
    let root = adaptive_surface_cover(&AdaptiveCoverParams {
        min_depth: 0,
        max_depth: 0,
        ..base
    })
    .unwrap();
    assert_eq!(root.centres, vec![DVec3::ZERO]);
    assert_eq!(root.radii, vec![0.75 * 3f64.sqrt()]);
}
