//! `TetMesh`: a tetrahedral complex with unique edges, the ordered ring of tetrahedra around
//! each edge, and vertex → edge incidence, as plain arrays and CSR offsets.
//!
//! The method is described on [`TetMesh`].

use crate::dual_complex::DualComplex;
use crate::regular::NO_TET;

/// A tetrahedral complex (typically the dual complex of a cover) with its edge structure.
///
/// Edge rings: the tetrahedra around edge `(a, b)` (`a < b`) are listed in the order of a
/// right-handed rotation about the direction `a → b`. An edge inside the complex has a closed
/// ring (the last tetrahedron is adjacent to the first; it starts at the smallest tetrahedron
/// index); an edge on the boundary of the complex has an open ring, starting and ending at the
/// two tetrahedra with a boundary face through the edge.
///
/// Topology only: positions stay with the caller (the support centres), indexed through
/// [`TetMesh::vertices`].
#[derive(Clone, Debug, Default)]
pub struct TetMesh {
    /// Support (input sphere) index of each mesh vertex, ascending.
    pub vertices: Vec<u32>,
    /// Tetrahedra as mesh-vertex indices, positively oriented.
    pub tets: Vec<[u32; 4]>,
    /// Neighbour of each tetrahedron across the face opposite vertex `i`, or [`NO_TET`] on
    /// the boundary of the complex.
    pub tet_neighbours: Vec<[u32; 4]>,
    /// Unique edges `[a, b]` with `a < b`, sorted.
    pub edges: Vec<[u32; 2]>,
    /// The six edges of each tetrahedron, for vertex pairs `01, 02, 03, 12, 13, 23`.
    pub tet_edges: Vec<[u32; 6]>,
    /// CSR offsets into [`Self::edge_rings`], one more than the number of edges.
    pub edge_ring_offsets: Vec<u32>,
    /// Tetrahedra around each edge, in rotation order.
    pub edge_rings: Vec<u32>,
    /// Per edge: `true` when its ring is closed (interior edge).
    pub edge_ring_closed: Vec<bool>,
    /// CSR offsets into [`Self::vertex_edges`], one more than the number of vertices.
    pub vertex_edge_offsets: Vec<u32>,
    /// Edges incident to each vertex, ascending.
    pub vertex_edges: Vec<u32>,
}

/// Vertex position pairs of the six edges of a tetrahedron.
pub const TET_EDGE_VERTICES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

impl TetMesh {
    /// The mesh of a dual complex: its tetrahedra, over the supports they use.
    pub fn from_dual_complex(dc: &DualComplex) -> TetMesh {
        Self::from_tets(dc.status.len(), &dc.tets, &dc.neighbours)
    }

