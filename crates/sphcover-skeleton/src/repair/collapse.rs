//! Elementary collapses from a sheet's free edges: removals that keep its topology.
//!
//! Removing a triangle together with the edges and corners that only it uses changes the
//! Euler characteristic by `free edges − freed corners − 1`. It is an elementary collapse
//! (the sheet keeps its homotopy type: components, holes and handles) when that is 0: one
//! free edge; two, with their shared corner freed; three, with two corners freed (a tip
//! hanging on one corner). An isolated triangle (three corners freed) is a component and
//! stays. The flap repair eats fins this way; the rim trimming, where the voxels are at
//! hand, trims this way too, so that it cannot join two holes or a hole and the rim.

use std::collections::{BinaryHeap, HashMap};

use sphcover_core::{TriMesh, VertexTriangles};

use super::MinFirst;

/// The state of a sequence of elementary collapses on a mesh: which triangles are gone, and
/// how many live triangles use each edge and each corner.
pub(crate) struct FreeEdgeCollapse<'m> {
    mesh: &'m TriMesh,
    triangle_edges: Vec<[u32; 3]>,
    edge_use: Vec<u32>,
    corner_use: Vec<u32>,
    vertex_triangles: VertexTriangles,
    removed: Vec<bool>,
}

impl<'m> FreeEdgeCollapse<'m> {
    /// Nothing removed yet.
    pub(crate) fn new(mesh: &'m TriMesh) -> FreeEdgeCollapse<'m> {
        let mut edge_index: HashMap<(u32, u32), u32> = HashMap::new();
        let triangle_edges: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .map(|tri| {
                [0, 1, 2].map(|k| {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    let next = edge_index.len() as u32;
                    *edge_index.entry((a.min(b), a.max(b))).or_insert(next)
                })
            })
            .collect();
        let mut edge_use = vec![0u32; edge_index.len()];
        for ids in &triangle_edges {
            for &e in ids {
                edge_use[e as usize] += 1;
            }
        }
        let vertex_triangles = VertexTriangles::of(mesh);
        let corner_use = (0..mesh.vertices.len())
            .map(|v| vertex_triangles.triangles_at(v).len() as u32)
            .collect();
        FreeEdgeCollapse {
            mesh,
            triangle_edges,
            edge_use,
            corner_use,
            vertex_triangles,
            removed: vec![false; mesh.triangles.len()],
        }
    }

    /// Removes triangle `t` when that is an elementary collapse now; returns whether it did.
    pub(crate) fn try_remove(&mut self, t: usize) -> bool {
        if self.removed[t] {
            return false;
        }
        let edges = self.triangle_edges[t];
        let free = edges
            .iter()
            .filter(|&&e| self.edge_use[e as usize] == 1)
            .count();
        let freed = self.mesh.triangles[t]
            .iter()
            .filter(|&&v| self.corner_use[v as usize] == 1)
            .count();
        if free == 0 || free != freed + 1 {
            return false;
        }
        self.removed[t] = true;
        for &e in &edges {
            self.edge_use[e as usize] -= 1;
        }
        for &v in &self.mesh.triangles[t] {
            self.corner_use[v as usize] -= 1;
        }
        true
    }

    /// The live triangles sharing a corner with `t` (those a removal of `t` may have made
    /// collapsible), with repeats.
    pub(crate) fn neighbours(&self, t: usize) -> impl Iterator<Item = u32> + '_ {
        self.mesh.triangles[t]
            .iter()
            .flat_map(|&v| self.vertex_triangles.triangles_at(v as usize))
            .copied()
            .filter(|&n| !self.removed[n as usize])
    }

    /// Which triangles are gone.
    pub(crate) fn into_removed(self) -> Vec<bool> {
        self.removed
    }
}

