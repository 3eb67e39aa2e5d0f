//! Validity of the regular triangulation on random and degenerate inputs.
mod common;
use common::*;
use proptest::prelude::*;
use sphcover_tetra::predicates::orient3d;
use sphcover_tetra::{RegularTriangulation, TetraError, TriangulationParams, VertexStatus};

fn build(p: &[[f64; 3]], w: &[f64]) -> Result<RegularTriangulation, TetraError> {
    RegularTriangulation::new(p, w, &TriangulationParams::default())
}

/// Sum of finite tetrahedron volumes (must equal the hull volume; exact on integer grids).
fn volume(t: &RegularTriangulation) -> f64 {
    t.finite_tets()
        .map(|c| {
            let [a, b, cc, d] = t.tet(c).map(|v| t.point_of(v));
            let e = |x: [f64; 3]| [x[0] - a[0], x[1] - a[1], x[2] - a[2]];
            let (u, v, w) = (e(b), e(cc), e(d));
            u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                + u[2] * (v[0] * w[1] - v[1] * w[0])
        })
        .sum::<f64>()
        / 6.0
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn random_weighted_sets_are_valid(n in 4usize..300, wmax in 0.0f64..0.05, seed in 0u64..1000) {
        let (p, w) = random_points(n, wmax, seed);
        let t = build(&p, &w).unwrap();
        prop_assert!(t.check_validity().is_ok(), "{:?}", t.check_validity());
    }

    #[test]
    fn grids_with_random_weights_are_valid(n in 2usize..6, k in 0u64..1000) {
        // Few distinct weights: many exact ties between equal spheres.
        let (p, _) = grid(n, 0.5, 0.0);
        let mut rng = sphcover_core::random::SplitMix64::new(k);
        let w: Vec<f64> = p.iter().map(|_| [0.0, 0.0625, 0.25][rng.below(3) as usize]).collect();
        let t = build(&p, &w).unwrap();
        prop_assert!(t.check_validity().is_ok(), "{:?}", t.check_validity());
    }
}

#[test]
fn random_2000_is_valid_and_deterministic() {
    let (p, w) = random_points(2000, 0.002, 42);
    let t = build(&p, &w).unwrap();
    t.check_validity().unwrap();
    assert!(t.stats().hidden > 0, "the weights should hide some points");
    let again = build(&p, &w).unwrap();
    assert!(t.tet_slots().eq(again.tet_slots()));
    assert!((volume(&t) - volume(&again)).abs() == 0.0);
}

#[test]
fn grid_30_cubed_equal_spheres() {
    // 27,000 co-spherical points: every cube's corners tie. Brute force is too slow here;
    // check orientation, adjacency (inside `check_local`) and the total volume.
    let (p, w) = grid(30, 1.0, 0.75);
    let t = build(&p, &w).unwrap();
    assert_eq!(t.stats().hidden, 0);
    for c in t.finite_tets() {
        let q = t.tet(c).map(|v| p[v as usize]);
        assert_eq!(orient3d(&q[0], &q[1], &q[2], &q[3]), 1);
    }
    assert_eq!(volume(&t), 29f64.powi(3));
    // Every cube is split into 6 tetrahedra, as CGAL's perturbation does.
    assert_eq!(t.stats().finite_tets, 6 * 29 * 29 * 29);
    t.check_local_regularity().unwrap();
}

#[test]
fn co_spherical_points() {
    // All integer points on the sphere x² + y² + z² = 81, plus the centre.
    let mut p = vec![[0.0, 0.0, 0.0]];
    for x in -9i32..=9 {
        for y in -9i32..=9 {
            for z in -9i32..=9 {
                if x * x + y * y + z * z == 81 {
                    p.push([x as f64, y as f64, z as f64]);
                }
            }
        }
    }
    for wc in [0.0, 81.0, 100.0] {
        let mut w = vec![0.0; p.len()];
        w[0] = wc;
        let t = build(&p, &w).unwrap();
        t.check_validity().unwrap();
        // With weight 81 at the centre, every sphere point ties with it.
        if wc == 100.0 {
            assert_eq!(t.vertex_status()[0], VertexStatus::Vertex);
        }
    }
}

