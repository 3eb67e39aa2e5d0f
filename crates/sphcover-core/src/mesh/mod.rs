//! Indexed triangle meshes, and the tools every pipeline applies to them: the triangles
//! at each vertex ([`VertexTriangles`]), unused vertices and small components removed.

mod adjacency;
mod small_components;
mod unused_vertices;

pub use adjacency::VertexTriangles;
pub(crate) use adjacency::bucketed;
pub use small_components::{
    SmallComponentsError, SmallComponentsStats, component_areas, remove_components,
    remove_small_components,
};
pub use unused_vertices::remove_unused_vertices;

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry::{Aabb, Normalisation};

/// A triangle mesh with shared vertices: positions and `u32` vertex-index triples.
///
/// Optional per-vertex normals and a per-vertex scalar (for example the confidence of a
/// reconstructed surface) travel with the vertices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub vertices: Vec<DVec3>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex normals, if known.
    pub normals: Option<Vec<DVec3>>,
    /// A per-vertex scalar, if any.
    pub values: Option<Vec<f64>>,
    /// Per-vertex colour as 8-bit red, green, blue, if any.
    pub colors: Option<Vec<[u8; 3]>>,
}

impl TriMesh {
    /// A mesh of positions and triangles, without attributes.
    pub fn new(vertices: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> TriMesh {
        TriMesh {
            vertices,
            triangles,
            ..TriMesh::default()
        }
    }

    /// Bounding box of the finite vertices.
    pub fn bounding_box(&self) -> Aabb {
        Aabb::from_points(&self.vertices)
    }

    /// Checks that every triangle index is in range and attributes have one entry per vertex.
    pub fn check(&self) -> Result<(), String> {
        let n = self.vertices.len();
        if let Some((t, tri)) = self
            .triangles
            .iter()
            .enumerate()
            .find(|(_, tri)| tri.iter().any(|&v| v as usize >= n))
        {
            return Err(format!(
                "triangle {t} refers to vertex {:?} but there are {n} vertices",
                tri
            ));
        }
        for (name, len) in [
            ("normals", self.normals.as_ref().map(Vec::len)),
            ("values", self.values.as_ref().map(Vec::len)),
            ("colors", self.colors.as_ref().map(Vec::len)),
        ] {
            if let Some(len) = len
                && len != n
            {
                return Err(format!("{name} has {len} entries for {n} vertices"));
            }
        }
        Ok(())
    }

    /// Maps the vertices into the unit frame of `norm`.
    pub fn to_unit(&mut self, norm: &Normalisation) {
        norm.points_to_unit(&mut self.vertices);
    }

    /// Maps the vertices back to input coordinates.
    pub fn to_input(&mut self, norm: &Normalisation) {
        norm.points_to_input(&mut self.vertices);
    }
}

/// Area-weighted vertex normals of a triangle mesh (unit; zero for a vertex of no
/// triangle with area).
pub fn vertex_normals(positions: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let faces: Vec<DVec3> = triangles
        .par_iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            let f = (b - a).cross(c - a);
            if f.is_finite() { f } else { DVec3::ZERO }
        })
        .collect();
    // Each thread sums into its own range of vertices, walking all triangles in order: every
    // vertex adds its triangles' normals in triangle order, whatever the thread count.
    let mut sums = vec![DVec3::ZERO; positions.len()];
    let part_len = positions
        .len()
        .div_ceil(rayon::current_num_threads().max(1))
        .max(1);
    sums.par_chunks_mut(part_len)
        .enumerate()
        .for_each(|(part, sums)| {
            let lo = part * part_len;
            for (t, f) in triangles.iter().zip(&faces) {
                for &v in t {
                    if let Some(sum) = (v as usize).checked_sub(lo).and_then(|i| sums.get_mut(i)) {
                        *sum += *f;
                    }
                }
            }
            for sum in sums.iter_mut() {
                *sum = sum.normalize_or_zero();
            }
        });
    sums
}

/// Area of triangle `tri` of `mesh`.
pub fn triangle_area(mesh: &TriMesh, tri: &[u32; 3]) -> f64 {
    let [a, b, c] = tri.map(|v| mesh.vertices[v as usize]);
    0.5 * (b - a).cross(c - a).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_normals_of_a_closed_box_point_outward() {
        // A unit cube of twelve outward-wound triangles.
        let positions: Vec<DVec3> = (0..8)
            .map(|i| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let triangles: Vec<[u32; 3]> = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        let normals = vertex_normals(&positions, &triangles);
        for (p, n) in positions.iter().zip(&normals) {
            let outward = (*p - DVec3::splat(0.5)).normalize();
            assert!(n.dot(outward) > 0.9, "{p} {n}");
        }
    }
}
