//! Topology of a triangle mesh: connected components, boundary and non-manifold edges,
//! non-manifold vertices, orientation consistency and the Euler characteristic.
//!
//! The method is described on [`MeshTopology`].

use rayon::prelude::*;

use crate::disjoint_sets::DisjointSets;
use crate::mesh::{TriMesh, bucketed};

/// Counts describing the topology of a [`TriMesh`].
///
/// Triangles with an out-of-range or repeated vertex index are *invalid*: they are counted
/// and otherwise ignored, so the analysis never fails. Vertices used by no valid triangle
/// are ignored too (they do not count towards components or the Euler characteristic).
///
/// Reconstruction promises "a watertight 2-manifold where the object is closed" and the
/// skeleton promises a sheet with the ground truth's Euler characteristic; both, and the
/// benchmark scores, are checked with this one analysis so they cannot disagree.
///
/// ```
/// use sphcover_core::{TriMesh, DVec3};
/// use sphcover_core::MeshTopology;
///
/// // A tetrahedron's surface: closed, one component, χ = 2.
/// let v = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
/// let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
/// let topo = MeshTopology::of(&TriMesh::new(v, t));
/// assert!(topo.is_watertight());
/// assert_eq!((topo.components, topo.euler_characteristic()), (1, 2));
/// ```
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
    /// For each component, whether it has a boundary edge.
    pub open_component: Vec<bool>,
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

        // The fans of the vertices and the edges and components are independent passes,
        // each partly sequential: side by side they keep both threads of a small machine busy.
        let (non_manifold_vertices, mut topo) = rayon::join(
            || count_non_manifold_vertices(mesh, &valid),
            || {
                let mut topo = MeshTopology {
                    faces,
                    invalid_triangles: mesh.triangles.len() - faces,
                    ..MeshTopology::default()
                };
                let boundary_vertices = count_edges(mesh, &valid, &mut topo);
                label_components(mesh, &valid, &mut topo);
                mark_open_components(mesh, &boundary_vertices, &mut topo);
                topo
            },
        );
        topo.non_manifold_vertices = non_manifold_vertices;
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

/// Counts the undirected edges of the valid triangles into `topo`: all of them, boundary,
/// non-manifold and inconsistently wound ones; returns a vertex of each boundary edge.
///
/// The half-edges are bucketed by their lower vertex (a counting sort), and each bucket,
/// a few entries long, is sorted on its own: a sort of all `3F` half-edges by their vertex
/// pair would be about half the analysis time of a reconstruction's mesh.
fn count_edges(mesh: &TriMesh, valid: &[bool], topo: &mut MeshTopology) -> Vec<u32> {
    let half_edges = || {
        mesh.triangles
            .iter()
            .zip(valid)
            .filter(|&(_, &ok)| ok)
            .flat_map(|(tri, _)| (0..3).map(move |k| (tri[k], tri[(k + 1) % 3])))
    };
    // Each half-edge as (upper vertex, runs from the lower to the upper), by lower vertex.
    let (offsets, upper) = bucketed(mesh.vertices.len(), || {
        half_edges().map(|(a, b)| (a.min(b) as usize, (a.max(b), a < b)))
    });
    type Counts = (usize, usize, usize, usize);
    let add = |a: Counts, b: Counts| (a.0 + b.0, a.1 + b.1, a.2 + b.2, a.3 + b.3);
    let (counts, boundary_vertices) = offsets
        .par_windows(2)
        .enumerate()
        .with_min_len(1024)
        .map_init(Vec::new, |bucket, (v, w)| {
            bucket.clear();
            bucket.extend_from_slice(&upper[w[0] as usize..w[1] as usize]);
            bucket.sort_unstable();
            let mut counts = (0, 0, 0, 0);
            for run in bucket.chunk_by(|x, y| x.0 == y.0) {
                counts.0 += 1;
                match run {
                    [_] => counts.1 += 1,
                    [x, y] => counts.3 += usize::from(x.1 == y.1),
                    _ => counts.2 += 1,
                }
            }
            (counts, v as u32)
        })
        .fold(
            || ((0, 0, 0, 0), Vec::new()),
            |(sum, mut open), (counts, v)| {
                if counts.1 > 0 {
                    open.push(v);
                }
                (add(sum, counts), open)
            },
        )
        .reduce(
            || ((0, 0, 0, 0), Vec::new()),
            |(a, mut open), (b, more)| {
                open.extend(more);
                (add(a, b), open)
            },
        );
    topo.edges = counts.0;
    topo.boundary_edges = counts.1;
    topo.non_manifold_edges = counts.2;
    topo.inconsistent_edges = counts.3;
    boundary_vertices
}