    /// Builds the mesh from tetrahedra over `num_points` input points (positively oriented)
    /// and their face adjacency (`neighbours[t][i]` across the face opposite vertex `i`, or
    /// [`NO_TET`]).
    pub fn from_tets(num_points: usize, tets: &[[u32; 4]], neighbours: &[[u32; 4]]) -> TetMesh {
        let mut map = vec![NO_TET; num_points];
        for t in tets {
            for &v in t {
                map[v as usize] = 0;
            }
        }
        let mut vertices = Vec::new();
        for (i, m) in map.iter_mut().enumerate() {
            if *m == 0 {
                *m = vertices.len() as u32;
                vertices.push(i as u32);
            }
        }
        let tets: Vec<[u32; 4]> = tets.iter().map(|t| t.map(|v| map[v as usize])).collect();
        let nv = vertices.len();

        // Vertex → tetrahedra (CSR), to enumerate each vertex's higher neighbours.
        let mut vt_off = vec![0u32; nv + 1];
        for t in &tets {
            for &v in t {
                vt_off[v as usize + 1] += 1;
            }
        }
        for i in 0..nv {
            vt_off[i + 1] += vt_off[i];
        }
        let mut fill = vt_off.clone();
        let mut vt = vec![0u32; 4 * tets.len()];
        for (ti, t) in tets.iter().enumerate() {
            for &v in t {
                vt[fill[v as usize] as usize] = ti as u32;
                fill[v as usize] += 1;
            }
        }

        // Unique edges, sorted: for each a, its neighbours b > a.
        let mut edges: Vec<[u32; 2]> = Vec::new();
        let mut first_edge = vec![0u32; nv + 1];
        let mut seen = vec![u32::MAX; nv];
        let mut nbrs: Vec<u32> = Vec::new();
        for a in 0..nv {
            first_edge[a] = edges.len() as u32;
            nbrs.clear();
            for &t in &vt[vt_off[a] as usize..vt_off[a + 1] as usize] {
                for &b in &tets[t as usize] {
                    if b as usize > a && seen[b as usize] != a as u32 {
                        seen[b as usize] = a as u32;
                        nbrs.push(b);
                    }
                }
            }
            nbrs.sort_unstable();
            edges.extend(nbrs.iter().map(|&b| [a as u32, b]));
        }
        first_edge[nv] = edges.len() as u32;
        let find = |a: u32, b: u32| -> u32 {
            let (a, b) = if a < b { (a, b) } else { (b, a) };
            let range =
                &edges[first_edge[a as usize] as usize..first_edge[a as usize + 1] as usize];
            let k = range
                .binary_search_by_key(&b, |e| e[1])
                .expect("every tetrahedron edge is listed");
            first_edge[a as usize] + k as u32
        };
        let mut edge_tet = vec![NO_TET; edges.len()];
        let tet_edges: Vec<[u32; 6]> = tets
            .iter()
            .enumerate()
            .map(|(ti, t)| {
                TET_EDGE_VERTICES.map(|[i, j]| {
                    let e = find(t[i], t[j]);
                    if edge_tet[e as usize] == NO_TET {
                        edge_tet[e as usize] = ti as u32;
                    }
                    e
                })
            })
            .collect();

        // Rings.
        let mut edge_ring_offsets = Vec::with_capacity(edges.len() + 1);
        let mut edge_rings = Vec::with_capacity(6 * tets.len());
        let mut edge_ring_closed = Vec::with_capacity(edges.len());
        edge_ring_offsets.push(0u32);
        for (e, &[a, b]) in edges.iter().enumerate() {
            let t0 = edge_tet[e];
            // Step across the face opposite `c` (forward) or `d` (backward), where `c, d` are
            // the other two vertices ordered so that (a, b, c, d) is positive.
            let step = |t: u32, forward: bool| -> u32 {
                let cell = &tets[t as usize];
                let (pc, pd) = ring_positions(cell, a, b);
                neighbours[t as usize][if forward { pc } else { pd }]
            };
            // Walk backwards to the ring's start (an open ring) or all the way round (a
            // closed ring, which starts at its smallest tetrahedron).
            let mut start = t0;
            let mut min = t0;
            let mut closed = false;
            loop {
                let p = step(start, false);
                if p == NO_TET {
                    break;
                }
                if p == t0 {
                    closed = true;
                    break;
                }
                start = p;
                min = min.min(p);
            }
            if closed {
                start = min;
            }
            let mut t = start;
            loop {
                edge_rings.push(t);
                t = step(t, true);
                if t == NO_TET || t == start {
                    break;
                }
            }
            edge_ring_closed.push(closed);
            edge_ring_offsets.push(edge_rings.len() as u32);
        }

        // Vertex → edges.
        let mut vertex_edge_offsets = vec![0u32; nv + 1];
        for e in &edges {
            vertex_edge_offsets[e[0] as usize + 1] += 1;
            vertex_edge_offsets[e[1] as usize + 1] += 1;
        }
        for i in 0..nv {
            vertex_edge_offsets[i + 1] += vertex_edge_offsets[i];
        }
        let mut fill = vertex_edge_offsets.clone();
        let mut vertex_edges = vec![0u32; 2 * edges.len()];
        for (ei, e) in edges.iter().enumerate() {
            for &v in e {
                vertex_edges[fill[v as usize] as usize] = ei as u32;
                fill[v as usize] += 1;
            }
        }

        // Neighbours are already in tetrahedron indices; keep them as given.
        TetMesh {
            vertices,
            tets,
            tet_neighbours: neighbours.to_vec(),
            edges,
            tet_edges,
            edge_ring_offsets,
            edge_rings,
            edge_ring_closed,
            vertex_edge_offsets,
            vertex_edges,
        }
    }

