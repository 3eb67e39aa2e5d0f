//! The dual and overlap complexes against their brute-force definitions, Euler characteristics of known
//! unions, `TetMesh` edge rings, and marching tetrahedra.
mod common;
use common::*;
use proptest::prelude::*;
use sphcover_core::DVec3;
use sphcover_tetra::NO_TET;
use sphcover_tetra::predicates::{orient3d, orthocentre, orthocentre_power_sign};
use sphcover_tetra::{
    DualComplexParams, TetMesh, dual_complex, marching_tetrahedra, marching_tetrahedra_scalar,
    overlap_complex, overlap_complex_admitting,
};

fn no_shrink() -> DualComplexParams {
    DualComplexParams {
        shrink: 1.0,
        ..Default::default()
    }
}

/// Thesis §3.5 literally: four spheres form a tetrahedron when their orthocentre has power ≤ 0
/// and no other sphere has smaller power there. Returns the tetrahedra and the 4-subsets
/// too close to a tie to decide in floating point.
fn brute_force(c: &[DVec3], r: &[f64]) -> (Vec<[u32; 4]>, Vec<[u32; 4]>) {
    brute_force_cells(c, r, true)
}

/// The tetrahedra of the regular triangulation (no other sphere has smaller power at the
/// orthocentre), only those whose orthocentre has power ≤ 0 when `dual`; and the 4-subsets
/// too close to a tie to decide in floating point.
fn brute_force_cells(c: &[DVec3], r: &[f64], dual: bool) -> (Vec<[u32; 4]>, Vec<[u32; 4]>) {
    let n = c.len();
    let p: Vec<[f64; 3]> = c.iter().map(|x| x.to_array()).collect();
    let w: Vec<f64> = r.iter().map(|x| x * x).collect();
    let (mut sure, mut unsure) = (Vec::new(), Vec::new());
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                for l in k + 1..n {
                    let s = [i, j, k, l];
                    let mut pts = s.map(|x| &p[x]);
                    let o = orient3d(pts[0], pts[1], pts[2], pts[3]);
                    if o == 0 {
                        continue;
                    }
                    if o < 0 {
                        pts.swap(0, 1);
                    }
                    let ws = s.map(|x| w[x]);
                    let mut ws = ws;
                    if o < 0 {
                        ws.swap(0, 1);
                    }
                    if dual && orthocentre_power_sign(pts, ws) > 0 {
                        continue;
                    }
                    let (x, pw) = orthocentre(pts, ws).unwrap();
                    let scale = 1e-9 * (1.0 + pw.abs());
                    let mut empty = true;
                    let mut close = false;
                    for m in 0..n {
                        if s.contains(&m) {
                            continue;
                        }
                        let d: f64 = (0..3).map(|a| (x[a] - p[m][a]).powi(2)).sum::<f64>() - w[m];
                        if d < pw - scale {
                            empty = false;
                        } else if d < pw + scale {
                            close = true;
                        }
                    }
                    let t = s.map(|x| x as u32);
                    if close {
                        unsure.push(t);
                    } else if empty {
                        sure.push(t);
                    }
                }
            }
        }
    }
    (sure, unsure)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn dual_complex_equals_brute_force(n in 5usize..40, seed in 0u64..10_000) {
        let (c, r) = random_cover(n, seed);
        let dc = match dual_complex(&c, &r, &no_shrink()) {
            Ok(d) => d,
            Err(e) => return Err(TestCaseError::fail(format!("{e}"))),
        };
        let ours = canonical(&dc.tets);
        let (sure, unsure) = brute_force(&c, &r);
        for t in &sure {
            prop_assert!(ours.binary_search(t).is_ok(), "missing {:?}", t);
        }
        for t in &ours {
            prop_assert!(sure.contains(t) || unsure.contains(t), "extra {:?}", t);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// The overlap complex is the triangulation's tetrahedra whose balls overlap pairwise,
    /// and holds the dual complex.
    #[test]
    fn overlap_complex_equals_brute_force(n in 5usize..40, seed in 0u64..10_000) {
        let (c, r) = random_cover(n, seed);
        let (overlap, dual) = match (overlap_complex(&c, &r, &no_shrink()), dual_complex(&c, &r, &no_shrink())) {
            (Ok(o), Ok(d)) => (canonical(&o.tets), canonical(&d.tets)),
            (Err(e), _) | (_, Err(e)) => return Err(TestCaseError::fail(format!("{e}"))),
        };
        for t in &dual {
            prop_assert!(overlap.binary_search(t).is_ok(), "dual tetrahedron {:?} missing", t);
        }
        let (cells, unsure) = brute_force_cells(&c, &r, false);
        for t in &cells {
            if overlap_margin(&c, &r, t, 1.0) == Some(true) {
                prop_assert!(overlap.binary_search(t).is_ok(), "missing {:?}", t);
            }
        }
        for t in &overlap {
            prop_assert!(unsure.contains(t) || (cells.contains(t) && overlap_margin(&c, &r, t, 1.0) != Some(false)), "extra {:?}", t);
        }
    }

    /// The admitting overlap complex is the overlap complex and the triangulation's other
    /// tetrahedra whose balls, grown twice, overlap pairwise and that the predicate admits.
    #[test]
    fn admitting_overlap_complex_equals_brute_force(
        n in 5usize..40,
        seed in 0u64..10_000,
        parity in 0u32..2,
    ) {
        let (c, r) = random_cover(n, seed);
        // A property of the sorted cell, whatever order the triangulation lists it in.
        let admitted = |t: [u32; 4]| {
            let mut s = t;
            s.sort_unstable();
            (s[0] + 2 * s[1] + 3 * s[2] + s[3]) % 2 == parity
        };
        let ours = match overlap_complex_admitting(&c, &r, &no_shrink(), 2.0, admitted) {
            Ok(o) => canonical(&o.tets),
            Err(e) => return Err(TestCaseError::fail(format!("{e}"))),
        };
        let (cells, unsure) = brute_force_cells(&c, &r, false);
        for t in &cells {
            let expected = match (overlap_margin(&c, &r, t, 1.0), overlap_margin(&c, &r, t, 2.0)) {
                (Some(true), _) => Some(true),
                (Some(false), Some(grown)) => Some(grown && admitted(*t)),
                _ => None,
            };
            if let Some(expected) = expected {
                prop_assert_eq!(ours.binary_search(t).is_ok(), expected, "{:?}", t);
            }
        }
        for t in &ours {
            prop_assert!(cells.contains(t) || unsure.contains(t), "extra {:?}", t);
        }
    }
}

/// Whether the balls of `t`, radii times `growth`, overlap pairwise, with a margin either
/// side; `None` near a tie.
fn overlap_margin(c: &[DVec3], r: &[f64], t: &[u32; 4], growth: f64) -> Option<bool> {
    let mut all = true;
    for a in 0..4 {
        for b in a + 1..4 {
            let (i, j) = (t[a] as usize, t[b] as usize);
            let reach = growth * (r[i] + r[j]);
            let gap = c[i].distance(c[j]) - reach;
            if gap.abs() < 1e-9 * reach {
                return None;
            }
            all &= gap < 0.0;
        }
    }
    Some(all)
}

/// Balls of radius `r` at `centres`.
fn euler(centres: &[DVec3], r: f64) -> i64 {
    let radii = vec![r; centres.len()];
    let dc = dual_complex(centres, &radii, &no_shrink()).unwrap();
    TetMesh::from_dual_complex(&dc).euler_characteristic()
}

#[test]
fn euler_characteristic_of_known_unions() {
    // A solid ball made of many overlapping balls: χ = 1.
    let (p, _) = random_points(300, 0.0, 3);
    let ball: Vec<DVec3> = p
        .iter()
        .map(|x| DVec3::from_array(*x) - DVec3::splat(0.5))
        .filter(|x| x.length() < 0.5)
        .collect();
    assert_eq!(euler(&ball, 0.2), 1);

    // A ring (solid torus) of balls: χ = 0.
    let mut ring = Vec::new();
    for i in 0..60 {
        let a = i as f64 / 60.0 * std::f64::consts::TAU;
        for j in 0..6 {
            let b = j as f64 / 6.0 * std::f64::consts::TAU;
            let rr = 1.0 + 0.15 * b.cos();
            ring.push(DVec3::new(rr * a.cos(), rr * a.sin(), 0.15 * b.sin()));
        }
    }
    assert_eq!(euler(&ring, 0.16), 0);

    // A spherical shell of balls: χ = 2.
    let mut shell = Vec::new();
    let m = 400;
    for layer in [0.9, 1.1] {
        for i in 0..m {
            // Fibonacci sphere.
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / m as f64;
            let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let s = (1.0 - z * z).sqrt();
            shell.push(DVec3::new(s * phi.cos(), s * phi.sin(), z) * layer);
        }
    }
    assert_eq!(euler(&shell, 0.2), 2);
}

fn octree_fixture_mesh() -> (Vec<DVec3>, TetMesh) {
    let (c, r) = read_spheres("octree_torus_d6.spheres.txt");
    let dc = dual_complex(&c, &r, &DualComplexParams::default()).unwrap();
    (c, TetMesh::from_dual_complex(&dc))
}

#[test]
fn edge_rings_are_ordered_rotations() {
    let (c, mesh) = octree_fixture_mesh();
    let pos = |v: u32| c[mesh.vertices[v as usize] as usize].to_array();
    let mut ring_entries = 0;
    for (e, &[a, b]) in mesh.edges.iter().enumerate() {
        assert!(a < b);
        let ring = mesh.edge_ring(e as u32);
        ring_entries += ring.len();
        assert!(!ring.is_empty());
        for (k, &t) in ring.iter().enumerate() {
            let cell = mesh.tets[t as usize];
            assert!(cell.contains(&a) && cell.contains(&b));
            assert!(mesh.tet_edges[t as usize].contains(&(e as u32)));
            let next = if k + 1 < ring.len() {
                Some(ring[k + 1])
            } else if mesh.edge_ring_closed[e] {
                Some(ring[0])
            } else {
                None
            };
            // (a, b, c, d) positive, the next tetrahedron shares (a, b, d).
            let others: Vec<u32> = cell.iter().copied().filter(|&x| x != a && x != b).collect();
            let (cc, d) = if orient3d(&pos(a), &pos(b), &pos(others[0]), &pos(others[1])) > 0 {
                (others[0], others[1])
            } else {
                (others[1], others[0])
            };
            let pc = cell.iter().position(|&x| x == cc).unwrap();
            match next {
                Some(n) => {
                    assert_eq!(mesh.tet_neighbours[t as usize][pc], n);
                    assert!(mesh.tets[n as usize].contains(&d));
                }
                None => assert_eq!(mesh.tet_neighbours[t as usize][pc], NO_TET),
            }
        }
        if !mesh.edge_ring_closed[e] {
            // An open ring starts at a boundary face.
            let t = ring[0];
            let cell = mesh.tets[t as usize];
            let others: Vec<u32> = cell.iter().copied().filter(|&x| x != a && x != b).collect();
            let d = if orient3d(&pos(a), &pos(b), &pos(others[0]), &pos(others[1])) > 0 {
                others[1]
            } else {
                others[0]
            };
            let pd = cell.iter().position(|&x| x == d).unwrap();
            assert_eq!(mesh.tet_neighbours[t as usize][pd], NO_TET);
        }
    }
    assert_eq!(ring_entries, 6 * mesh.tets.len());
    // Vertex → edge incidence.
    for v in 0..mesh.vertices.len() as u32 {
        for &e in mesh.edges_of_vertex(v) {
            assert!(mesh.edges[e as usize].contains(&v));
        }
    }
    assert_eq!(mesh.vertex_edges.len(), 2 * mesh.edges.len());
    assert_eq!(mesh.find_edge(mesh.edges[5][1], mesh.edges[5][0]), Some(5));
    assert_eq!(mesh.euler_characteristic(), 0, "a solid torus");
}

/// Every undirected edge of `tris` is used once in each direction (closed, consistently
/// oriented) or, with `allow_boundary`, at most once in each.
fn check_orientation(tris: &[[u32; 3]], allow_boundary: bool) {
    let mut directed = std::collections::HashMap::new();
    for t in tris {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "directed edge {a}->{b} used {n} times");
        if !allow_boundary {
            assert!(directed.contains_key(&(b, a)), "edge {a}-{b} not closed");
        }
    }
}