/// Marks the components that hold a vertex of a boundary edge.
fn mark_open_components(mesh: &TriMesh, boundary_vertices: &[u32], topo: &mut MeshTopology) {
    topo.open_component = vec![false; topo.components];
    if boundary_vertices.is_empty() {
        return;
    }
    let mut component_of_vertex = vec![u32::MAX; mesh.vertices.len()];
    for (tri, &c) in mesh.triangles.iter().zip(&topo.triangle_component) {
        if c != u32::MAX {
            for &v in tri {
                component_of_vertex[v as usize] = c;
            }
        }
    }
    for &v in boundary_vertices {
        let c = component_of_vertex[v as usize];
        if c != u32::MAX {
            topo.open_component[c as usize] = true;
        }
    }
}

/// Counts the used vertices and labels the components of the valid triangles into `topo`.
fn label_components(mesh: &TriMesh, valid: &[bool], topo: &mut MeshTopology) {
    let nv = mesh.vertices.len();
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
}

/// Counts vertices whose incident triangles do not form one edge-connected fan.
fn count_non_manifold_vertices(mesh: &TriMesh, valid: &[bool]) -> usize {
    let nv = mesh.vertices.len();
    let corners = || {
        mesh.triangles
            .iter()
            .enumerate()
            .filter(|&(t, _)| valid[t])
            .flat_map(|(t, tri)| tri.iter().map(move |&v| (v as usize, t as u32)))
    };
    let (offsets, incident) = bucketed(nv, corners);
    (0..nv)
        .into_par_iter()
        .with_min_len(1024)
        .map_init(
            || (Vec::new(), DisjointSets::new(0)),
            |(others, sets), v| {
                let fan = &incident[offsets[v] as usize..offsets[v + 1] as usize];
                fan.len() > 1 && !is_single_fan(mesh, v as u32, fan, others, sets)
            },
        )
        .filter(|&non_manifold| non_manifold)
        .count()
}

