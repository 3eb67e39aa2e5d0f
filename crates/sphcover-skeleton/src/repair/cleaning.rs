//! Cleaning of the raw patch mesh (future work in thesis §6.4): weld coincident vertices,
//! drop degenerate triangles, drop fragments, fill tiny holes.
//!
//! The method is described on [`clean_sheet()`].

use std::collections::HashMap;

use glam::DVec3;
use sphcover_core::{
    DisjointSets, MeshTopology, TriMesh, VertexTriangles, remove_unused_vertices, triangle_area,
};

use super::retain_triangles;

/// Parameters of [`clean_sheet`]; lengths in voxels.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct CleaningParams {
    /// A component is dropped when its strength-weighted area is below this fraction of the
    /// largest component's.
    pub min_component_fraction: f64,
    /// A component is dropped when its area is below this many voxel areas.
    pub min_component_area_voxels: f64,
    /// Largest number of edges of a hole that is filled (with material at its centroid).
    pub max_hole_edges: usize,
    /// Largest perimeter of a hole that is filled.
    pub max_hole_perimeter_voxels: f64,
}

impl Default for CleaningParams {
    fn default() -> CleaningParams {
        CleaningParams {
            min_component_fraction: 0.05,
            min_component_area_voxels: 4.0,
            max_hole_edges: 200,
            max_hole_perimeter_voxels: 60.0,
        }
    }
}

/// [`CleaningParams`] in world units.
struct Limits {
    min_component_fraction: f64,
    min_component_area: f64,
    max_hole_edges: usize,
    max_hole_perimeter: f64,
}

impl CleaningParams {
    fn in_world(&self, voxel: f64) -> Limits {
        Limits {
            min_component_fraction: self.min_component_fraction,
            min_component_area: self.min_component_area_voxels * voxel * voxel,
            max_hole_edges: self.max_hole_edges,
            max_hole_perimeter: self.max_hole_perimeter_voxels * voxel,
        }
    }
}

/// What [`clean_sheet`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CleaningStats {
    /// Vertices merged into a coincident one.
    pub welded_vertices: usize,
    /// Triangles dropped because two of their corners coincide.
    pub degenerate_triangles: usize,
    /// Components before dropping fragments.
    pub components_before: usize,
    /// Components dropped.
    pub dropped_components: usize,
    /// Triangles dropped with them.
    pub dropped_triangles: usize,
    /// Holes filled.
    pub holes_filled: usize,
    /// Triangles removed to undo pinched (bow-tie) vertices.
    pub pinch_triangles: usize,
}

impl CleaningStats {
    /// Adds the counts of a later pass over the cleaned sheet; the components before
    /// cleaning stay those of the first pass.
    pub fn add_later_pass(&mut self, later: &CleaningStats) {
        self.welded_vertices += later.welded_vertices;
        self.degenerate_triangles += later.degenerate_triangles;
        self.dropped_components += later.dropped_components;
        self.dropped_triangles += later.dropped_triangles;
        self.holes_filled += later.holes_filled;
        self.pinch_triangles += later.pinch_triangles;
    }
}

/// Cleans a patch mesh whose per-vertex values are ridge strengths (missing values count
/// as 1); `voxel` is the length unit of `params` (world units). The output has no unused
/// vertex.
///
/// `is_material(x)` says whether there is material at `x`: a hole is filled only when there
/// is material at its centroid, so holes of the part itself (air in the middle) stay open
/// whatever their size.
///
/// * Welding: a tetrahedron crossed by a single ridge point puts its vertex `q_t` on that
///   point; welding makes the fans meeting there share it instead of leaving a crack.
/// * Fragments: noise and spurious ridges make small separate pieces. A component is kept
///   when its area weighted by the ridge strength `|λ1|` reaches a fraction of the largest
///   component's (faint ridges weigh little, whatever their size) and its plain area reaches
///   a minimum.
/// * Spurious holes: a boundary loop whose vertices all have exactly two boundary edges, with
///   a bounded number of edges and perimeter, and with material at its centroid, is a hole
///   left by tetrahedra where the ridge test failed (eigenvectors turning near rims and
///   junctions), not a hole of the part (which has air in its middle); it is closed by a fan
///   around its centroid.
pub fn clean_sheet(
    mesh: &TriMesh,
    params: &CleaningParams,
    voxel: f64,
    is_material: impl Fn(DVec3) -> bool,
) -> (TriMesh, CleaningStats) {
    let params = &params.in_world(voxel);
    let mut stats = CleaningStats::default();
    let mut mesh = weld_coincident(mesh, &mut stats);
    resolve_pinches(&mut mesh, &mut stats);
    fill_small_holes(&mut mesh, params, &is_material, &mut stats);
    resolve_pinches(&mut mesh, &mut stats);
    drop_fragments(&mut mesh, params, &mut stats);
    remove_unused_vertices(&mut mesh);
    (mesh, stats)
}

