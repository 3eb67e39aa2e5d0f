//! Trimming the sheet back from the rounded rims of the part (future work in thesis §6.4).
//!
//! The method is described on [`trim_rims()`].

use std::collections::BinaryHeap;

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{TriMesh, triangle_area};

use super::collapse::collapse_in_order;
use super::part_surface::PartSurface;
use super::sorted_edges;
use super::{MinFirst, retain_triangles};
use crate::slice_stretch::SliceStretch;

/// Parameters of [`trim_rims`]; lengths in voxels.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct RimTrimParams {
    /// `κ`: a vertex is in the rim when the surface lies closer than `κ·h` along the sheet.
    pub factor: f64,
    /// Step of the march towards the part's faces.
    pub step_voxels: f64,
    /// Pieces of the sheet of at least this area (voxel²) that trimming would cut off stay
    /// joined to the rest ([`trim_rims`]); `None` lets trimming cut off pieces of any size.
    pub keep_pieces_voxels: Option<f64>,
    /// `γ`: on a grid resampled from thick slices, the test measures `h` and the distances
    /// along the sheet with the slice axis compressed by `s^γ`, where `s` is the factor of
    /// [`SliceStretch`](crate::SliceStretch) (see [`trim_rims`]); 0 measures them in the
    /// grid's coordinates.
    pub slice_exponent: f64,
}

impl Default for RimTrimParams {
    fn default() -> RimTrimParams {
        RimTrimParams {
            factor: 0.9,
            step_voxels: 0.25,
            keep_pieces_voxels: Some(16.0),
            slice_exponent: 0.5,
        }
    }
}

/// In-plane directions tested around each vertex.
pub(crate) const DIRECTIONS: usize = 12;

/// Removes the rim triangles of `mesh` (whose normals must hold the ridge directions `e`) in
/// the part `surface`; `voxel` is the length unit of `params` (world units). Returns the
/// trimmed mesh (vertices unchanged) and the number of triangles removed.
///
/// Trimming must not cut the sheet apart: where the raw sheet has a slit reaching the rim (a
/// crack along which the ridge was missed), the piece beyond it hangs on the rest by rim
/// triangles only, and removing them would leave it a fragment that cleaning drops (on the
/// generated T-junction at 10 % noise, 55 voxel² of the base, coverage 0.98 instead of 0.99).
/// So every piece of at least [`RimTrimParams::keep_pieces_voxels`] that trimming separates
/// from the largest piece of its component keeps the fewest removed triangles that connect
/// it back across edges (a breadth-first path through the removed triangles).
///
/// A plate of thickness `t` ends in a rounded rim that sticks out `t/2` beyond the true
/// sheet's boundary, and the intensity ridge runs on to the rim's tip: left alone, the
/// extracted sheet is `t/2` too wide all around (on the phantoms: 5–25 % of the output lies
/// farther than one voxel from the true sheet, all of it at the rims).
///
/// The medial-axis property tells the rim apart, locally. At a sheet point `p` with across
/// direction `e`, let `h(p)` be the half-thickness along `e` (the distance from `p` to the
/// object surface `f = T` along `±e`, averaged over both sides). Inside the true sheet the
/// object extends farther than `h` in every direction along the sheet. In the rim, at
/// distance `δ` beyond the true boundary, the surface lies `t/2 − δ` away along the sheet
/// (outwards) while `h = √(t²/4 − δ²)`. So a vertex is in the rim when, in one of
/// `DIRECTIONS` directions perpendicular to `e`, the surface is closer than `κ·h`
/// (`κ` = [`RimTrimParams::factor`]; with `κ = 0.9` this trims what lies more than about
/// `0.05 t` beyond the true boundary), and triangles with two rim corners are removed. At a
/// T-junction the other sheet's material continues along the sheet, so nothing is trimmed
/// there. Only vertices within the object's thickness of the sheet's boundary (geodesic
/// distance) are tested.
///
/// The test asks the cover's function, which passes over holes a few voxels wide, and near
/// them it also fires inside the sheet: over a hole the sheet spans, around it, and across a
/// strip of plate two voxels wide between two such holes or between a hole and the plate's
/// edge. Removing every rim triangle there opens the holes, but joins them to each other
/// and to the rim (on the small perforations at 10 % noise, 8 of 16 runs of seeds 1–8 lost a
/// hole that way or kept one too many). So where the voxels are at hand
/// (`little_material`: which vertices' columns across the sheet hold little material, as the
/// perforation cut reads them), the rim triangles go only as far as elementary collapses from
/// the free edges reach, outermost first (`super::collapse`: the sheet keeps its
/// components, holes and handles), and beyond that only where a corner stands over little
/// material; the perforation cut opens the holes the voxels show. Without them (`None`: a
/// point set, or a grid resampled from thick slices, whose voxels between slices are
/// interpolated) every rim triangle goes.
///
/// On thick slices the part reads thicker across them than it is (the slices' box profile
/// widens it at the surface level), so an `h` taken as measured would trim inside the true
/// boundary. With `stretch` ([`RimTrimParams::slice_exponent`]), `h` and the distances along
/// the sheet are measured in coordinates where the slice axis is compressed by its factor.
pub fn trim_rims(
    mesh: &TriMesh,
    surface: &PartSurface<'_>,
    params: &RimTrimParams,
    voxel: f64,
    little_material: Option<&[bool]>,
    stretch: Option<&SliceStretch>,
) -> (TriMesh, usize) {
    let Some(normals) = &mesh.normals else {
        return (mesh.clone(), 0);
    };
    let step = params.step_voxels * voxel;
    let distance = distance_to_boundary(mesh, 2.0 * surface.max_half_thickness);
    let in_rim: Vec<bool> = (0..mesh.vertices.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|v| {
            distance[v].is_finite()
                && is_rim(
                    surface,
                    mesh.vertices[v],
                    normals[v],
                    params.factor,
                    step,
                    stretch,
                )
        })
        .collect();
    let mut keep = kept_triangles(mesh, &in_rim, &distance, little_material);
    if let Some(area) = params.keep_pieces_voxels {
        reconnect_split_pieces(mesh, &mut keep, area * voxel * voxel);
    }
    let mut out = mesh.clone();
    retain_triangles(&mut out.triangles, |t| keep[t]);
    let removed = mesh.triangles.len() - out.triangles.len();
    (out, removed)
}

