//! Marching tetrahedra on a [`TetMesh`]: the surface separating inside from outside vertices.
//!
//! The method is described on [`marching_tetrahedra()`].

use sphcover_core::DVec3;

use crate::error::TetraError;
use crate::tet_mesh::{TET_EDGE_VERTICES, TetMesh, permutation_is_even};

/// A triangle mesh extracted from a tetrahedral mesh.
#[derive(Clone, Debug, Default)]
pub struct IsoSurface {
    /// Vertex positions, one per cut edge, in increasing edge order.
    pub vertices: Vec<DVec3>,
    /// Triangles (indices into `vertices`), normals pointing from inside to outside.
    pub triangles: Vec<[u32; 3]>,
    /// For each vertex, the [`TetMesh`] edge it lies on.
    pub vertex_edges: Vec<u32>,
}

/// Extracts the surface between the vertices with `inside[v] = true` and the others.
///
/// `place(edge, inside_end, outside_end)` gives the position of the vertex on a cut edge
/// (mesh-vertex indices of its two ends); it is called once per cut edge, in edge order.
/// Quadrilaterals are split along their shorter diagonal between the placed vertices.
///
/// An edge is *cut* when its two ends are on different sides. Each cut edge gets exactly one
/// output vertex (shared by every triangle through it), placed by a caller-given rule; each
/// tetrahedron with a cut contributes one triangle (one vertex on one side) or two (two and
/// two, split along the shorter diagonal). Triangles are oriented with their normal from the
/// inside towards the outside, consistently over the whole surface, because every tetrahedron
/// is positively oriented and the winding is chosen from the parity of its vertex order.
///
/// Thesis §5.2.2: with a label per vertex (e.g. inside/outside from a graph cut) the cut edges are
/// those whose labels differ, and the vertex goes to the zero of the scalar when its signs
/// differ along the edge, otherwise to the end with the smaller `|value|`
/// ([`marching_tetrahedra_scalar`]).
pub fn marching_tetrahedra<F>(
    mesh: &TetMesh,
    inside: &[bool],
    mut place: F,
) -> Result<IsoSurface, TetraError>
where
    F: FnMut(u32, u32, u32) -> DVec3,
{
    if inside.len() != mesh.vertices.len() {
        return Err(TetraError::VertexArrayLength {
            expected: mesh.vertices.len(),
            got: inside.len(),
        });
    }
    let mut out = IsoSurface::default();
    let mut edge_vertex = vec![u32::MAX; mesh.edges.len()];
    for (e, &[a, b]) in mesh.edges.iter().enumerate() {
        let (ia, ib) = (inside[a as usize], inside[b as usize]);
        if ia != ib {
            let (i, o) = if ia { (a, b) } else { (b, a) };
            edge_vertex[e] = out.vertices.len() as u32;
            out.vertices.push(place(e as u32, i, o));
            out.vertex_edges.push(e as u32);
        }
    }
    for (t, cell) in mesh.tets.iter().enumerate() {
        let mask = (0..4).fold(0u8, |m, i| m | ((inside[cell[i] as usize] as u8) << i));
        if mask == 0 || mask == 15 {
            continue;
        }
        let te = &mesh.tet_edges[t];
        // Output vertex on the edge between positions i and j of the cell.
        let ev = |i: usize, j: usize| -> u32 {
            let k = TET_EDGE_VERTICES
                .iter()
                .position(|&[x, y]| (x == i && y == j) || (x == j && y == i))
                .unwrap_or(0);
            edge_vertex[te[k] as usize]
        };
        let mut ins = [0usize; 4];
        let mut outs = [0usize; 4];
        let (mut ni, mut no) = (0, 0);
        for i in 0..4 {
            if mask & (1 << i) != 0 {
                ins[ni] = i;
                ni += 1;
            } else {
                outs[no] = i;
                no += 1;
            }
        }
        match ni {
            1 | 3 => {
                // The lone vertex s and the other three in increasing position order; with
                // (s, j, k, l) even the triangle (e_sj, e_sk, e_sl) faces away from s.
                let (s, rest) = if ni == 1 {
                    (ins[0], outs)
                } else {
                    (outs[0], ins)
                };
                let (j, mut k, mut l) = (rest[0], rest[1], rest[2]);
                if !permutation_is_even([s, j, k, l]) {
                    std::mem::swap(&mut k, &mut l);
                }
                let tri = [ev(s, j), ev(s, k), ev(s, l)];
                if ni == 1 {
                    out.triangles.push(tri);
                } else {
                    // Lone outside vertex: the surface faces towards it.
                    out.triangles.push([tri[0], tri[2], tri[1]]);
                }
            }
            _ => {
                let (i1, i2) = (ins[0], ins[1]);
                let (mut o1, mut o2) = (outs[0], outs[1]);
                if !permutation_is_even([i1, i2, o1, o2]) {
                    std::mem::swap(&mut o1, &mut o2);
                }
                // With (i1, i2, o1, o2) even, the cycle below faces the outside.
                let q = [ev(i1, o1), ev(i1, o2), ev(i2, o2), ev(i2, o1)];
                let p = |k: usize| out.vertices[q[k] as usize];
                if p(0).distance_squared(p(2)) <= p(1).distance_squared(p(3)) {
                    out.triangles.push([q[0], q[1], q[2]]);
                    out.triangles.push([q[0], q[2], q[3]]);
                } else {
                    out.triangles.push([q[0], q[1], q[3]]);
                    out.triangles.push([q[1], q[2], q[3]]);
                }
            }
        }
    }
    Ok(out)
}

/// Marching tetrahedra of a per-vertex scalar (`positions` and `values` per mesh vertex).
///
/// Without `labels`, a vertex is inside when its value is negative, and each cut edge's
/// vertex is the linear zero crossing. With `labels` (`true` = inside), the cut edges are
/// those whose labels differ; the vertex is the linear zero crossing (the regula falsi step)
/// when the values' signs differ along the edge, otherwise the end with the smaller `|value|`.
pub fn marching_tetrahedra_scalar(
    mesh: &TetMesh,
    positions: &[DVec3],
    values: &[f64],
    labels: Option<&[bool]>,
) -> Result<IsoSurface, TetraError> {
    let nv = mesh.vertices.len();
    for len in [positions.len(), values.len()] {
        if len != nv {
            return Err(TetraError::VertexArrayLength {
                expected: nv,
                got: len,
            });
        }
    }
    let inside: Vec<bool> = match labels {
        Some(l) => l.to_vec(),
        None => values.iter().map(|&v| v < 0.0).collect(),
    };
    marching_tetrahedra(mesh, &inside, |_, i, o| {
        let (pi, po) = (positions[i as usize], positions[o as usize]);
        let (fi, fo) = (values[i as usize], values[o as usize]);
        if (fi < 0.0) != (fo < 0.0) && fi != fo {
            let t = (fi / (fi - fo)).clamp(0.0, 1.0);
            pi + (po - pi) * t
        } else if fi.abs() <= fo.abs() {
            pi
        } else {
            po
        }
    })
}