fn weld_coincident(mesh: &TriMesh, stats: &mut CleaningStats) -> TriMesh {
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(mesh.vertices.len());
    let mut map = Vec::with_capacity(mesh.vertices.len());
    for (i, v) in mesh.vertices.iter().enumerate() {
        // +0.0 and −0.0 are the same point.
        let key = (*v + DVec3::ZERO).to_array().map(f64::to_bits);
        let target = *first.entry(key).or_insert(i as u32);
        if target != i as u32 {
            stats.welded_vertices += 1;
        }
        map.push(target);
    }
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for tri in &mesh.triangles {
        let t = tri.map(|v| map[v as usize]);
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            stats.degenerate_triangles += 1;
        } else {
            triangles.push(t);
        }
    }
    TriMesh {
        vertices: mesh.vertices.clone(),
        triangles,
        normals: mesh.normals.clone(),
        values: mesh.values.clone(),
        colors: mesh.colors.clone(),
    }
}

/// Undoes pinched vertices: where the triangles around a vertex form several fans that meet
/// only at that vertex (a bow-tie, typically left where trimming removed a triangle between
/// two others along the boundary), only the largest fan is kept (ties: the one with the
/// lowest triangle index). Repeats while removals create new pinches (at most 4 rounds).
fn resolve_pinches(mesh: &mut TriMesh, stats: &mut CleaningStats) {
    for _ in 0..4 {
        let incident = VertexTriangles::of(mesh);
        let mut remove = vec![false; mesh.triangles.len()];
        let mut any = false;
        let mut fans = DisjointSets::new(0);
        for v in 0..mesh.vertices.len() {
            let around = incident.triangles_at(v);
            if around.len() < 2 {
                continue;
            }
            // The triangles around v, joined through a shared second vertex.
            fans.reset(around.len());
            let mut by_vertex: HashMap<u32, u32> = HashMap::new();
            for (k, &t) in around.iter().enumerate() {
                for &w in &mesh.triangles[t as usize] {
                    if w as usize == v {
                        continue;
                    }
                    if let Some(&j) = by_vertex.get(&w) {
                        fans.union(k as u32, j);
                    } else {
                        by_vertex.insert(w, k as u32);
                    }
                }
            }
            let mut size: HashMap<u32, usize> = HashMap::new();
            for k in 0..around.len() as u32 {
                *size.entry(fans.find(k)).or_insert(0) += 1;
            }
            if size.len() < 2 {
                continue;
            }
            let best = size
                .iter()
                .max_by(|a, b| a.1.cmp(b.1).then_with(|| b.0.cmp(a.0)))
                .map(|(&root, _)| root)
                .unwrap_or(0);
            for (k, &t) in around.iter().enumerate() {
                if fans.find(k as u32) != best {
                    remove[t as usize] = true;
                    any = true;
                }
            }
        }
        if !any {
            return;
        }
        let before = mesh.triangles.len();
        retain_triangles(&mut mesh.triangles, |t| !remove[t]);
        stats.pinch_triangles += before - mesh.triangles.len();
    }
}

fn drop_fragments(mesh: &mut TriMesh, params: &Limits, stats: &mut CleaningStats) {
    let topo = MeshTopology::of(mesh);
    stats.components_before = topo.components;
    if topo.components == 0 {
        return;
    }
    let mut area = vec![0.0; topo.components];
    let mut weighted = vec![0.0; topo.components];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let c = topo.triangle_component[t] as usize;
        let a = triangle_area(mesh, tri);
        let s = match &mesh.values {
            Some(v) => tri.iter().map(|&i| v[i as usize].abs()).sum::<f64>() / 3.0,
            None => 1.0,
        };
        area[c] += a;
        weighted[c] += a * s;
    }
    let largest = weighted.iter().copied().fold(0.0, f64::max);
    let keep: Vec<bool> = (0..topo.components)
        .map(|c| {
            weighted[c] >= params.min_component_fraction * largest
                && area[c] >= params.min_component_area
        })
        .collect();
    stats.dropped_components = keep.iter().filter(|&&k| !k).count();
    let before = mesh.triangles.len();
    retain_triangles(&mut mesh.triangles, |t| {
        keep[topo.triangle_component[t] as usize]
    });
    stats.dropped_triangles = before - mesh.triangles.len();
}

