//! Vertices whose triangles form several fans, made single.
//!
//! Where the meshed region ends (`f` undefined, trimming) a vertex can keep two separate
//! fans, and where two sheets pass through one cell two closed fans can share a vertex. This
//! last pass makes the mesh a 2-manifold there; it works on the finished mesh alone, after
//! trimming, and knows nothing of the grid.
//!
//! A closed fan (a full ring of triangles around the vertex) belongs to a closed sheet and is
//! kept whole: each closed fan gets a copy of the vertex. An open fan (a path of triangles:
//! the vertex is on a boundary) is not worth a copy: two copies at one position are a
//! boundary that other tools weld back into a pinched vertex, and count differently (the
//! Euler characteristic of the file then depends on the reader). So at a pinched vertex the
//! open fans are removed, except the largest when no closed fan is there; removing them can
//! pinch a neighbour, so the pass repeats, and splits whatever is left after a few rounds.

use rayon::prelude::*;
use sphcover_core::{DisjointSets, TriMesh, VertexTriangles, remove_unused_vertices};

/// Rounds of open-fan removal before the remaining pinches are split.
const REMOVAL_ROUNDS: usize = 4;

/// What [`resolve_fans`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct FanRepair {
    /// Triangles of open fans removed.
    pub removed_triangles: usize,
    /// Copies of vertices made for closed fans (and for pinches left after the rounds).
    pub split_vertices: usize,
}

/// Makes every vertex a single fan (see the module docs).
pub(super) fn resolve_fans(mesh: &mut TriMesh) -> FanRepair {
    let mut repair = FanRepair::default();
    for round in 0.. {
        // Nearly always empty: one pass over the vertices, and nothing else to do.
        let pinches = pinched_vertices(mesh);
        let dropped: Vec<u32> = if round < REMOVAL_ROUNDS {
            pinches
                .iter()
                .flat_map(|p| p.tris.iter().zip(p.kept_fans()))
                .filter(|&(_, keep)| !keep)
                .map(|(&t, _)| t)
                .collect()
        } else {
            Vec::new()
        };
        if dropped.is_empty() {
            repair.split_vertices = split_fans(mesh, pinches);
            break;
        }
        let mut remove = vec![false; mesh.triangles.len()];
        for t in dropped {
            remove[t as usize] = true;
        }
        let before = mesh.triangles.len();
        let mut k = remove.iter();
        mesh.triangles.retain(|_| !*k.next().unwrap_or(&false));
        repair.removed_triangles += before - mesh.triangles.len();
        remove_unused_vertices(mesh);
    }
    repair
}

/// A vertex whose triangles form several fans.
struct Pinch {
    vertex: usize,
    /// Its incident triangles.
    tris: Vec<u32>,
    /// The fan of each.
    fan: Vec<u32>,
    /// Whether each fan is closed, by fan number.
    closed: Vec<bool>,
}

impl Pinch {
    /// Whether each incident triangle stays: closed fans do; open fans only when no closed
    /// fan is there, and then only the largest (ties: the lowest fan number).
    fn kept_fans(&self) -> impl Iterator<Item = bool> + '_ {
        let fans = self.closed.len();
        let mut size = vec![0usize; fans];
        for &f in &self.fan {
            size[f as usize] += 1;
        }
        let largest_open = if self.closed.iter().any(|&c| c) {
            None
        } else {
            (0..fans).rev().max_by_key(|&f| size[f])
        };
        self.fan
            .iter()
            .map(move |&f| self.closed[f as usize] || Some(f as usize) == largest_open)
    }
}

/// The vertices of several fans, ascending.
fn pinched_vertices(mesh: &TriMesh) -> Vec<Pinch> {
    let incident = VertexTriangles::of(mesh);
    (0..mesh.vertices.len())
        .into_par_iter()
        .with_min_len(1024)
        .filter_map(|v| {
            let tris = incident.triangles_at(v);
            if is_single_fan(v as u32, tris, &mesh.triangles) == Some(true) {
                return None;
            }
            let fan = fans_of(v as u32, tris, &mesh.triangles)?;
            let closed = closed_fans(v as u32, tris, &fan, &mesh.triangles);
            Some(Pinch {
                vertex: v,
                tris: tris.to_vec(),
                fan,
                closed,
            })
        })
        .collect()
}