/// Collapses as many of the `removable` triangles of `mesh` as elementary collapses allow,
/// lowest `priority` first (ties by index; a triangle is tried again whenever a neighbour
/// goes), and returns which are gone. The result does not depend on anything but the inputs.
pub(crate) fn collapse_in_order(mesh: &TriMesh, removable: &[bool], priority: &[f64]) -> Vec<bool> {
    let mut collapse = FreeEdgeCollapse::new(mesh);
    let mut heap: BinaryHeap<MinFirst> = (0..mesh.triangles.len())
        .filter(|&t| removable[t])
        .map(|t| MinFirst(priority[t], t as u32))
        .collect();
    let mut next = Vec::new();
    while let Some(MinFirst(_, t)) = heap.pop() {
        if !collapse.try_remove(t as usize) {
            continue;
        }
        next.extend(
            collapse
                .neighbours(t as usize)
                .filter(|&n| removable[n as usize]),
        );
        heap.extend(next.drain(..).map(|n| MinFirst(priority[n as usize], n)));
    }
    collapse.into_removed()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::repair::{grid, kept_triangles_of};
    use proptest::prelude::*;
    use sphcover_core::MeshTopology;

    /// The mesh without the triangles marked.
    fn without(mesh: &TriMesh, removed: &[bool]) -> TriMesh {
        let keep: Vec<bool> = removed.iter().map(|r| !r).collect();
        kept_triangles_of(mesh, &keep)
    }

    proptest! {
        /// Whatever may be removed and in whatever order, the collapses keep the components
        /// and the Euler characteristic (with holes punched first, so that the removable
        /// triangles may join them to each other and to the rim).
        #[test]
        fn collapsing_keeps_the_topology(n in 2u32..7,
                                         holes in prop::collection::vec(any::<u16>(), 0..4),
                                         removable in prop::collection::vec(any::<bool>(), 72),
                                         priority in prop::collection::vec(0.0f64..1.0, 72)) {
            let full = grid(n, n);
            let nt = full.triangles.len();
            let punched: Vec<bool> =
                (0..nt).map(|t| holes.iter().any(|&h| h as usize % nt == t)).collect();
            let mesh = without(&full, &punched);
            let nt = mesh.triangles.len();
            let removable: Vec<bool> = (0..nt).map(|t| removable[t % removable.len()]).collect();
            let priority: Vec<f64> = (0..nt).map(|t| priority[t % priority.len()]).collect();
            let removed = collapse_in_order(&mesh, &removable, &priority);
            prop_assert!((0..nt).all(|t| removable[t] || !removed[t]));
            let before = MeshTopology::of(&mesh);
            let after = MeshTopology::of(&without(&mesh, &removed));
            prop_assert_eq!(after.euler_characteristic(), before.euler_characteristic());
            prop_assert_eq!(after.components, before.components);
        }

        /// On a disk every triangle may go but one: the collapses eat it down to a single
        /// triangle, which stays as the component it is.
        #[test]
        fn a_disk_collapses_to_one_triangle(n in 1u32..7,
                                            priority in prop::collection::vec(0.0f64..1.0, 72)) {
            let mesh = grid(n, n);
            let nt = mesh.triangles.len();
            let priority: Vec<f64> = (0..nt).map(|t| priority[t % priority.len()]).collect();
            let removed = collapse_in_order(&mesh, &vec![true; nt], &priority);
            prop_assert_eq!(removed.iter().filter(|&&r| !r).count(), 1);
        }
    }

    /// A strip one square wide between two holes keeps a triangle: taking both of its
    /// triangles would join the holes.
    #[test]
    fn a_strip_between_holes_keeps_a_triangle() {
        // 5 × 3 squares, holes at squares (1, 1) and (3, 1), the strip (2, 1) between them
        // removable.
        let five = grid(5, 3);
        let square = |i: usize, j: usize| [2 * (i + 5 * j), 2 * (i + 5 * j) + 1];
        let mut punched = vec![false; 30];
        for t in square(1, 1).into_iter().chain(square(3, 1)) {
            punched[t] = true;
        }
        let mesh = without(&five, &punched);
        // Indices shift by the two triangles of square (1, 1) punched before the strip.
        let strip = square(2, 1).map(|t| t - 2);
        let mut removable = vec![false; mesh.triangles.len()];
        for t in strip {
            removable[t] = true;
        }
        let removed = collapse_in_order(&mesh, &removable, &vec![0.0; mesh.triangles.len()]);
        assert!(strip.iter().any(|&t| !removed[t]));
        let before = MeshTopology::of(&mesh);
        let after = MeshTopology::of(&without(&mesh, &removed));
        assert_eq!(after.euler_characteristic(), before.euler_characteristic());
    }
}