#[test]
fn co_planar_sets() {
    // A planar grid plus apexes on both sides: the hull has large coplanar facets.
    let mut p = Vec::new();
    for i in 0..8 {
        for j in 0..8 {
            p.push([i as f64, j as f64, 0.0]);
        }
    }
    p.push([3.5, 3.5, 2.0]);
    let w = vec![0.0; p.len()];
    build(&p, &w).unwrap().check_validity().unwrap();
    p.push([3.5, 3.5, -2.0]);
    let w = vec![0.3; p.len()];
    build(&p, &w).unwrap().check_validity().unwrap();
    // Only the plane: no tetrahedron exists.
    let flat: Vec<[f64; 3]> = p[..64].to_vec();
    assert!(matches!(
        build(&flat, &vec![0.0; 64]),
        Err(TetraError::NotFullDimensional { dimension: 2, .. })
    ));
}

#[test]
fn duplicated_centres() {
    let (mut p, mut w) = random_points(200, 0.001, 5);
    // Equal duplicates and heavier duplicates.
    for i in 0..20 {
        p.push(p[i]);
        w.push(w[i]);
        p.push(p[i + 20]);
        w.push(w[i + 20] + 0.01);
    }
    let t = build(&p, &w).unwrap();
    t.check_validity().unwrap();
    let s = t.vertex_status();
    for i in 0..20 {
        assert_eq!(
            s[200 + 2 * i],
            VertexStatus::Duplicate,
            "equal copy kept the first"
        );
        assert_eq!(s[i + 20], VertexStatus::Duplicate, "lighter copy dropped");
        assert_ne!(s[201 + 2 * i], VertexStatus::Duplicate);
    }
    assert_eq!(t.stats().duplicates, 40);
}

#[test]
fn lines_and_tiny_inputs_are_typed_errors() {
    let line: Vec<[f64; 3]> = (0..10).map(|i| [i as f64, 2.0 * i as f64, 0.5]).collect();
    assert!(matches!(
        build(&line, &[0.0; 10]),
        Err(TetraError::NotFullDimensional { dimension: 1, .. })
    ));
    assert!(matches!(
        build(&[], &[]),
        Err(TetraError::NotFullDimensional { dimension: 0, .. })
    ));
    let three = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert!(matches!(
        build(&three, &[0.0; 3]),
        Err(TetraError::NotFullDimensional { dimension: 2, .. })
    ));
    let same = [[1.0, 1.0, 1.0]; 5];
    assert!(matches!(
        build(&same, &[0.0; 5]),
        Err(TetraError::NotFullDimensional {
            dimension: 0,
            distinct: 1
        })
    ));
    let four = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let t = build(&four, &[0.0; 4]).unwrap();
    assert_eq!(t.stats().finite_tets, 1);
    t.check_validity().unwrap();
    assert!(matches!(
        build(&[[f64::NAN, 0.0, 0.0]], &[0.0]),
        Err(TetraError::InvalidPoint { index: 0 })
    ));
    assert!(matches!(
        build(&four, &[0.0; 3]),
        Err(TetraError::LengthMismatch { .. })
    ));
    assert!(matches!(
        build(&four, &[0.0, f64::INFINITY, 0.0, 0.0]),
        Err(TetraError::InvalidWeight { index: 1 })
    ));
}

#[test]
fn a_heavy_late_point_hides_earlier_vertices() {
    // Small spheres first (seeded order is random, so add many), then one huge sphere.
    let (mut p, mut w) = random_points(300, 0.0001, 9);
    p.push([0.5, 0.5, 0.5]);
    w.push(0.04);
    let t = build(&p, &w).unwrap();
    t.check_validity().unwrap();
    assert!(t.stats().hidden > 0);
}