/// The loops of boundary edges (edges of one triangle) whose vertices each have exactly two
/// boundary edges and which have at most `max_edges` edges, each as its vertices in order,
/// from the lowest boundary vertex up; a walk that meets a branching or an already walked
/// vertex, or grows past `max_edges`, is no loop.
pub(crate) fn simple_boundary_loops(mesh: &TriMesh, max_edges: usize) -> Vec<Vec<u32>> {
    let mut edge_count: HashMap<(u32, u32), u32> = HashMap::new();
    for tri in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *edge_count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let mut boundary: Vec<(u32, u32)> = edge_count
        .into_iter()
        .filter(|&(_, c)| c == 1)
        .map(|(e, _)| e)
        .collect();
    boundary.sort_unstable();
    let mut adjacency: HashMap<u32, Vec<u32>> = HashMap::new();
    for &(a, b) in &boundary {
        adjacency.entry(a).or_default().push(b);
        adjacency.entry(b).or_default().push(a);
    }
    let mut visited: HashMap<u32, bool> = HashMap::new();
    let mut starts: Vec<u32> = adjacency.keys().copied().collect();
    starts.sort_unstable();
    let mut loops = Vec::new();
    for start in starts {
        if visited.contains_key(&start) || adjacency[&start].len() != 2 {
            continue;
        }
        let mut loop_vertices = vec![start];
        visited.insert(start, true);
        let (mut prev, mut cur) = (start, adjacency[&start][0]);
        let mut simple = true;
        while cur != start {
            let next = &adjacency[&cur];
            if next.len() != 2 || visited.contains_key(&cur) {
                simple = false;
                break;
            }
            visited.insert(cur, true);
            loop_vertices.push(cur);
            let n = if next[0] == prev { next[1] } else { next[0] };
            (prev, cur) = (cur, n);
            if loop_vertices.len() > max_edges {
                simple = false;
                break;
            }
        }
        if simple && loop_vertices.len() >= 3 {
            loops.push(loop_vertices);
        }
    }
    loops
}

