//! Topology of a triangle mesh: connected components, boundary and non-manifold edges,
//! non-manifold vertices, orientation consistency and the Euler characteristic.
//!
//! Reconstruction promises "a watertight 2-manifold where the object is closed" and the
//! skeleton promises a sheet with the ground truth's Euler characteristic; both, and the
//! benchmark scores, are checked with this one analysis so they cannot disagree.
//!
//! ```
//! use sphcover_core::{TriMesh, DVec3};
//! use sphcover_core::mesh_topology::MeshTopology;
//!
//! // A tetrahedron's surface: closed, one component, χ = 2.
//! let v = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
//! let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
//! let topo = MeshTopology::of(&TriMesh::new(v, t));
//! assert!(topo.is_watertight());
//! assert_eq!((topo.components, topo.euler_characteristic()), (1, 2));
//! ```

use rayon::prelude::*;

use crate::mesh::TriMesh;

/// Counts describing the topology of a [`TriMesh`].
///
/// Triangles with an out-of-range or repeated vertex index are *invalid*: they are counted
/// and otherwise ignored, so the analysis never fails. Vertices used by no valid triangle
/// are ignored too (they do not count towards components or the Euler characteristic).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MeshTopology {
    /// Vertices used by at least one valid triangle.
    pub used_vertices: usize,
    /// Unique undirected edges of the valid triangles.
    pub edges: usize,
    /// Valid triangles.
    pub faces: usize,
    /// Triangles skipped because an index is out of range or repeated.
    pub invalid_triangles: usize,
    /// Edges used by exactly one triangle.
    pub boundary_edges: usize,
    /// Edges used by three or more triangles.
    pub non_manifold_edges: usize,
    /// Edges shared by two triangles that traverse it in the same direction (inconsistent
    /// winding between the two).
    pub inconsistent_edges: usize,
    /// Vertices whose incident triangles form more than one fan (a "bow tie").
    pub non_manifold_vertices: usize,
    /// Connected components (triangles sharing a vertex are connected).
    pub components: usize,
    /// For each triangle, its component (`u32::MAX` for invalid triangles). Components are
    /// numbered by their first triangle.
    pub triangle_component: Vec<u32>,
}

impl MeshTopology {
    /// Analyses `mesh`.
    pub fn of(mesh: &TriMesh) -> MeshTopology {
        let nv = mesh.vertices.len();
        let valid: Vec<bool> = mesh
            .triangles
            .par_iter()
            .map(|t| {
                t.iter().all(|&v| (v as usize) < nv) && t[0] != t[1] && t[1] != t[2] && t[0] != t[2]
            })
            .collect();
        let faces = valid.iter().filter(|&&v| v).count();

        // Directed half-edges (min, max, forward?, triangle), sorted so the uses of one
        // undirected edge are adjacent; the triangle index makes the order total, hence
        // independent of the thread count.
        let mut half: Vec<(u64, u32, bool)> = Vec::with_capacity(3 * faces);
        for (t, tri) in mesh.triangles.iter().enumerate() {
            if !valid[t] {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let key = (u64::from(a.min(b)) << 32) | u64::from(a.max(b));
                half.push((key, t as u32, a < b));
            }
        }
        half.par_sort_unstable();

        let mut topo = MeshTopology {
            faces,
            invalid_triangles: mesh.triangles.len() - faces,
            ..MeshTopology::default()
        };
        let mut start = 0;
        while start < half.len() {
            let key = half[start].0;
            let mut end = start + 1;
            while end < half.len() && half[end].0 == key {
                end += 1;
            }
            topo.edges += 1;
            match end - start {
                1 => topo.boundary_edges += 1,
                2 => {
                    if half[start].2 == half[start + 1].2 {
                        topo.inconsistent_edges += 1;
                    }
                }
                _ => topo.non_manifold_edges += 1,
            }
            start = end;
        }

        let mut used = vec![false; nv];
        let mut sets = DisjointSets::new(nv);
        for (t, tri) in mesh.triangles.iter().enumerate() {
            if valid[t] {
                for &v in tri {
                    used[v as usize] = true;
                }
                sets.union(tri[0], tri[1]);
                sets.union(tri[0], tri[2]);
            }
        }
        topo.used_vertices = used.iter().filter(|&&u| u).count();

        let mut component_of_root = vec![u32::MAX; nv];
        topo.triangle_component = vec![u32::MAX; mesh.triangles.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            if valid[t] {
                let root = sets.find(tri[0]) as usize;
                if component_of_root[root] == u32::MAX {
                    component_of_root[root] = topo.components as u32;
                    topo.components += 1;
                }
                topo.triangle_component[t] = component_of_root[root];
            }
        }
        topo.non_manifold_vertices = count_non_manifold_vertices(mesh, &valid);
        topo
    }

