//! Patches of the skeletal sheet around ridge edges (thesis §6.2.2, Fig. 6.11).
//!
//! The method is described on [`ridge_patches()`].

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::TriMesh;
use sphcover_tetra::TetMesh;

use crate::ridge_points::RidgePoint;

/// Builds the patch mesh of the ridge points (`ridge` is indexed like `mesh.edges`).
///
/// Every tetrahedron with a ridge point on one of its edges gets one vertex `q_t`, the
/// centroid of those points. For each edge with a ridge point `c`, the walk around the edge's
/// ordered ring of tetrahedra emits a triangle `(q_t, q_t', c)` for every consecutive pair
/// (closing the fan for an interior edge, leaving it open for an edge on the mesh boundary).
/// Each tetrahedron of the ring contains the edge, so each has a `q_t`. The result is one
/// mesh with shared vertices: the ridge points (in edge order) and then the tetrahedron
/// vertices (in tetrahedron order). The per-vertex value is the ridge strength `−λ1`, the
/// per-vertex normal the ridge's across direction `e` (unoriented: its sign is arbitrary).
pub fn ridge_patches(mesh: &TetMesh, ridge: &[Option<RidgePoint>]) -> TriMesh {
    let mut vertices = Vec::new();
    let mut strengths = Vec::new();
    let mut normals = Vec::new();
    let mut edge_vertex = vec![u32::MAX; ridge.len()];
    for (e, p) in ridge.iter().enumerate() {
        if let Some(p) = p {
            edge_vertex[e] = vertices.len() as u32;
            vertices.push(p.position);
            strengths.push(p.strength);
            normals.push(p.direction);
        }
    }
    let tet_points: Vec<Option<(DVec3, f64, DVec3)>> = mesh
        .tet_edges
        .par_iter()
        .with_min_len(1024)
        .map(|edges| {
            let (mut sum, mut strength, mut n) = (DVec3::ZERO, 0.0, 0usize);
            let mut direction: Option<DVec3> = None;
            for &e in edges {
                if let Some(p) = &ridge[e as usize] {
                    sum += p.position;
                    strength += p.strength;
                    n += 1;
                    // Directions have no sign: align each to the running sum.
                    direction = Some(match direction {
                        None => p.direction,
                        Some(d) if d.dot(p.direction) < 0.0 => d - p.direction,
                        Some(d) => d + p.direction,
                    });
                }
            }
            let direction = direction.unwrap_or(DVec3::Z);
            (n > 0).then(|| {
                (
                    sum / n as f64,
                    strength / n as f64,
                    direction.normalize_or(DVec3::Z),
                )
            })
        })
        .collect();
    let mut tet_vertex = vec![u32::MAX; tet_points.len()];
    for (t, q) in tet_points.iter().enumerate() {
        if let Some((q, s, d)) = q {
            tet_vertex[t] = vertices.len() as u32;
            vertices.push(*q);
            strengths.push(*s);
            normals.push(*d);
        }
    }
    let fans: Vec<Vec<[u32; 3]>> = (0..ridge.len())
        .into_par_iter()
        .with_min_len(1024)
        .map(|e| {
            let c = edge_vertex[e];
            if c == u32::MAX {
                return Vec::new();
            }
            let ring = mesh.edge_ring(e as u32);
            let closed = mesh.edge_ring_closed[e];
            let pairs = if closed {
                ring.len()
            } else {
                ring.len().saturating_sub(1)
            };
            (0..pairs)
                .map(|k| {
                    let (t0, t1) = (ring[k], ring[(k + 1) % ring.len()]);
                    [tet_vertex[t0 as usize], tet_vertex[t1 as usize], c]
                })
                .filter(|tri| tri[0] != tri[1])
                .collect()
        })
        .collect();
    let mut out = TriMesh::new(vertices, fans.concat());
    out.values = Some(strengths);
    out.normals = Some(normals);
    out
}