fn fill_small_holes(
    mesh: &mut TriMesh,
    params: &Limits,
    is_material: &impl Fn(DVec3) -> bool,
    stats: &mut CleaningStats,
) {
    for loop_vertices in simple_boundary_loops(mesh, params.max_hole_edges) {
        let pos: Vec<DVec3> = loop_vertices
            .iter()
            .map(|&v| mesh.vertices[v as usize])
            .collect();
        let perimeter: f64 = (0..pos.len())
            .map(|k| pos[k].distance(pos[(k + 1) % pos.len()]))
            .sum();
        if perimeter > params.max_hole_perimeter {
            continue;
        }
        let centre = pos.iter().copied().sum::<DVec3>() / pos.len() as f64;
        if !is_material(centre) {
            continue;
        }
        let c = mesh.vertices.len() as u32;
        mesh.vertices.push(centre);
        if let Some(normals) = &mut mesh.normals {
            let n = normals[loop_vertices[0] as usize];
            normals.push(n);
        }
        if let Some(values) = &mut mesh.values {
            let mean = loop_vertices
                .iter()
                .map(|&v| values[v as usize])
                .sum::<f64>()
                / loop_vertices.len() as f64;
            values.push(mean);
        }
        for k in 0..loop_vertices.len() {
            let (a, b) = (
                loop_vertices[k],
                loop_vertices[(k + 1) % loop_vertices.len()],
            );
            mesh.triangles.push([a, b, c]);
        }
        stats.holes_filled += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `n × n` grid of unit squares, two triangles each, at height `z`, offset by `x0`.
    fn grid(n: u32, x0: f64, z: f64) -> TriMesh {
        let mut v = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                v.push(DVec3::new(x0 + i as f64, j as f64, z));
            }
        }
        let id = |i: u32, j: u32| j * (n + 1) + i;
        let mut t = Vec::new();
        for j in 0..n {
            for i in 0..n {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        TriMesh::new(v, t)
    }

    fn append(a: &mut TriMesh, b: &TriMesh) {
        let off = a.vertices.len() as u32;
        a.vertices.extend_from_slice(&b.vertices);
        a.triangles
            .extend(b.triangles.iter().map(|t| t.map(|v| v + off)));
    }

    const PARAMS: CleaningParams = CleaningParams {
        min_component_fraction: 0.05,
        min_component_area_voxels: 0.5,
        max_hole_edges: 8,
        max_hole_perimeter_voxels: 6.0,
    };

    #[test]
    fn small_fragment_is_dropped_and_large_kept() {
        let mut m = grid(10, 0.0, 0.0);
        append(&mut m, &grid(1, 20.0, 0.0));
        let (out, stats) = clean_sheet(&m, &PARAMS, 1.0, |_| true);
        assert_eq!(stats.components_before, 2);
        assert_eq!(stats.dropped_components, 1);
        assert_eq!(out.triangles.len(), 200);
        assert_eq!(out.vertices.len(), 121);
        assert_eq!(MeshTopology::of(&out).components, 1);
    }

    #[test]
    fn tiny_hole_is_filled_and_large_hole_kept() {
        let m = grid(10, 0.0, 0.0);
        // Remove the two triangles of square (4, 4): a 4-edge hole of perimeter 4.
        let mut small = m.clone();
        small.triangles.remove(2 * (4 * 10 + 4));
        small.triangles.remove(2 * (4 * 10 + 4));
        let (out, stats) = clean_sheet(&small, &PARAMS, 1.0, |_| true);
        assert_eq!(stats.holes_filled, 1);
        assert_eq!(MeshTopology::of(&out).euler_characteristic(), 1);
        // Remove a 3 × 3 block: perimeter 12 stays open (χ = 0, an annulus).
        let mut big = m.clone();
        big.triangles = m
            .triangles
            .iter()
            .enumerate()
            .filter(|(t, _)| {
                let (i, j) = ((t / 2) % 10, (t / 2) / 10);
                !((3..6).contains(&i) && (3..6).contains(&j))
            })
            .map(|(_, t)| *t)
            .collect();
        let (out, stats) = clean_sheet(&big, &PARAMS, 1.0, |_| true);
        assert_eq!(stats.holes_filled, 0);
        assert_eq!(MeshTopology::of(&out).euler_characteristic(), 0);
        // A small hole over air stays open.
        let (out, stats) = clean_sheet(&small, &PARAMS, 1.0, |_| false);
        assert_eq!(stats.holes_filled, 0);
        assert_eq!(MeshTopology::of(&out).euler_characteristic(), 0);
    }

    #[test]
    fn pinched_vertex_keeps_its_largest_fan() {
        // A 3 × 3 grid and one square below-left of it sharing only the corner (0, 0).
        let mut m = grid(3, 0.0, 0.0);
        let off = m.vertices.len() as u32;
        m.vertices.extend_from_slice(&[
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(0.0, -1.0, 0.0),
            DVec3::new(-1.0, 0.0, 0.0),
        ]);
        m.triangles.push([off, off + 1, 0]);
        m.triangles.push([off, 0, off + 2]);
        assert_eq!(MeshTopology::of(&m).non_manifold_vertices, 1);
        let (out, stats) = clean_sheet(&m, &PARAMS, 1.0, |_| true);
        assert_eq!(stats.pinch_triangles, 2);
        let topo = MeshTopology::of(&out);
        assert_eq!((topo.non_manifold_vertices, topo.components), (0, 1));
        assert_eq!(out.triangles.len(), 18);
    }

    #[test]
    fn coincident_vertices_are_welded() {
        let mut m = grid(2, 0.0, 0.0);
        let n = m.vertices.len() as u32;
        // A second copy of vertex 4 (the centre) used by one triangle.
        m.vertices.push(m.vertices[4]);
        for t in &mut m.triangles {
            if t.contains(&4) && t.contains(&0) {
                for v in t.iter_mut() {
                    if *v == 4 {
                        *v = n;
                    }
                }
            }
        }
        let (out, stats) = clean_sheet(&m, &PARAMS, 1.0, |_| true);
        assert!(stats.welded_vertices == 1);
        assert_eq!(out.vertices.len(), 9);
        assert_eq!(MeshTopology::of(&out).euler_characteristic(), 1);
    }
}