    /// The tetrahedra around edge `e`, in rotation order (see the type's documentation).
    pub fn edge_ring(&self, e: u32) -> &[u32] {
        let (s, t) = (
            self.edge_ring_offsets[e as usize] as usize,
            self.edge_ring_offsets[e as usize + 1] as usize,
        );
        &self.edge_rings[s..t]
    }

    /// The edges incident to mesh vertex `v`.
    pub fn edges_of_vertex(&self, v: u32) -> &[u32] {
        let (s, t) = (
            self.vertex_edge_offsets[v as usize] as usize,
            self.vertex_edge_offsets[v as usize + 1] as usize,
        );
        &self.vertex_edges[s..t]
    }

    /// The edge joining mesh vertices `a` and `b`, if any.
    pub fn find_edge(&self, a: u32, b: u32) -> Option<u32> {
        let (a, b) = if a < b { (a, b) } else { (b, a) };
        self.edges_of_vertex(a)
            .iter()
            .copied()
            .find(|&e| self.edges[e as usize] == [a, b])
    }

    /// Number of triangles of the complex (faces of the tetrahedra, each counted once).
    pub fn num_triangles(&self) -> usize {
        let boundary: usize = self
            .tet_neighbours
            .iter()
            .map(|n| n.iter().filter(|&&x| x == NO_TET).count())
            .sum();
        (4 * self.tets.len() + boundary) / 2
    }

    /// `V − E + F − T` of the complex formed by the tetrahedra and their faces.
    pub fn euler_characteristic(&self) -> i64 {
        self.vertices.len() as i64 - self.edges.len() as i64 + self.num_triangles() as i64
            - self.tets.len() as i64
    }
}

/// Positions in `cell` of the two vertices other than `a` and `b`, ordered so that the
/// permutation `(a, b, c, d)` of the cell's positions is even (positive orientation).
#[inline]
fn ring_positions(cell: &[u32; 4], a: u32, b: u32) -> (usize, usize) {
    // EVEN_REST[pa][pb] = (pc, pd) with (pa, pb, pc, pd) an even permutation of 0..4.
    const EVEN_REST: [[(u8, u8); 4]; 4] = [
        [(0, 0), (2, 3), (3, 1), (1, 2)],
        [(3, 2), (0, 0), (0, 3), (2, 0)],
        [(1, 3), (3, 0), (0, 0), (0, 1)],
        [(2, 1), (0, 2), (1, 0), (0, 0)],
    ];
    let mut pa = 0;
    let mut pb = 1;
    for (i, &x) in cell.iter().enumerate() {
        if x == a {
            pa = i;
        } else if x == b {
            pb = i;
        }
    }
    let (c, d) = EVEN_REST[pa][pb];
    (c as usize, d as usize)
}

/// Parity of a permutation of `0..4` by counting inversions.
#[inline]
pub(crate) fn permutation_is_even(p: [usize; 4]) -> bool {
    let mut inversions = 0;
    for i in 0..4 {
        for j in i + 1..4 {
            if p[i] > p[j] {
                inversions += 1;
            }
        }
    }
    inversions % 2 == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn even_rest_table_gives_even_permutations() {
        for pa in 0..4 {
            for pb in 0..4 {
                if pa == pb {
                    continue;
                }
                let cell = [10u32, 11, 12, 13];
                let (pc, pd) = ring_positions(&cell, 10 + pa as u32, 10 + pb as u32);
                let mut all = [pa, pb, pc, pd];
                assert!(permutation_is_even(all));
                all.sort_unstable();
                assert_eq!(all, [0, 1, 2, 3]);
            }
        }
    }
}
