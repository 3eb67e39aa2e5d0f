//! `TetMesh` against a brute-force construction from the tetrahedra's vertex sets alone
//! (edges as sorted vertex pairs, rings from the tetrahedra sharing a triangle), and the same
//! mesh whatever the number of threads.
mod common;
use std::collections::{BTreeMap, BTreeSet};

use common::*;
use sphcover_core::on_threads;
use sphcover_tetra::{DualComplex, DualComplexParams, NO_TET, TetMesh, dual_complex};

/// Vertex position pairs of a tetrahedron's edges, in `TetMesh::tet_edges` order.
const PAIRS: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

/// The dual complex of `n` random spheres: for a few thousand, several tasks of the mesh's
/// per-vertex passes, a boundary (open rings) and an inside (closed rings).
fn random_complex(n: usize, seed: u64) -> DualComplex {
    let (c, r) = random_cover(n, seed);
    let params = DualComplexParams {
        shrink: 1.0,
        ..Default::default()
    };
    dual_complex(&c, &r, &params).unwrap()
}

fn is_even(p: [usize; 4]) -> bool {
    let mut inversions = 0;
    for i in 0..4 {
        for j in i + 1..4 {
            inversions += usize::from(p[i] > p[j]);
        }
    }
    inversions % 2 == 0
}

/// The mesh by definition, over the tetrahedra alone (no neighbour array).
struct Reference {
    vertices: Vec<u32>,
    tets: Vec<[u32; 4]>,
    /// Across the triangle opposite each vertex: the other tetrahedron on it, or `NO_TET`.
    neighbours: Vec<[u32; 4]>,
    edges: Vec<[u32; 2]>,
    tet_edges: Vec<[u32; 6]>,
    /// Per edge: its ring and whether it is closed.
    rings: Vec<(Vec<u32>, bool)>,
    /// Per vertex: its edges, ascending.
    vertex_edges: Vec<Vec<u32>>,
    /// Edges whose ring misses some of the tetrahedra around the edge (a non-manifold edge:
    /// they form several fans, and the ring is the one through the smallest tetrahedron).
    partial_rings: usize,
}

fn reference(tets: &[[u32; 4]]) -> Reference {
    let vertices: Vec<u32> = tets
        .iter()
        .flatten()
        .copied()
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    let tets: Vec<[u32; 4]> = tets
        .iter()
        .map(|t| t.map(|v| vertices.binary_search(&v).unwrap() as u32))
        .collect();
    let sorted_pair = |a: u32, b: u32| [a.min(b), a.max(b)];
    let edges: Vec<[u32; 2]> = tets
        .iter()
        .flat_map(|t| PAIRS.map(|[i, j]| sorted_pair(t[i], t[j])))
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    let edge_id = |a: u32, b: u32| edges.binary_search(&sorted_pair(a, b)).unwrap() as u32;
    let tet_edges: Vec<[u32; 6]> = tets
        .iter()
        .map(|t| PAIRS.map(|[i, j]| edge_id(t[i], t[j])))
        .collect();

    // The tetrahedra on each triangle (one or two), and around each edge.
    let mut triangle_tets: BTreeMap<[u32; 3], Vec<u32>> = BTreeMap::new();
    let mut edge_tets = vec![Vec::new(); edges.len()];
    for (ti, t) in tets.iter().enumerate() {
        for skip in 0..4 {
            let mut f: Vec<u32> = (0..4).filter(|&k| k != skip).map(|k| t[k]).collect();
            f.sort_unstable();
            triangle_tets
                .entry([f[0], f[1], f[2]])
                .or_default()
                .push(ti as u32);
        }
        for &e in &tet_edges[ti] {
            edge_tets[e as usize].push(ti as u32);
        }
    }
    let across = |t: u32, tri: [u32; 3]| -> Option<u32> {
        let mut f = tri;
        f.sort_unstable();
        triangle_tets[&f].iter().copied().find(|&u| u != t)
    };

    let neighbours: Vec<[u32; 4]> = tets
        .iter()
        .enumerate()
        .map(|(t, cell)| {
            std::array::from_fn(|skip| {
                let mut f = [0; 3];
                for (slot, k) in (0..4).filter(|&k| k != skip).enumerate() {
                    f[slot] = cell[k];
                }
                across(t as u32, f).unwrap_or(NO_TET)
            })
        })
        .collect();

    let mut rings = Vec::with_capacity(edges.len());
    let mut partial_rings = 0;
    for (e, &[a, b]) in edges.iter().enumerate() {
        // In tetrahedron `t`: the other two vertices `(c, d)` with `(a, b, c, d)` an even
        // permutation of its vertex order (positive); the rotation a → b goes from the
        // triangle (a, b, c) to (a, b, d), so the next tetrahedron shares (a, b, d).
        let others = |t: u32| -> (u32, u32) {
            let cell = tets[t as usize];
            let pos = |v: u32| cell.iter().position(|&x| x == v).unwrap();
            let rest: Vec<usize> = (0..4).filter(|&k| cell[k] != a && cell[k] != b).collect();
            if is_even([pos(a), pos(b), rest[0], rest[1]]) {
                (cell[rest[0]], cell[rest[1]])
            } else {
                (cell[rest[1]], cell[rest[0]])
            }
        };
        let next = |t: u32| across(t, [a, b, others(t).1]);
        let previous = |t: u32| across(t, [a, b, others(t).0]);
        let first = edge_tets[e][0];
        let mut ring = vec![first];
        let mut closed = false;
        while let Some(t) = next(*ring.last().unwrap()) {
            if t == first {
                closed = true;
                break;
            }
            ring.push(t);
        }
        if !closed {
            let mut before = Vec::new();
            let mut t = first;
            while let Some(p) = previous(t) {
                before.push(p);
                t = p;
            }
            before.reverse();
            before.extend(ring);
            ring = before;
        }
        if ring.len() < edge_tets[e].len() {
            partial_rings += 1;
        }
        rings.push((ring, closed));
    }

    let mut vertex_edges = vec![Vec::new(); vertices.len()];
    for (e, &[a, b]) in edges.iter().enumerate() {
        vertex_edges[a as usize].push(e as u32);
        vertex_edges[b as usize].push(e as u32);
    }
    Reference {
        vertices,
        tets,
        neighbours,
        edges,
        tet_edges,
        rings,
        vertex_edges,
        partial_rings,
    }
}