/// Which triangles of `mesh` the trimming keeps, given which vertices are in the rim and
/// their distance to the boundary ([`trim_rims`]): those with fewer than two rim corners;
/// with `little_material`, also the rim triangles that elementary collapses from the free
/// edges, outermost first, do not reach, unless a corner is over little material.
fn kept_triangles(
    mesh: &TriMesh,
    in_rim: &[bool],
    distance: &[f64],
    little_material: Option<&[bool]>,
) -> Vec<bool> {
    let rim_triangle: Vec<bool> = mesh
        .triangles
        .iter()
        .map(|t| t.iter().filter(|&&v| in_rim[v as usize]).count() >= 2)
        .collect();
    let Some(little) = little_material else {
        return rim_triangle.iter().map(|r| !r).collect();
    };
    let depth: Vec<f64> = mesh
        .triangles
        .iter()
        .map(|t| {
            t.iter()
                .map(|&v| distance[v as usize])
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let collapsed = collapse_in_order(mesh, &rim_triangle, &depth);
    mesh.triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let over_little = rim_triangle[t] && tri.iter().any(|&v| little[v as usize]);
            !collapsed[t] && !over_little
        })
        .collect()
}

/// Restores, for every edge-connected piece of the kept triangles of at least `min_area` that
/// is not the largest kept piece of its component of `mesh`, the shortest chain of removed
/// triangles (across shared edges) joining it to a larger piece (see [`trim_rims`]). Pieces
/// are handled largest first; a restored chain merges the pieces, so later ones may join
/// through it.
pub(crate) fn reconnect_split_pieces(mesh: &TriMesh, keep: &mut [bool], min_area: f64) {
    let nt = mesh.triangles.len();
    if nt == 0 || !min_area.is_finite() {
        return;
    }
    // Triangles sharing each edge.
    let mut edges: Vec<((u32, u32), u32)> = Vec::with_capacity(3 * nt);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            edges.push(((a.min(b), a.max(b)), t as u32));
        }
    }
    edges.sort_unstable();
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); nt];
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j].0 == edges[i].0 {
            j += 1;
        }
        for a in i..j {
            for b in i..j {
                if a != b {
                    neighbours[edges[a].1 as usize].push(edges[b].1);
                }
            }
        }
        i = j;
    }
    let area = |t: usize| triangle_area(mesh, &mesh.triangles[t]);
    // Components of the whole mesh, and pieces of the kept triangles, by flood fill.
    let label = |mask: &dyn Fn(usize) -> bool| {
        let mut id = vec![u32::MAX; nt];
        let mut count = 0u32;
        for s in 0..nt {
            if id[s] != u32::MAX || !mask(s) {
                continue;
            }
            id[s] = count;
            let mut stack = vec![s as u32];
            while let Some(t) = stack.pop() {
                for &u in &neighbours[t as usize] {
                    if id[u as usize] == u32::MAX && mask(u as usize) {
                        id[u as usize] = count;
                        stack.push(u);
                    }
                }
            }
            count += 1;
        }
        (id, count as usize)
    };
    let (component, components) = label(&|_| true);
    let kept = keep.to_vec();
    let (piece, pieces) = label(&|t| kept[t]);
    let mut piece_area = vec![0.0; pieces];
    let mut piece_component = vec![0u32; pieces];
    for t in 0..nt {
        if piece[t] != u32::MAX {
            piece_area[piece[t] as usize] += area(t);
            piece_component[piece[t] as usize] = component[t];
        }
    }
    let mut largest: Vec<Option<usize>> = vec![None; components];
    for p in 0..pieces {
        let c = piece_component[p] as usize;
        if largest[c].is_none_or(|q| piece_area[p] > piece_area[q]) {
            largest[c] = Some(p);
        }
    }
    let mut order: Vec<usize> = (0..pieces)
        .filter(|&p| piece_area[p] >= min_area && largest[piece_component[p] as usize] != Some(p))
        .collect();
    order.sort_by(|&a, &b| piece_area[b].total_cmp(&piece_area[a]).then(a.cmp(&b)));
    // Triangles already joined to the largest piece of their component (grows as chains are
    // restored).
    let mut joined: Vec<bool> = (0..nt)
        .map(|t| piece[t] != u32::MAX && largest[component[t] as usize] == Some(piece[t] as usize))
        .collect();
    for p in order {
        if joined
            .iter()
            .enumerate()
            .any(|(t, &j)| j && piece[t] == p as u32)
        {
            continue;
        }
        // Breadth-first search from the piece through removed triangles to a joined one.
        let mut parent = vec![u32::MAX; nt];
        let mut queue = std::collections::VecDeque::new();
        for t in 0..nt {
            if piece[t] == p as u32 {
                parent[t] = t as u32;
                queue.push_back(t as u32);
            }
        }
        let mut reached = None;
        'search: while let Some(t) = queue.pop_front() {
            for &u in &neighbours[t as usize] {
                if parent[u as usize] != u32::MAX {
                    continue;
                }
                parent[u as usize] = t;
                if joined[u as usize] {
                    reached = Some(u);
                    break 'search;
                }
                if !keep[u as usize] {
                    queue.push_back(u);
                }
            }
        }
        let Some(end) = reached else {
            continue;
        };
        let mut t = parent[end as usize];
        while piece[t as usize] != p as u32 {
            keep[t as usize] = true;
            joined[t as usize] = true;
            t = parent[t as usize];
        }
        for t in 0..nt {
            if piece[t] == p as u32 {
                joined[t] = true;
            }
        }
    }
}