#[test]
fn marching_a_sphere_in_the_torus_free_grid() {
    // A grid cover of a cube; the iso-surface of |x − m| − R is a closed, outward surface.
    let (p, _) = grid(12, 1.0 / 11.0, 0.0);
    let c: Vec<DVec3> = p.iter().map(|x| DVec3::from_array(*x)).collect();
    let r = vec![0.75 * 3f64.sqrt() / 11.0; c.len()];
    let dc = dual_complex(&c, &r, &DualComplexParams::default()).unwrap();
    let mesh = TetMesh::from_dual_complex(&dc);
    let pos: Vec<DVec3> = mesh.vertices.iter().map(|&v| c[v as usize]).collect();
    let centre = DVec3::splat(0.5);
    let val: Vec<f64> = pos.iter().map(|x| (*x - centre).length() - 0.3).collect();
    let s = marching_tetrahedra_scalar(&mesh, &pos, &val, None).unwrap();
    check_orientation(&s.triangles, false);
    for v in &s.vertices {
        assert!(((*v - centre).length() - 0.3).abs() < 0.02);
    }
    // Outward: the enclosed signed volume is positive and close to the ball's.
    let vol: f64 = s
        .triangles
        .iter()
        .map(|t| {
            let [a, b, cc] = t.map(|i| s.vertices[i as usize] - centre);
            a.dot(b.cross(cc)) / 6.0
        })
        .sum();
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.027;
    assert!(vol > 0.9 * exact && vol < 1.01 * exact, "{vol} vs {exact}");
    // χ of a sphere.
    let edges = s.triangles.len() * 3 / 2;
    assert_eq!(
        s.vertices.len() as i64 - edges as i64 + s.triangles.len() as i64,
        2
    );
    assert_eq!(s.vertex_edges.len(), s.vertices.len());
}