/// Whether the triangles around `v` are connected through edges that contain `v`; `others`
/// and `sets` are scratch space.
fn is_single_fan(
    mesh: &TriMesh,
    v: u32,
    fan: &[u32],
    others: &mut Vec<[u32; 2]>,
    sets: &mut DisjointSets,
) -> bool {
    // Each triangle around v links its two other vertices; the fan is one piece when those
    // links form one connected graph over the triangles.
    others.clear();
    others.extend(fan.iter().map(|&t| {
        let tri = mesh.triangles[t as usize];
        let k = tri.iter().position(|&x| x == v).unwrap_or(0);
        [tri[(k + 1) % 3], tri[(k + 2) % 3]]
    }));
    sets.reset(fan.len());
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
        assert_eq!(topo.open_component, vec![true]);

        // A closed tetrahedron beside an open one: only the second component is open.
        let mut pair = tetrahedron();
        let far = open.vertices.iter().map(|v| *v + DVec3::splat(5.0));
        pair.vertices.extend(far);
        pair.triangles
            .extend(open.triangles.iter().map(|t| t.map(|v| v + 4)));
        let topo = MeshTopology::of(&pair);
        assert_eq!(topo.open_component, vec![false, true]);
        assert_eq!(MeshTopology::of(&tetrahedron()).open_component, vec![false]);

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

    /// Every count of [`MeshTopology`] by brute force: edges from a map of vertex pairs,
    /// fans and components by repeated merging over all pairs.
    fn brute_force(mesh: &TriMesh) -> MeshTopology {
        use std::collections::BTreeMap;
        let nv = mesh.vertices.len();
        let valid: Vec<usize> = (0..mesh.triangles.len())
            .filter(|&t| {
                let [a, b, c] = mesh.triangles[t];
                [a, b, c].iter().all(|&v| (v as usize) < nv) && a != b && b != c && a != c
            })
            .collect();
        let mut uses: BTreeMap<(u32, u32), Vec<bool>> = BTreeMap::new();
        for &t in &valid {
            let tri = mesh.triangles[t];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                uses.entry((a.min(b), a.max(b))).or_default().push(a < b);
            }
        }
        // Merges the labels of `items` until `linked` pairs share one: the classes.
        let classes = |items: &[usize], linked: &dyn Fn(usize, usize) -> bool| -> Vec<usize> {
            let mut label: Vec<usize> = (0..items.len()).collect();
            loop {
                let mut changed = false;
                for i in 0..items.len() {
                    for j in 0..items.len() {
                        if linked(items[i], items[j]) && label[j] > label[i] {
                            label[j] = label[i];
                            changed = true;
                        }
                    }
                }
                if !changed {
                    return label;
                }
            }
        };
        let shares = |t: usize, u: usize, v: u32| {
            let (a, b) = (mesh.triangles[t], mesh.triangles[u]);
            a.iter().any(|&x| x != v && b.contains(&x))
        };
        let mut non_manifold_vertices = 0;
        let mut used = 0;
        for v in 0..nv as u32 {
            let fan: Vec<usize> = valid
                .iter()
                .copied()
                .filter(|&t| mesh.triangles[t].contains(&v))
                .collect();
            used += usize::from(!fan.is_empty());
            let label = classes(&fan, &|t, u| shares(t, u, v));
            non_manifold_vertices += usize::from(label.iter().any(|&l| l != 0));
        }
        let label = classes(&valid, &|t, u| {
            mesh.triangles[t]
                .iter()
                .any(|x| mesh.triangles[u].contains(x))
        });
        let mut first_of_label = BTreeMap::new();
        let mut triangle_component = vec![u32::MAX; mesh.triangles.len()];
        for (i, &t) in valid.iter().enumerate() {
            let next = first_of_label.len() as u32;
            triangle_component[t] = *first_of_label.entry(label[i]).or_insert(next);
        }
        // A component is open when one of its triangles has an edge no other triangle has.
        let edge_of = |t: usize, k: usize| {
            let (a, b) = (mesh.triangles[t][k], mesh.triangles[t][(k + 1) % 3]);
            (a.min(b), a.max(b))
        };
        let holders = |e: (u32, u32)| {
            valid
                .iter()
                .filter(|&&u| (0..3).any(|k| edge_of(u, k) == e))
                .count()
        };
        let mut open_component = vec![false; first_of_label.len()];
        for &t in &valid {
            if (0..3).any(|k| holders(edge_of(t, k)) == 1) {
                open_component[triangle_component[t] as usize] = true;
            }
        }
        MeshTopology {
            used_vertices: used,
            edges: uses.len(),
            faces: valid.len(),
            invalid_triangles: mesh.triangles.len() - valid.len(),
            boundary_edges: uses.values().filter(|u| u.len() == 1).count(),
            non_manifold_edges: uses.values().filter(|u| u.len() > 2).count(),
            inconsistent_edges: uses
                .values()
                .filter(|u| u.len() == 2 && u[0] == u[1])
                .count(),
            non_manifold_vertices,
            components: first_of_label.len(),
            triangle_component,
            open_component,
        }
    }

    proptest! {
        // Triangle soups over a few vertices: repeated, fins, bow ties, flipped and invalid
        // triangles, unused vertices.
        #[test]
        fn matches_brute_force(
            nv in 0usize..12,
            triangles in prop::collection::vec(prop::array::uniform3(0u32..13), 0..30),
        ) {
            let mesh = TriMesh::new(vec![DVec3::ZERO; nv], triangles);
            prop_assert_eq!(MeshTopology::of(&mesh), brute_force(&mesh));
        }

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