/// True when the part's surface is closer than `factor · h(p)` along some direction
/// perpendicular to `e` (see [`trim_rims`]), marching in steps of `step` (world
/// units). With `stretch`, both lengths are measured with the slice axis compressed.
pub(crate) fn is_rim(
    surface: &PartSurface<'_>,
    p: DVec3,
    e: DVec3,
    factor: f64,
    step: f64,
    stretch: Option<&SliceStretch>,
) -> bool {
    let Some(h) = surface.half_thickness(p, e, step) else {
        return false;
    };
    let compressed = |d: DVec3| stretch.map_or(1.0, |s| s.compressed_length(d));
    let reach = factor * h * compressed(e);
    let u = e.any_orthonormal_vector();
    let v = e.cross(u);
    (0..DIRECTIONS).any(|k| {
        let angle = std::f64::consts::TAU * k as f64 / DIRECTIONS as f64;
        let dir = angle.cos() * u + angle.sin() * v;
        let reach = reach / compressed(dir);
        let mut s = step;
        while s <= reach {
            if surface.is_outside(p + s * dir) {
                return true;
            }
            s += step;
        }
        false
    })
}

/// Geodesic (shortest path over edges) distance from every vertex to the mesh boundary (the
/// vertices of edges used by one triangle), `+∞` beyond `limit` or without a boundary.
pub(crate) fn distance_to_boundary(mesh: &TriMesh, limit: f64) -> Vec<f64> {
    let n = mesh.vertices.len();
    let edges = sorted_edges(mesh);
    let mut adjacency: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut dist = vec![f64::INFINITY; n];
    let mut heap = BinaryHeap::new();
    let mut k = 0;
    while k < edges.len() {
        let mut j = k + 1;
        while j < edges.len() && edges[j] == edges[k] {
            j += 1;
        }
        let (a, b) = edges[k];
        adjacency[a as usize].push(b);
        adjacency[b as usize].push(a);
        if j - k == 1 {
            for v in [a, b] {
                if dist[v as usize] != 0.0 {
                    dist[v as usize] = 0.0;
                    heap.push(MinFirst(0.0, v));
                }
            }
        }
        k = j;
    }
    while let Some(MinFirst(d, v)) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        for &w in &adjacency[v as usize] {
            let nd = d + mesh.vertices[v as usize].distance(mesh.vertices[w as usize]);
            if nd < dist[w as usize] && nd < limit {
                dist[w as usize] = nd;
                heap.push(MinFirst(nd, w));
            }
        }
    }
    dist
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::repair::{grid, kept_triangles_of};
    use proptest::prelude::*;

    proptest! {
        /// Removing the squares of column `c` cuts a grid in two; the smaller side is joined
        /// back through exactly one removed square's worth of triangles or fewer (the
        /// shortest chain across the cut), when it is at least `min_area`; only removed
        /// triangles are restored, and the kept ones stay.
        #[test]
        fn cut_off_pieces_are_joined_back(n in 5u32..12, m in 2u32..6, c_frac in 0.2..0.8f64,
                                          min_area in 0.0..30.0f64) {
            let mesh = grid(n, m);
            let c = ((n as f64 * c_frac) as u32).clamp(1, n - 2);
            let removed: Vec<bool> = (0..mesh.triangles.len())
                .map(|t| (t as u32 / 2) % n == c)
                .collect();
            let mut keep: Vec<bool> = removed.iter().map(|r| !r).collect();
            let before = keep.clone();
            reconnect_split_pieces(&mesh, &mut keep, min_area);
            let smaller = (c.min(n - 1 - c) * m) as f64;
            let restored = keep.iter().zip(&before).filter(|(k, b)| **k && !**b).count();
            prop_assert!(keep.iter().zip(&before).all(|(k, b)| *k || !*b));
            if smaller >= min_area {
                prop_assert!((1..=2).contains(&restored), "{restored}");
                // Edge-connected now: flood fill over kept triangles reaches them all.
                let topology = sphcover_core::MeshTopology::of(&kept_triangles_of(&mesh, &keep));
                prop_assert_eq!(topology.components, 1);
            } else {
                prop_assert_eq!(restored, 0);
            }
        }
    }

    proptest! {
        /// Without the voxels every triangle with two rim corners goes. With them and no
        /// vertex over little material the trimmed grid (holes punched in it first, so that
        /// the rim may run between them) keeps its components and Euler characteristic; with
        /// some, only rim triangles go, and every rim triangle with a corner over little
        /// material goes.
        #[test]
        fn trimming_over_material_keeps_the_topology(
            n in 3u32..8, m in 3u32..8,
            holes in prop::collection::vec(any::<u16>(), 0..4),
            rim in prop::collection::vec(any::<bool>(), 81),
            little in prop::collection::vec(prop::bool::weighted(0.1), 81),
            distance in prop::collection::vec(0.0f64..5.0, 81),
        ) {
            let mut mesh = grid(n, m);
            let nt = mesh.triangles.len();
            mesh.triangles = (0..nt)
                .filter(|&t| !holes.iter().any(|&h| h as usize % nt == t))
                .map(|t| mesh.triangles[t])
                .collect();
            let nv = mesh.vertices.len();
            let rim = &rim[..nv];
            let rim_triangle: Vec<bool> = mesh
                .triangles
                .iter()
                .map(|t| t.iter().filter(|&&v| rim[v as usize]).count() >= 2)
                .collect();
            let without_voxels = kept_triangles(&mesh, rim, &distance[..nv], None);
            prop_assert!(without_voxels.iter().zip(&rim_triangle).all(|(k, r)| *k != *r));
            let kept_mesh =
                |keep: &[bool]| sphcover_core::MeshTopology::of(&kept_triangles_of(&mesh, keep));
            let before = sphcover_core::MeshTopology::of(&mesh);
            let over_material = kept_triangles(&mesh, rim, &distance[..nv], Some(&vec![false; nv]));
            let after = kept_mesh(&over_material);
            prop_assert_eq!(after.euler_characteristic(), before.euler_characteristic());
            prop_assert_eq!(after.components, before.components);
            let little = &little[..nv];
            let keep = kept_triangles(&mesh, rim, &distance[..nv], Some(little));
            for (t, tri) in mesh.triangles.iter().enumerate() {
                prop_assert!(keep[t] || rim_triangle[t]);
                if rim_triangle[t] && tri.iter().any(|&v| little[v as usize]) {
                    prop_assert!(!keep[t]);
                }
            }
        }
    }

    #[test]
    fn pieces_never_joined_by_edges_stay_apart() {
        // Two squares sharing only a corner: nothing to restore.
        let v = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::new(2.0, 2.0, 0.0),
            DVec3::new(1.0, 2.0, 0.0),
        ];
        let t = vec![[0, 1, 2], [0, 2, 3], [2, 4, 5], [2, 5, 6]];
        let mesh = TriMesh::new(v, t);
        let mut keep = vec![true; 4];
        reconnect_split_pieces(&mesh, &mut keep, 0.0);
        assert_eq!(keep, vec![true; 4]);
    }

    #[test]
    fn distance_to_boundary_of_a_strip() {
        // A 4 × 1 strip of unit squares: every vertex is on the boundary.
        let mut v = Vec::new();
        for j in 0..2 {
            for i in 0..5 {
                v.push(DVec3::new(i as f64, j as f64, 0.0));
            }
        }
        let mut t = Vec::new();
        for i in 0..4u32 {
            t.push([i, i + 1, i + 6]);
            t.push([i, i + 6, i + 5]);
        }
        let d = distance_to_boundary(&TriMesh::new(v, t), 10.0);
        assert!(d.iter().all(|&x| x == 0.0));
    }

    #[test]
    fn distance_to_boundary_of_a_fan() {
        // A hexagonal fan: the centre is one unit from the boundary ring.
        let mut v = vec![DVec3::ZERO];
        for k in 0..6 {
            let a = k as f64 * std::f64::consts::TAU / 6.0;
            v.push(DVec3::new(a.cos(), a.sin(), 0.0));
        }
        let t: Vec<[u32; 3]> = (0..6u32).map(|k| [0, 1 + k, 1 + (k + 1) % 6]).collect();
        let d = distance_to_boundary(&TriMesh::new(v, t), 10.0);
        assert!((d[0] - 1.0).abs() < 1e-12);
        assert!(d[1..].iter().all(|&x| x == 0.0));
        // Beyond the limit: infinite.
        let d = distance_to_boundary(&TriMesh::new(vec![], vec![]), 0.5);
        assert!(d.is_empty());
    }
}