    /// `V − E + F` over the valid part of the mesh.
    pub fn euler_characteristic(&self) -> i64 {
        self.used_vertices as i64 - self.edges as i64 + self.faces as i64
    }

    /// Every edge is shared by exactly two triangles (no boundary, no non-manifold edge).
    pub fn is_watertight(&self) -> bool {
        self.faces > 0 && self.boundary_edges == 0 && self.non_manifold_edges == 0
    }

    /// Every edge has at most two triangles and every vertex a single fan (a 2-manifold,
    /// possibly with boundary).
    pub fn is_manifold(&self) -> bool {
        self.non_manifold_edges == 0 && self.non_manifold_vertices == 0
    }

    /// Watertight, manifold, consistently wound and free of invalid triangles: a closed
    /// oriented 2-manifold.
    pub fn is_closed_oriented_manifold(&self) -> bool {
        self.is_watertight()
            && self.is_manifold()
            && self.inconsistent_edges == 0
            && self.invalid_triangles == 0
    }

    /// The number of triangles in each component.
    pub fn component_sizes(&self) -> Vec<usize> {
        let mut sizes = vec![0; self.components];
        for &c in &self.triangle_component {
            if c != u32::MAX {
                sizes[c as usize] += 1;
            }
        }
        sizes
    }
}

/// Counts vertices whose incident triangles do not form one edge-connected fan.
fn count_non_manifold_vertices(mesh: &TriMesh, valid: &[bool]) -> usize {
    let nv = mesh.vertices.len();
    let mut offsets = vec![0u32; nv + 1];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if valid[t] {
            for &v in tri {
                offsets[v as usize + 1] += 1;
            }
        }
    }
    for i in 0..nv {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut incident = vec![0u32; offsets[nv] as usize];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if valid[t] {
            for &v in tri {
                incident[fill[v as usize] as usize] = t as u32;
                fill[v as usize] += 1;
            }
        }
    }
    (0..nv)
        .into_par_iter()
        .filter(|&v| {
            let fan = &incident[offsets[v] as usize..offsets[v + 1] as usize];
            fan.len() > 1 && !is_single_fan(mesh, v as u32, fan)
        })
        .count()
}

/// Whether the triangles around `v` are connected through edges that contain `v`.
fn is_single_fan(mesh: &TriMesh, v: u32, fan: &[u32]) -> bool {
    // Each triangle around v links its two other vertices; the fan is one piece when those
    // links form one connected graph over the triangles.
    let others: Vec<[u32; 2]> = fan
        .iter()
        .map(|&t| {
            let tri = mesh.triangles[t as usize];
            let k = tri.iter().position(|&x| x == v).unwrap_or(0);
            [tri[(k + 1) % 3], tri[(k + 2) % 3]]
        })
        .collect();
    let mut sets = DisjointSets::new(fan.len());
    for a in 0..fan.len() {
        for b in a + 1..fan.len() {
            if others[a].iter().any(|x| others[b].contains(x)) {
                sets.union(a as u32, b as u32);
            }
        }
    }
    let root = sets.find(0);
    (1..fan.len() as u32).all(|i| sets.find(i) == root)
}

/// Union–find with path halving and union by index (deterministic roots).
struct DisjointSets {
    parent: Vec<u32>,
}