#[test]
fn marching_with_labels_places_vertices_by_rule() {
    let (c, mesh) = octree_fixture_mesh();
    let pos: Vec<DVec3> = mesh.vertices.iter().map(|&v| c[v as usize]).collect();
    // Labels from a plane, values from a different plane: some cut edges have equal signs.
    let labels: Vec<bool> = pos.iter().map(|x| x.z < 0.5).collect();
    let val: Vec<f64> = pos.iter().map(|x| x.z - 0.45).collect();
    let s = marching_tetrahedra_scalar(&mesh, &pos, &val, Some(&labels)).unwrap();
    check_orientation(&s.triangles, true);
    for (k, &e) in s.vertex_edges.iter().enumerate() {
        let [a, b] = mesh.edges[e as usize];
        assert_ne!(labels[a as usize], labels[b as usize]);
        let (fa, fb) = (val[a as usize], val[b as usize]);
        let v = s.vertices[k];
        if (fa < 0.0) != (fb < 0.0) {
            assert!((v.z - 0.45).abs() < 1e-12);
        } else {
            let end = if fa.abs() <= fb.abs() { a } else { b };
            assert_eq!(v, pos[end as usize]);
        }
    }
    // A generic caller rule and a length check.
    let mid = marching_tetrahedra(&mesh, &labels, |_, i, o| {
        (pos[i as usize] + pos[o as usize]) * 0.5
    })
    .unwrap();
    assert_eq!(mid.triangles.len(), s.triangles.len());
    assert!(marching_tetrahedra(&mesh, &labels[1..], |_, _, _| DVec3::ZERO).is_err());
}
