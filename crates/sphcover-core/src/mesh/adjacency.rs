//! Which triangles meet at each vertex, as compressed rows: the index every mesh repair
//! (pinches, fans, flaps, manifold checks) starts from.

use super::TriMesh;

/// The triangles at each vertex of a mesh (compressed rows). A triangle appears in the row
/// of each of its corners, once per corner, and every row lists its triangles in ascending
/// order, so walks over a row visit them in the mesh's order whatever built the index.
///
/// ```
/// use sphcover_core::{DVec3, TriMesh, VertexTriangles};
///
/// // Two triangles sharing the edge 1–2.
/// let mesh = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::ONE], vec![[0, 1, 2], [2, 1, 3]]);
/// let around = VertexTriangles::of(&mesh);
/// assert_eq!(around.triangles_at(1), &[0, 1]);
/// assert_eq!(around.triangles_at(3), &[1]);
/// ```
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct VertexTriangles {
    /// Vertex `v`'s triangles are `triangles[offsets[v]..offsets[v + 1]]`.
    offsets: Vec<u32>,
    triangles: Vec<u32>,
}

impl VertexTriangles {
    /// The index of every triangle of `mesh`; corners out of range are left out.
    pub fn of(mesh: &TriMesh) -> VertexTriangles {
        let n = mesh.vertices.len();
        let (offsets, triangles) = bucketed(n, || {
            mesh.triangles
                .iter()
                .enumerate()
                .flat_map(|(t, tri)| tri.iter().map(move |&v| (v as usize, t as u32)))
                .filter(move |&(v, _)| v < n)
        });
        VertexTriangles { offsets, triangles }
    }

    /// The triangles at vertex `v`, ascending.
    ///
    /// # Panics
    ///
    /// When `v` is not a vertex of the mesh.
    pub fn triangles_at(&self, v: usize) -> &[u32] {
        &self.triangles[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }
}

/// Compressed rows of `(row, value)` entries over rows `0..n`: a counting sort, so each row
/// keeps the order in which `entries` yields its values. `entries` is called twice (to count,
/// then to fill) and must yield the same sequence both times.
pub(crate) fn bucketed<T: Copy + Default, I: Iterator<Item = (usize, T)>>(
    n: usize,
    entries: impl Fn() -> I,
) -> (Vec<u32>, Vec<T>) {
    let mut offsets = vec![0u32; n + 1];
    for (b, _) in entries() {
        offsets[b + 1] += 1;
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut values = vec![T::default(); offsets[n] as usize];
    for (b, value) in entries() {
        values[fill[b] as usize] = value;
        fill[b] += 1;
    }
    (offsets, values)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use proptest::prelude::*;

    proptest! {
        /// Against a brute-force scan: each row holds exactly the triangles with a corner
        /// there, once per corner, ascending.
        #[test]
        fn rows_match_a_scan_of_the_triangles(
            n in 1usize..12,
            triangles in prop::collection::vec(prop::array::uniform3(0u32..14), 0..30),
        ) {
            let mesh = TriMesh::new(vec![DVec3::ZERO; n], triangles.clone());
            let around = VertexTriangles::of(&mesh);
            prop_assert_eq!(around.vertex_count(), n);
            for v in 0..n {
                let expected: Vec<u32> = triangles
                    .iter()
                    .enumerate()
                    .flat_map(|(t, tri)| tri.iter().filter(move |&&c| c as usize == v).map(move |_| t as u32))
                    .collect();
                prop_assert_eq!(around.triangles_at(v), &expected[..]);
            }
        }
    }
}