/// Whether each fan of `v` is a full ring: every edge `(v, w)` of its triangles is held by
/// exactly two of them.
fn closed_fans(v: u32, tris: &[u32], fan: &[u32], triangles: &[[u32; 3]]) -> Vec<bool> {
    let fans = fan.iter().copied().max().map_or(0, |m| m as usize + 1);
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(2 * tris.len());
    for (&t, &f) in tris.iter().zip(fan) {
        edges.extend(
            triangles[t as usize]
                .iter()
                .filter(|&&w| w != v)
                .map(|&w| (f, w)),
        );
    }
    edges.sort_unstable();
    let mut closed = vec![true; fans];
    for group in edges.chunk_by(|a, b| a == b) {
        if group.len() != 2 {
            closed[group[0].0 as usize] = false;
        }
    }
    closed
}

/// Splits every vertex of `pinches` (the mesh's [`pinched_vertices`]) into one vertex per
/// fan; returns how many new vertices were made.
fn split_fans(mesh: &mut TriMesh, pinches: Vec<Pinch>) -> usize {
    let n = mesh.vertices.len();
    let mut added = 0;
    for Pinch {
        vertex: v,
        tris,
        fan,
        ..
    } in pinches
    {
        let count = fan.iter().copied().max().unwrap_or(0) as usize + 1;
        let copies: Vec<u32> = std::iter::once(v as u32)
            .chain((1..count).map(|k| (n + added + k - 1) as u32))
            .collect();
        for _ in 1..count {
            mesh.vertices.push(mesh.vertices[v]);
            if let Some(normals) = &mut mesh.normals {
                normals.push(normals[v]);
            }
            if let Some(values) = &mut mesh.values {
                values.push(values[v]);
            }
            if let Some(colors) = &mut mesh.colors {
                colors.push(colors[v]);
            }
        }
        added += count - 1;
        for (&t, &f) in tris.iter().zip(&fan) {
            for corner in &mut mesh.triangles[t as usize] {
                if *corner == v as u32 {
                    *corner = copies[f as usize];
                }
            }
        }
    }
    added
}

/// Most incident triangles a vertex may have for [`is_single_fan`] to decide.
const QUICK_FAN_MAX: usize = 32;

/// Whether the triangles `tris` (all holding `v` once) form a single fan, joined as in
/// [`fans_of`]; `None` when it cannot tell quickly (more than [`QUICK_FAN_MAX`] triangles, a
/// degenerate triangle). Nearly every vertex of a surface net is one fan of about six
/// triangles: walking around it on the stack, without the sorting and the lists of
/// [`fans_of`], the splitting pass takes about half the time.
fn is_single_fan(v: u32, tris: &[u32], triangles: &[[u32; 3]]) -> Option<bool> {
    let k = tris.len();
    if k <= 1 {
        return Some(true);
    }
    if k > QUICK_FAN_MAX {
        return None;
    }
    // The two other corners of each triangle: the ends of its two edges at `v`.
    let mut ends = [[0u32; 2]; QUICK_FAN_MAX];
    for (pair, &t) in ends.iter_mut().zip(tris) {
        let [x, y, z] = triangles[t as usize];
        *pair = if x == v {
            [y, z]
        } else if y == v {
            [z, x]
        } else {
            [x, y]
        };
        if pair[0] == pair[1] || pair.contains(&v) {
            return None;
        }
    }
    let ends = &ends[..k];
    // The triangle across the edge (v, w) from triangle `from`: the edge joins two triangles
    // only when exactly two hold it.
    let across = |from: usize, w: u32| -> Option<usize> {
        let mut found = None;
        for (j, pair) in ends.iter().enumerate() {
            if j != from && pair.contains(&w) {
                if found.is_some() {
                    return None;
                }
                found = Some(j);
            }
        }
        found
    };
    // Each triangle meets at most two others, so triangle 0's fan is a cycle or a path: walk
    // it one way, and when that ends (a boundary) the other way.
    let mut seen = 1;
    for start in [1, 0] {
        let (mut at, mut w) = (0, ends[0][start]);
        while let Some(next) = across(at, w) {
            if next == 0 {
                return (start == 1).then_some(seen == k);
            }
            seen += 1;
            if seen > k {
                return None;
            }
            w = if ends[next][0] == w {
                ends[next][1]
            } else {
                ends[next][0]
            };
            at = next;
        }
    }
    Some(seen == k)
}

