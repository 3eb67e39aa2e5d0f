//! The input domain of the triangulation (`src/regular/domain.rs`): scaling an input by an
//! exact power of two `2^k` (weights by `2^(2k)`) gives the same tetrahedra, in the same order,
//! with the same hidden points, or the same refusal; inputs no scaling brings into the exact
//! range are refused with the true reason.
mod common;
use common::*;
use proptest::prelude::*;
use sphcover_core::DVec3;
use sphcover_core::random::SplitMix64;
use sphcover_tetra::{
    DualComplex, DualComplexParams, RegularTriangulation, TetraError, TriangulationParams,
    VertexStatus, dual_complex,
};

type Point = [f64; 3];

/// `x · 2^k` when that is exact and stays in the normal range (or `x` is zero), else `None`.
/// The product is formed in two steps, each by a normal power of two; when `x` and the
/// result are normal so is the intermediate value, and neither step rounds.
fn scaled(x: f64, k: i32) -> Option<f64> {
    if x == 0.0 {
        return Some(x);
    }
    let pow2 = |e: i32| f64::from_bits(((e + 1023) as u64) << 52);
    let half = k / 2;
    let y = x * pow2(half) * pow2(k - half);
    (x.is_normal() && y.is_normal()).then_some(y)
}

fn scaled_points(p: &[Point], k: i32) -> Option<Vec<Point>> {
    p.iter()
        .map(|x| Some([scaled(x[0], k)?, scaled(x[1], k)?, scaled(x[2], k)?]))
        .collect()
}

fn scaled_values(v: &[f64], k: i32) -> Option<Vec<f64>> {
    v.iter().map(|&x| scaled(x, k)).collect()
}

/// Everything a triangulation answers with, in its own order.
#[derive(Debug, PartialEq)]
struct Triangulated {
    slots: Vec<[u32; 4]>,
    neighbours: Vec<[u32; 4]>,
    status: Vec<VertexStatus>,
    finite_tets: usize,
}

fn triangulated(t: &RegularTriangulation) -> Triangulated {
    Triangulated {
        slots: t.tet_slots().collect(),
        neighbours: (0..t.num_slots() as u32).map(|s| t.neighbours(s)).collect(),
        status: t.vertex_status().to_vec(),
        finite_tets: t.stats().finite_tets,
    }
}

/// The dual complex's tetrahedra, neighbours and statuses, in its own order.
fn complex(dc: &DualComplex) -> (Vec<[u32; 4]>, Vec<[u32; 4]>, Vec<VertexStatus>) {
    (dc.tets.clone(), dc.neighbours.clone(), dc.status.clone())
}

/// Same outcome: equal results, or refusals for the same reason.
fn same_outcome<T: PartialEq + std::fmt::Debug>(
    a: &Result<T, TetraError>,
    b: &Result<T, TetraError>,
) -> Result<(), String> {
    match (a, b) {
        (Ok(x), Ok(y)) if x == y => Ok(()),
        (Err(x), Err(y)) if std::mem::discriminant(x) == std::mem::discriminant(y) => Ok(()),
        (Ok(_), Ok(_)) => Err("different results".into()),
        (x, y) => Err(format!("{:?} vs {:?}", x.as_ref().err(), y.as_ref().err())),
    }
}

fn triangulate(p: &[Point], w: &[f64]) -> Result<RegularTriangulation, TetraError> {
    RegularTriangulation::new(p, w, &TriangulationParams::default())
}

fn complex_of(c: &[Point], r: &[f64], shrink: f64) -> Result<DualComplex, TetraError> {
    let c: Vec<DVec3> = c.iter().map(|&x| DVec3::from_array(x)).collect();
    let params = DualComplexParams {
        shrink,
        ..Default::default()
    };
    dual_complex(&c, r, &params)
}

