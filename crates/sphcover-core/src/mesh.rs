//! Indexed triangle meshes.

use glam::DVec3;

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