#[test]
fn mesh_matches_the_brute_force_construction() {
    let dc = random_complex(5000, 11);
    let mesh = TetMesh::from_dual_complex(&dc);
    let r = reference(&dc.tets);

    assert_eq!(mesh.vertices, r.vertices);
    assert_eq!(mesh.tets, r.tets);
    // The neighbours the mesh walks through are the tetrahedra sharing a triangle.
    assert_eq!(r.neighbours, dc.neighbours);
    assert_eq!(mesh.tet_neighbours, dc.neighbours);
    assert_eq!(mesh.edges, r.edges);
    assert_eq!(mesh.tet_edges, r.tet_edges);
    assert_eq!(mesh.edge_ring_offsets.len(), r.edges.len() + 1);
    assert_eq!(mesh.edge_ring_offsets[0], 0);
    assert_eq!(
        *mesh.edge_ring_offsets.last().unwrap() as usize,
        mesh.edge_rings.len()
    );
    for (e, (ring, closed)) in r.rings.iter().enumerate() {
        assert_eq!(mesh.edge_ring(e as u32), &ring[..], "ring of edge {e}");
        assert_eq!(mesh.edge_ring_closed[e], *closed, "ring of edge {e}");
    }
    assert_eq!(mesh.vertex_edge_offsets.len(), r.vertices.len() + 1);
    for (v, edges) in r.vertex_edges.iter().enumerate() {
        assert_eq!(
            mesh.edges_of_vertex(v as u32),
            &edges[..],
            "edges of vertex {v}"
        );
    }

    // The complex has what the construction must handle: both kinds of ring, and edges
    // around which the tetrahedra form several fans.
    let closed = mesh.edge_ring_closed.iter().filter(|&&c| c).count();
    assert!(
        closed > 1000 && mesh.edges.len() - closed > 1000,
        "{closed} closed rings"
    );
    assert!(r.partial_rings > 0, "no non-manifold edge");
}

#[test]
fn mesh_does_not_depend_on_the_thread_count() {
    let dc = random_complex(8000, 5);
    let one = on_threads(1, || TetMesh::from_dual_complex(&dc));
    // `from_tets` enumerates edges and rings in tasks of 1024 vertices.
    assert!(
        one.vertices.len() > 4 * 1024,
        "{} vertices",
        one.vertices.len()
    );
    for threads in [2, 8] {
        let TetMesh {
            vertices,
            tets,
            tet_neighbours,
            edges,
            tet_edges,
            edge_ring_offsets,
            edge_rings,
            edge_ring_closed,
            vertex_edge_offsets,
            vertex_edges,
        } = on_threads(threads, || TetMesh::from_dual_complex(&dc));
        let same = [
            vertices == one.vertices,
            tets == one.tets,
            tet_neighbours == one.tet_neighbours,
            edges == one.edges,
            tet_edges == one.tet_edges,
            edge_ring_offsets == one.edge_ring_offsets,
            edge_rings == one.edge_rings,
            edge_ring_closed == one.edge_ring_closed,
            vertex_edge_offsets == one.vertex_edge_offsets,
            vertex_edges == one.vertex_edges,
        ];
        assert!(
            same.iter().all(|&s| s),
            "{threads} threads: fields equal {same:?}"
        );
    }
}