/// A small sphere set of one of several kinds: uniform random; a grid of equal or
/// few-level spheres (every cube co-spherical); integer points on a sphere around a centre;
/// random points snapped to a coarse dyadic grid with repeated centres; random points with
/// one point whose coordinates are far too finely resolved (refused at every scale).
fn sphere_set(kind: u8, n: usize, seed: u64) -> (Vec<Point>, Vec<f64>) {
    let mut rng = SplitMix64::new(seed);
    let mut u = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    match kind {
        0 | 4 => {
            let mut p: Vec<Point> = (0..n).map(|_| [u(), u(), u()]).collect();
            let mut r: Vec<f64> = (0..n).map(|_| 0.02 + 0.1 * u()).collect();
            if kind == 4 {
                p.push([0.5, 1e-250 * (1.0 + u()), 0.5]);
                r.push(0.05);
            }
            (p, r)
        }
        1 => {
            let m = 2 + n % 5;
            let h = [1.0, 0.5, 0.1, 3.0][n % 4];
            let (p, _) = grid(m, h, 0.0);
            let levels = [0.0, 0.5 * h, 0.75 * h, h];
            let equal = u() < 0.5;
            let r = p
                .iter()
                .map(|_| {
                    if equal {
                        0.9 * h
                    } else {
                        levels[(u() * 4.0) as usize]
                    }
                })
                .collect();
            (p, r)
        }
        2 => {
            let h = [1.0, 0.1, 0.37][n % 3];
            let mut p = vec![[0.0; 3]];
            for x in -9i32..=9 {
                for y in -9i32..=9 {
                    for z in -9i32..=9 {
                        if x * x + y * y + z * z == 81 {
                            p.push([x as f64 * h, y as f64 * h, z as f64 * h]);
                        }
                    }
                }
            }
            let centre = [0.0, 3.0 * h, 9.0 * h, 10.0 * h][n % 4];
            let mut r = vec![h; p.len()];
            r[0] = centre;
            (p, r)
        }
        _ => {
            let snap = |x: f64| (x * 16.0).round() / 16.0;
            let p: Vec<Point> = (0..n).map(|_| [snap(u()), snap(u()), snap(u())]).collect();
            let r = p
                .iter()
                .map(|_| [0.0, 0.0625, 0.125][(u() * 3.0) as usize])
                .collect();
            (p, r)
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Scaled copies give the same triangulation (slots, neighbours, statuses) and the same
    /// dual complex, or the same refusal, for every `k` where the scaled input is exact.
    #[test]
    fn power_of_two_scalings_change_nothing(
        kind in 0u8..5,
        n in 10usize..200,
        seed in any::<u64>(),
        ks in prop::collection::vec(-1000i32..=1000, 6),
        shrink in prop::sample::select(vec![1.0, 0.75]),
    ) {
        let (p, r) = sphere_set(kind, n, seed);
        let w: Vec<f64> = r.iter().map(|x| x * x).collect();
        let base = triangulate(&p, &w);
        let base_tri = base.as_ref().map(triangulated).map_err(Clone::clone);
        let base_dc = complex_of(&p, &r, shrink).map(|dc| complex(&dc));
        if kind == 4 {
            prop_assert!(matches!(base, Err(TetraError::CoordinateSpan { .. })), "{:?}", base.err());
        } else {
            prop_assert!(base.is_ok() && base_dc.is_ok(), "{:?}", base.err());
        }
        let mut compared = 0;
        for &k in &ks {
            let Some(pk) = scaled_points(&p, k) else { continue };
            if let Some(wk) = scaled_values(&w, 2 * k) {
                let t = triangulate(&pk, &wk);
                if let Ok(t) = &t {
                    // The queries answer in the caller's units, exactly.
                    for v in 0..p.len() as u32 {
                        prop_assert_eq!(t.point_of(v), pk[v as usize]);
                        prop_assert_eq!(t.weight(v), wk[v as usize]);
                    }
                }
                let t = t.as_ref().map(triangulated).map_err(Clone::clone);
                prop_assert!(same_outcome(&base_tri, &t).is_ok(), "k = {}: {:?}", k, same_outcome(&base_tri, &t));
                compared += 1;
            }
            // From radii, the weights are formed after the scaling: no overflow of r² even
            // where the weights above would not fit.
            if let Some(rk) = scaled_values(&r, k) {
                let dc = complex_of(&pk, &rk, shrink).map(|dc| complex(&dc));
                prop_assert!(same_outcome(&base_dc, &dc).is_ok(), "k = {}: {:?}", k, same_outcome(&base_dc, &dc));
                compared += 1;
            }
        }
        // At least the scalings near 1 are always exact; far ones may fall out of f64, and
        // for kind 4 (a coordinate near 1e-250) any k below about -190 does.
        prop_assert!(compared > 0 || kind == 4 || ks.iter().all(|k| k.abs() > 700));
    }
}

/// `fixtures/tetra/random_3k` (3,000 spheres, 11,833 tetrahedra in CGAL's dual complex) and
/// the octree torus (14,960 spheres, exact ties) at `2^-1000`, `2^-400`, `2^-130`, `2^600`
/// and `2^1000`: the same tetrahedra in the same order as at scale 1.
#[test]
fn reference_sets_at_extreme_scales_give_the_same_tetrahedra() {
    for (name, ks) in [
        ("random_3k", &[-1000, -400, -130, 600, 1000][..]),
        ("octree_torus_d6", &[-400, 600][..]),
    ] {
        let (c, r) = read_spheres(&format!("{name}.spheres.txt"));
        let p: Vec<Point> = c.iter().map(|x| x.to_array()).collect();
        for shrink in [1.0, 0.75] {
            let base = complex_of(&p, &r, shrink).unwrap();
            if shrink == 1.0 {
                let reference = read_tets(&format!("{name}.tets.txt"));
                assert_eq!(canonical(&base.tets), reference, "{name}");
            }
            for &k in ks {
                let pk = scaled_points(&p, k).expect("the fixture scales exactly");
                let rk = scaled_values(&r, k).expect("the fixture scales exactly");
                let dc = complex_of(&pk, &rk, shrink).unwrap();
                assert_eq!(dc.tets.len(), base.tets.len(), "{name} x{shrink} at 2^{k}");
                assert!(complex(&dc) == complex(&base), "{name} x{shrink} at 2^{k}");
            }
        }
        // The triangulation from weights, where r²·2^(2k) is still an f64.
        let w: Vec<f64> = r.iter().map(|x| x * x).collect();
        let base = triangulated(&triangulate(&p, &w).unwrap());
        for k in [-400, -130, 300] {
            let t = triangulate(
                &scaled_points(&p, k).unwrap(),
                &scaled_values(&w, 2 * k).unwrap(),
            )
            .unwrap();
            assert!(triangulated(&t) == base, "{name} weights at 2^{k}");
        }
    }
}

fn unit_tetrahedron() -> Vec<Point> {
    vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ]
}

#[test]
fn coordinates_spanning_too_many_orders_are_refused_with_that_reason() {
    let mut p = unit_tetrahedron();
    p.push([1e-300, 0.5, 0.5]);
    let err = triangulate(&p, &[0.0; 5]).unwrap_err();
    let TetraError::CoordinateSpan {
        orders,
        max_orders,
        largest,
        largest_point,
        finest_point,
        ..
    } = err
    else {
        panic!("{err:?}");
    };
    // 1e-300 carries digits down to about 1e-316.
    assert_eq!((orders, max_orders), (316, 74));
    assert_eq!((largest, largest_point, finest_point), (1.0, 1, 4));
    let message = err.to_string();
    assert!(
        message.starts_with("coordinates span 316 orders of magnitude, from 1.000e0 (point 1)")
            && message.contains("(point 4)")
            && message.ends_with("the exact predicates support at most 74"),
        "{message}"
    );
    assert!(!message.contains("dimension"), "{message}");
    // The same reason through the dual complex.
    let err = complex_of(&p, &[0.5; 5], 0.75).unwrap_err();
    assert!(
        matches!(err, TetraError::CoordinateSpan { orders: 316, .. }),
        "{err:?}"
    );
}

#[test]
fn radii_out_of_scale_with_the_coordinates_are_refused_with_that_reason() {
    let mut p = unit_tetrahedron();
    p.push([0.25, 0.25, 0.25]);
    for (radius, too_large) in [(1e200, true), (1e-200, false)] {
        let mut r = vec![0.5; 5];
        r[4] = radius;
        let err = complex_of(&p, &r, 1.0).unwrap_err();
        let expected_radius = radius;
        assert!(
            matches!(err, TetraError::RadiusScale { index: 4, radius, too_large: t, .. }
                if radius == expected_radius && t == too_large),
            "{err:?}"
        );
        let message = err.to_string();
        let word = if too_large { "large" } else { "small" };
        assert!(
            message.starts_with(&format!("radius 4 ({radius:.3e}; weights are squared radii) is too {word} for coordinates from 1.000e0 down to the finest binary digit 2.5e-1")),
            "{message}"
        );
        assert!(!message.contains("dimension"), "{message}");
    }
    // Weights given directly: reported as the radius √w.
    let err = triangulate(&p, &[0.0, 0.0, 0.0, 0.0, 1e-300]).unwrap_err();
    assert!(
        matches!(err, TetraError::RadiusScale { index: 4, radius, too_large: false, .. }
            if (radius / 1e-150 - 1.0).abs() < 1e-15),
        "{err:?}"
    );
    // Radii the old range check refused, or whose squares underflow, are fine now.
    for radius in [1e-100, 1e50] {
        let mut r = vec![0.5; 5];
        r[4] = radius;
        complex_of(&p, &r, 0.75).unwrap();
    }
}

#[test]
fn huge_and_subnormal_inputs_triangulate_like_unit_ones() {
    // A 4³ grid of equal spheres covering each cube's centre (radius 7/8 > √3/2): 27 cubes
    // of 6 tetrahedra, with exact ties everywhere.
    let (p, _) = grid(4, 1.0, 0.0);
    let r = vec![0.875; p.len()];
    let base = complex(&complex_of(&p, &r, 1.0).unwrap());
    assert_eq!(base.0.len(), 6 * 27);
    // Times 2^-1070 every coordinate and radius is subnormal, exactly (a few bits each), and
    // the scaling into the exact range exceeds 2^1023; times 2^1000, r² overflows.
    for unit in [f64::from_bits(1 << 4), 2f64.powi(1000)] {
        let pk: Vec<Point> = p.iter().map(|x| x.map(|c| c * unit)).collect();
        let rk: Vec<f64> = r.iter().map(|x| x * unit).collect();
        let dc = complex_of(&pk, &rk, 1.0).unwrap();
        assert!(complex(&dc) == base, "unit {unit:e}");
    }
    // Coordinates up to 1e300 (the old range stopped at 1e20): the unit tetrahedron.
    let big: Vec<Point> = unit_tetrahedron()
        .iter()
        .map(|x| x.map(|c| c * 1e300))
        .collect();
    let t = triangulate(&big, &[0.0; 4]).unwrap();
    assert_eq!(t.stats().finite_tets, 1);
    assert_eq!(t.point_of(1), [1e300, 0.0, 0.0]);
}

#[test]
fn non_finite_input_is_still_refused() {
    let p = unit_tetrahedron();
    let mut bad = p.clone();
    bad[2][1] = f64::INFINITY;
    assert_eq!(
        triangulate(&bad, &[0.0; 4]).err(),
        Some(TetraError::InvalidPoint { index: 2 })
    );
    assert_eq!(
        complex_of(&bad, &[0.5; 4], 0.75).err(),
        Some(TetraError::InvalidPoint { index: 2 })
    );
    assert_eq!(
        triangulate(&p, &[0.0, 0.0, f64::NAN, 0.0]).err(),
        Some(TetraError::InvalidWeight { index: 2 })
    );
    assert_eq!(
        complex_of(&p, &[0.5, -0.5, 0.5, 0.5], 0.75).err(),
        Some(TetraError::InvalidWeight { index: 1 })
    );
    assert_eq!(
        complex_of(&p, &[0.5, 0.5, f64::INFINITY, 0.5], 0.75).err(),
        Some(TetraError::InvalidWeight { index: 2 })
    );
}