/// The fan of each triangle in `tris` (all holding `v`), numbered from 0 in order of first
/// appearance, or `None` when they form a single fan.
fn fans_of(v: u32, tris: &[u32], triangles: &[[u32; 3]]) -> Option<Vec<u32>> {
    if tris.len() <= 1 {
        return None;
    }
    let mut fans = DisjointSets::new(tris.len());
    // Each other corner w of an incident triangle names the edge (v, w).
    let mut by_other: Vec<(u32, usize)> = Vec::with_capacity(2 * tris.len());
    for (i, &t) in tris.iter().enumerate() {
        for &w in &triangles[t as usize] {
            if w != v {
                by_other.push((w, i));
            }
        }
    }
    by_other.sort_unstable();
    for group in by_other.chunk_by(|a, b| a.0 == b.0) {
        if let [(_, a), (_, b)] = group {
            fans.union(*a as u32, *b as u32);
        }
    }
    let mut label = vec![u32::MAX; tris.len()];
    let mut next = 0;
    let mut fan = Vec::with_capacity(tris.len());
    for i in 0..tris.len() as u32 {
        let r = fans.find(i) as usize;
        if label[r] == u32::MAX {
            label[r] = next;
            next += 1;
        }
        fan.push(label[r]);
    }
    (next > 1).then_some(fan)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use proptest::prelude::*;
    use sphcover_core::MeshTopology;

    /// Two closed tetrahedra glued at a vertex (a bow tie) or along an edge (four triangles
    /// on it) come apart into two closed oriented manifolds.
    #[test]
    fn split_fans_separates_pinched_sheets() {
        let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let tet = |v: [u32; 4]| faces.map(|f: [u32; 3]| f.map(|k| v[k as usize]));
        let mut vertices = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        vertices.extend([-DVec3::X, -DVec3::Y, -DVec3::Z]);
        // Sharing vertex 0.
        let mut pinched = TriMesh::new(
            vertices.clone(),
            [tet([0, 1, 2, 3]), tet([0, 4, 5, 6])].concat(),
        );
        pinched.normals = Some(vertices.clone());
        pinched.values = Some((0..7).map(f64::from).collect());
        assert_eq!(MeshTopology::of(&pinched).non_manifold_vertices, 1);
        assert_eq!(
            {
                let pinches = pinched_vertices(&pinched);
                split_fans(&mut pinched, pinches)
            },
            1
        );
        let topo = MeshTopology::of(&pinched);
        assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
        assert_eq!((topo.components, topo.euler_characteristic()), (2, 4));
        assert_eq!(pinched.normals.as_ref().map(Vec::len), Some(8));
        assert_eq!(pinched.vertices[7], DVec3::ZERO);
        assert_eq!(
            pinched.values.as_ref().map(|v| (v.len(), v[7])),
            Some((8, 0.0))
        );
        // Sharing the edge 0–1: the second tetrahedron is the first turned half a turn about
        // the x axis, so it is wound outwards too.
        let mut glued = TriMesh::new(vertices, [tet([0, 1, 2, 3]), tet([0, 1, 5, 6])].concat());
        assert_eq!(MeshTopology::of(&glued).non_manifold_edges, 1);
        assert_eq!(
            {
                let pinches = pinched_vertices(&glued);
                split_fans(&mut glued, pinches)
            },
            2
        );
        let topo = MeshTopology::of(&glued);
        assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
        assert_eq!((topo.components, topo.euler_characteristic()), (2, 4));
    }

    #[test]
    fn open_fans_at_a_pinch_are_removed_and_closed_ones_split() {
        let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let tet = |v: [u32; 4]| faces.map(|f: [u32; 3]| f.map(|k| v[k as usize]));
        let vertices = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            -DVec3::X,
            -DVec3::Y,
            -DVec3::Z,
        ];
        // Two closed sheets at vertex 0: both kept, the vertex split.
        let mut closed = TriMesh::new(
            vertices.clone(),
            [tet([0, 1, 2, 3]), tet([0, 4, 5, 6])].concat(),
        );
        let repair = resolve_fans(&mut closed);
        assert_eq!((repair.removed_triangles, repair.split_vertices), (0, 1));
        assert!(MeshTopology::of(&closed).is_closed_oriented_manifold());

        // A bow tie of an open fan of two triangles and one of one: the smaller goes, and no
        // vertex is duplicated.
        let mut bow_tie = TriMesh::new(vertices.clone(), vec![[0, 1, 2], [0, 2, 3], [0, 4, 5]]);
        let repair = resolve_fans(&mut bow_tie);
        assert_eq!((repair.removed_triangles, repair.split_vertices), (1, 0));
        assert_eq!(bow_tie.triangles.len(), 2);
        assert_eq!(bow_tie.vertices.len(), 4);
        let topo = MeshTopology::of(&bow_tie);
        assert!(
            topo.is_manifold() && topo.non_manifold_vertices == 0,
            "{topo:?}"
        );

        // An open fan touching a closed sheet: the open fan goes, the sheet stays closed.
        let mut touching = TriMesh::new(
            vertices,
            [tet([0, 1, 2, 3]).to_vec(), vec![[0, 4, 5], [0, 5, 6]]].concat(),
        );
        let repair = resolve_fans(&mut touching);
        assert_eq!((repair.removed_triangles, repair.split_vertices), (2, 0));
        assert!(MeshTopology::of(&touching).is_closed_oriented_manifold());
    }

    proptest! {
        /// Whatever the triangles, the repair leaves every vertex a single fan and the mesh
        /// consistent.
        #[test]
        fn resolved_meshes_have_single_fans(
            triangles in prop::collection::vec([0u32..8, 0u32..8, 0u32..8], 1..24),
        ) {
            let triangles: Vec<[u32; 3]> = triangles
                .into_iter()
                .filter(|[a, b, c]| a != b && b != c && a != c)
                .collect();
            let vertices: Vec<DVec3> = (0..8).map(|i| DVec3::new(i as f64, (i * i) as f64, 1.0)).collect();
            let mut mesh = TriMesh::new(vertices, triangles);
            resolve_fans(&mut mesh);
            prop_assert!(pinched_vertices(&mesh).is_empty());
            prop_assert!(mesh.check().is_ok());
        }

        /// The quick fan test agrees with the union–find of `fans_of` wherever it decides: on
        /// random triangles around vertex 0 over a few other vertices (closed and open fans,
        /// several fans, edges held by three or more triangles, repeated triangles).
        #[test]
        fn quick_fan_test_agrees_with_fans_of(
            others in prop::collection::vec((1u32..9, 1u32..9), 1..14),
            degenerate in prop::option::of(0usize..14),
        ) {
            let mut triangles: Vec<[u32; 3]> =
                others.iter().map(|&(a, b)| [0, a, b]).collect();
            if let Some(d) = degenerate.filter(|&d| d < triangles.len()) {
                triangles[d] = [0, 0, 3];
            }
            let tris: Vec<u32> = (0..triangles.len() as u32).collect();
            if let Some(single) = is_single_fan(0, &tris, &triangles) {
                prop_assert_eq!(single, fans_of(0, &tris, &triangles).is_none());
            }
        }
    }

    #[test]
    fn quick_fan_test_decides_closed_and_pinched_fans() {
        // A closed fan of six triangles around 0, then the same with a second closed fan.
        let ring = |base: u32| -> Vec<[u32; 3]> {
            (0..6).map(|i| [0, base + i, base + (i + 1) % 6]).collect()
        };
        let one = ring(1);
        let tris: Vec<u32> = (0..6).collect();
        assert_eq!(is_single_fan(0, &tris, &one), Some(true));
        let two = [ring(1), ring(11)].concat();
        let tris: Vec<u32> = (0..12).collect();
        assert_eq!(is_single_fan(0, &tris, &two), Some(false));
        // An open fan (a boundary vertex) listed from its middle.
        let open: Vec<[u32; 3]> = [3, 4, 1, 2].iter().map(|&i| [0, i, i + 1]).collect();
        assert_eq!(is_single_fan(0, &[0, 1, 2, 3], &open), Some(true));
    }
}
