//! `TetMesh`: a tetrahedral complex with unique edges, the ordered ring of tetrahedra around
//! each edge, and vertex → edge incidence, as plain arrays and CSR offsets.
//!
//! The method is described on [`TetMesh`].

use std::ops::Range;

use rayon::prelude::*;

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
    ///
    /// Runs on rayon; the output does not depend on the number of threads. Each vertex's
    /// edges and rings, and each tetrahedron's edges, are computed on their own, and the
    /// pieces concatenated in vertex order; the vertex → tetrahedra and vertex → edges
    /// incidences are scattered by vertex ranges.
    pub fn from_tets(num_points: usize, tets: &[[u32; 4]], neighbours: &[[u32; 4]]) -> TetMesh {
        // The number of tetrahedra of each support, zero for those not in use (the
        // vertex → tetrahedra offsets); then the same array maps each support to its vertex.
        let mut map = vec![0u32; num_points];
        for &v in tets.iter().flatten() {
            map[v as usize] += 1;
        }
        let mut vertices = Vec::new();
        let mut vt_off = vec![0u32];
        for (i, m) in map.iter_mut().enumerate() {
            if *m > 0 {
                vt_off.push(vt_off[vertices.len()] + *m);
                *m = vertices.len() as u32;
                vertices.push(i as u32);
            }
        }
        let tets: Vec<[u32; 4]> = tets
            .par_iter()
            .with_min_len(4096)
            .map(|t| t.map(|v| map[v as usize]))
            .collect();
        drop(map);
        let nv = vertices.len();
        // Vertex → tetrahedra, ascending per vertex.
        let vt = transpose(&tets, &vt_off);

        // Unique edges `(a, b)`, `a < b`, sorted, and their rings: vertex by vertex, in tasks
        // of `VERTEX_CHUNK` vertices.
        let chunks: Vec<EdgeChunk> = (0..nv.div_ceil(VERTEX_CHUNK))
            .into_par_iter()
            .map(|c| {
                let vs = c * VERTEX_CHUNK..((c + 1) * VERTEX_CHUNK).min(nv);
                edges_and_rings(vs, &tets, neighbours, &vt_off, &vt)
            })
            .collect();
        drop((vt_off, vt));
        let first_edge = offsets(chunks.iter().map(|c| &c.edge_ends[..]));
        let edge_ring_offsets = offsets(chunks.iter().map(|c| &c.ring_ends[..]));
        let (mut edges, mut rings, mut closed) = (Vec::new(), Vec::new(), Vec::new());
        for c in chunks {
            edges.push(c.edges);
            rings.push(c.rings);
            closed.push(c.closed);
        }
        let edge_rings = concat(rings);
        let edge_ring_closed = concat(closed);
        let edges = concat(edges);

        let find = |a: u32, b: u32| -> u32 {
            let (a, b) = if a < b { (a, b) } else { (b, a) };
            let range =
                &edges[first_edge[a as usize] as usize..first_edge[a as usize + 1] as usize];
            let k = range
                .binary_search_by_key(&b, |e| e[1])
                .expect("every tetrahedron edge is listed");
            first_edge[a as usize] + k as u32
        };
        let tet_edges: Vec<[u32; 6]> = tets
            .par_iter()
            .with_min_len(4096)
            .map(|t| TET_EDGE_VERTICES.map(|[i, j]| find(t[i], t[j])))
            .collect();

        // Vertex → edges, ascending per vertex.
        let mut vertex_edge_offsets = vec![0u32; nv + 1];
        for &v in edges.iter().flatten() {
            vertex_edge_offsets[v as usize + 1] += 1;
        }
        for i in 0..nv {
            vertex_edge_offsets[i + 1] += vertex_edge_offsets[i];
        }
        let vertex_edges = transpose(&edges, &vertex_edge_offsets);

        // Neighbours are already in tetrahedron indices; keep them as given.
        let tet_neighbours = neighbours.par_iter().with_min_len(4096).copied().collect();
        TetMesh {
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

/// Vertices per task of the edge and ring enumeration (the output does not depend on it).
const VERTEX_CHUNK: usize = 1024;

/// The transpose of `items` (tetrahedra or edges) given its CSR offsets (the running count
/// of items per vertex): per vertex, the indices of the items containing it, ascending.
///
/// A scatter split into vertex ranges, one per thread: each task reads all the items and
/// writes those of its own vertices, in item order, so the output does not depend on the
/// split. An extra task costs one more read of `items`; atomic cursors would cost more, and a
/// sort per vertex after them.
fn transpose<const K: usize>(items: &[[u32; K]], offsets: &[u32]) -> Vec<u32> {
    let nv = offsets.len() - 1;
    let tasks = rayon::current_num_threads().clamp(1, nv.max(1));
    let mut out = vec![0u32; offsets[nv] as usize];
    let mut parts = Vec::with_capacity(tasks);
    let mut rest = out.as_mut_slice();
    for k in 0..tasks {
        let vs = k * nv / tasks..(k + 1) * nv / tasks;
        let (head, tail) = rest.split_at_mut((offsets[vs.end] - offsets[vs.start]) as usize);
        parts.push((vs, head));
        rest = tail;
    }
    parts.into_par_iter().for_each(|(vs, out)| {
        let base = offsets[vs.start];
        let mut fill: Vec<u32> = offsets[vs.clone()].iter().map(|&o| o - base).collect();
        for (i, item) in items.iter().enumerate() {
            for &v in item {
                let slot = (v as usize)
                    .checked_sub(vs.start)
                    .and_then(|j| fill.get_mut(j));
                if let Some(f) = slot {
                    out[*f as usize] = i as u32;
                    *f += 1;
                }
            }
        }
    });
    out
}

/// The edges and rings of a range of vertices, in order.
struct EdgeChunk {
    /// Per vertex `a`, the end in `edges` of its edges `(a, b)`, `b > a`.
    edge_ends: Vec<u32>,
    edges: Vec<[u32; 2]>,
    /// Per edge, the end of its ring in `rings`.
    ring_ends: Vec<u32>,
    rings: Vec<u32>,
    closed: Vec<bool>,
}

/// The edges `(a, b)`, `b > a`, of the vertices `a` in `vs`, sorted, and their rings.
fn edges_and_rings(
    vs: Range<usize>,
    tets: &[[u32; 4]],
    neighbours: &[[u32; 4]],
    vt_off: &[u32],
    vt: &[u32],
) -> EdgeChunk {
    let mut out = EdgeChunk {
        edge_ends: Vec::with_capacity(vs.len()),
        edges: Vec::new(),
        ring_ends: Vec::new(),
        rings: Vec::new(),
        closed: Vec::new(),
    };
    // Pairs `(b, t)` of a higher neighbour `b` of `a` and a tetrahedron `t` with the edge
    // `(a, b)`, as `b << 32 | t`: about 35 per vertex at 1M spheres, for 7 edges. Sorted, they
    // give the edges in order, each with its smallest tetrahedron first. (A linear search for
    // each `b` took about 10% more of this pass; a stamp array would cost `O(nv)` per task.)
    let mut pairs: Vec<u64> = Vec::new();
    for a in vs {
        pairs.clear();
        for &t in &vt[vt_off[a] as usize..vt_off[a + 1] as usize] {
            for &b in &tets[t as usize] {
                if b as usize > a {
                    pairs.push(u64::from(b) << 32 | u64::from(t));
                }
            }
        }
        pairs.sort_unstable();
        let mut last = None;
        for &pair in &pairs {
            let (b, t0) = ((pair >> 32) as u32, pair as u32);
            if last == Some(b) {
                continue;
            }
            last = Some(b);
            out.edges.push([a as u32, b]);
            // The walk stays among the tetrahedra around `a`, whose vertices were just read.
            out.closed
                .push(walk_ring(tets, neighbours, a as u32, b, t0, &mut out.rings));
            out.ring_ends.push(out.rings.len() as u32);
        }
        out.edge_ends.push(out.edges.len() as u32);
    }
    out
}

/// Appends the ring of edge `(a, b)` through `t0`, its smallest tetrahedron, to `ring` and
/// returns whether it is closed.
///
/// A closed ring starts at `t0`; an open one at the tetrahedron reached by stepping backwards
/// from `t0` until the boundary. Each tetrahedron is visited once.
fn walk_ring(
    tets: &[[u32; 4]],
    neighbours: &[[u32; 4]],
    a: u32,
    b: u32,
    t0: u32,
    ring: &mut Vec<u32>,
) -> bool {
    // Step across the face opposite `c` (forward) or `d` (backward), where `c, d` are the
    // other two vertices ordered so that (a, b, c, d) is positive.
    let step = |t: u32, forward: bool| -> u32 {
        let (pc, pd) = ring_positions(&tets[t as usize], a, b);
        neighbours[t as usize][if forward { pc } else { pd }]
    };
    let start = ring.len();
    let mut t = t0;
    loop {
        ring.push(t);
        t = step(t, true);
        if t == t0 {
            return true;
        }
        if t == NO_TET {
            break;
        }
    }
    // Open: the tetrahedra before `t0`, met backwards, go in front of it in reverse.
    let after = ring.len();
    let mut t = step(t0, false);
    while t != NO_TET {
        ring.push(t);
        t = step(t, false);
    }
    let before = ring.len() - after;
    ring[after..].reverse();
    ring[start..].rotate_right(before);
    false
}

/// CSR offsets from per-chunk end offsets (each relative to its chunk): a leading 0, then
/// every end shifted by the total of the chunks before.
fn offsets<'a>(chunk_ends: impl Iterator<Item = &'a [u32]>) -> Vec<u32> {
    let mut out = vec![0u32];
    for ends in chunk_ends {
        let base = *out.last().expect("starts with 0");
        out.extend(ends.iter().map(|&e| base + e));
    }
    out
}

/// The concatenation of `parts`, copied in parallel; each part is freed once copied.
fn concat<T: Copy + Default + Send + Sync>(parts: Vec<Vec<T>>) -> Vec<T> {
    let mut out = vec![T::default(); parts.iter().map(Vec::len).sum()];
    let mut rest = out.as_mut_slice();
    let mut pieces = Vec::with_capacity(parts.len());
    for part in parts {
        let (head, tail) = rest.split_at_mut(part.len());
        pieces.push((head, part));
        rest = tail;
    }
    pieces
        .into_par_iter()
        .for_each(|(dst, src)| dst.copy_from_slice(&src));
    out
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