impl DisjointSets {
    fn new(n: usize) -> DisjointSets {
        DisjointSets {
            parent: (0..n as u32).collect(),
        }
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let grand = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = grand;
            x = grand;
        }
        x
    }

    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.parent[hi as usize] = lo;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use proptest::prelude::*;

    fn tetrahedron() -> TriMesh {
        let v = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        TriMesh::new(v, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    }

    /// A closed torus of `n × m` quads split into triangles: χ = 0.
    fn torus(n: u32, m: u32) -> TriMesh {
        let mut v = Vec::new();
        for i in 0..n {
            for j in 0..m {
                let (a, b) = (
                    i as f64 / n as f64 * std::f64::consts::TAU,
                    j as f64 / m as f64 * std::f64::consts::TAU,
                );
                v.push(DVec3::new(
                    (2.0 + b.cos()) * a.cos(),
                    (2.0 + b.cos()) * a.sin(),
                    b.sin(),
                ));
            }
        }
        let id = |i: u32, j: u32| (i % n) * m + (j % m);
        let mut t = Vec::new();
        for i in 0..n {
            for j in 0..m {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        TriMesh::new(v, t)
    }

    #[test]
    fn closed_surfaces_have_their_euler_characteristic() {
        let topo = MeshTopology::of(&torus(8, 6));
        assert!(topo.is_closed_oriented_manifold());
        assert_eq!((topo.components, topo.euler_characteristic()), (1, 0));
        let topo = MeshTopology::of(&tetrahedron());
        assert!(topo.is_closed_oriented_manifold());
        assert_eq!(topo.euler_characteristic(), 2);
    }

    #[test]
    fn open_flipped_and_broken_meshes_are_reported() {
        let mut open = tetrahedron();
        open.triangles.pop();
        let topo = MeshTopology::of(&open);
        assert_eq!((topo.boundary_edges, topo.euler_characteristic()), (3, 1));
        assert!(!topo.is_watertight() && topo.is_manifold());

        let mut flipped = tetrahedron();
        flipped.triangles[0].swap(1, 2);
        assert_eq!(MeshTopology::of(&flipped).inconsistent_edges, 3);

        let mut broken = tetrahedron();
        broken.triangles.push([0, 0, 1]);
        broken.triangles.push([0, 1, 99]);
        let topo = MeshTopology::of(&broken);
        assert_eq!((topo.invalid_triangles, topo.faces), (2, 4));
        assert!(topo.is_watertight() && !topo.is_closed_oriented_manifold());
    }

    #[test]
    fn bow_tie_and_fin_are_non_manifold() {
        // Two tetrahedra sharing only vertex 0.
        let mut m = tetrahedron();
        let shift = DVec3::new(-1.0, -1.0, -1.0);
        m.vertices
            .extend([shift * DVec3::X, shift * DVec3::Y, shift * DVec3::Z]);
        m.triangles
            .extend([[0, 4, 5], [0, 6, 4], [0, 5, 6], [4, 6, 5]]);
        let topo = MeshTopology::of(&m);
        assert_eq!((topo.non_manifold_vertices, topo.components), (1, 1));
        assert!(topo.is_watertight() && !topo.is_manifold());

        // A third triangle on edge (0, 1).
        let mut fin = tetrahedron();
        fin.vertices.push(DVec3::new(0.5, -1.0, 0.0));
        fin.triangles.push([0, 1, 4]);
        assert_eq!(MeshTopology::of(&fin).non_manifold_edges, 1);
    }

    #[test]
    fn empty_mesh_is_not_watertight() {
        let topo = MeshTopology::of(&TriMesh::default());
        assert_eq!(topo.components, 0);
        assert!(!topo.is_watertight());
    }

    proptest! {
        // Disjoint copies add components and Euler characteristics; relabelling vertices and
        // reordering triangles changes nothing but the component numbering.
        #[test]
        fn components_and_euler_are_additive(copies in 1usize..5, n in 3u32..8, m in 3u32..8,
                                             perm_seed in any::<u64>()) {
            let one = torus(n, m);
            let mut all = TriMesh::default();
            for c in 0..copies {
                let base = all.vertices.len() as u32;
                all.vertices.extend(one.vertices.iter().map(|&p| p + DVec3::X * 10.0 * c as f64));
                all.triangles.extend(one.triangles.iter().map(|t| t.map(|v| v + base)));
            }
            all.vertices.push(DVec3::ONE); // an unused vertex is ignored
            let topo = MeshTopology::of(&all);
            prop_assert_eq!(topo.components, copies);
            prop_assert_eq!(topo.euler_characteristic(), 0);
            prop_assert!(topo.is_closed_oriented_manifold());

            let nv = all.vertices.len() as u32;
            let step = (perm_seed % u64::from(nv - 1)) as u32 * 2 + 1;
            let relabel = |v: u32| (v * step) % nv;
            if (1..nv).all(|k| relabel(k) != relabel(0)) {
                let mut shuffled = all.clone();
                for (i, p) in all.vertices.iter().enumerate() {
                    shuffled.vertices[relabel(i as u32) as usize] = *p;
                }
                shuffled.triangles = all.triangles.iter().rev().map(|t| t.map(relabel)).collect();
                let again = MeshTopology::of(&shuffled);
                prop_assert_eq!(again.components, topo.components);
                prop_assert_eq!(again.euler_characteristic(), 0);
                prop_assert!(again.is_closed_oriented_manifold());
            }
        }
    }
}
