//! Trimming the sheet back from the rounded rims of the part (future work in thesis §6.4).
//!
//! A plate of thickness `t` ends in a rounded rim that sticks out `t/2` beyond the true
//! sheet's boundary, and the intensity ridge runs on to the rim's tip: left alone, the
//! extracted sheet is `t/2` too wide all around (on the phantoms: 5–25 % of the output lies
//! farther than one voxel from the true sheet, all of it at the rims).
//!
//! The medial-axis property tells the rim apart, locally. At a sheet point `p` with across
//! direction `e`, let `h(p)` be the half-thickness along `e` (the distance from `p` to the
//! object surface `f = T` along `±e`, averaged over both sides). Inside the true sheet the
//! object extends farther than `h` in every direction along the sheet. In the rim, at
//! distance `δ` beyond the true boundary, the surface lies `t/2 − δ` away along the sheet
//! (outwards) while `h = √(t²/4 − δ²)`. So a vertex is in the rim when, in one of
//! [`DIRECTIONS`] directions perpendicular to `e`, the surface is closer than `κ·h`
//! (`κ` = [`RimTrimParams::factor`]; with `κ = 0.9` this trims what lies more than about
//! `0.05 t` beyond the true boundary), and triangles with two rim corners are removed. At a
//! T-junction the other sheet's material continues along the sheet, so nothing is trimmed
//! there. Only vertices within the object's thickness of the sheet's boundary (geodesic
//! distance) are tested.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{PuEvaluator, TriMesh};

/// Parameters of [`trim_rims`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RimTrimParams {
    /// Level of the object surface in the evaluator's units.
    pub surface_level: f64,
    /// Step of the march along `±e` (world units).
    pub step: f64,
    /// Largest half-thickness searched (world units); also bounds the geodesic distances.
    pub max_half_thickness: f64,
    /// `κ`: a vertex is in the rim when the surface lies closer than `κ·h` along the sheet.
    pub factor: f64,
}

/// In-plane directions tested around each vertex.
pub const DIRECTIONS: usize = 12;

/// Removes the rim triangles of `mesh` (whose normals must hold the ridge directions `e`).
/// Returns the trimmed mesh (vertices unchanged) and the number of triangles removed.
pub fn trim_rims(
    mesh: &TriMesh,
    evaluator: &PuEvaluator<'_>,
    params: &RimTrimParams,
) -> (TriMesh, usize) {
    let Some(normals) = &mesh.normals else {
        return (mesh.clone(), 0);
    };
    let distance = distance_to_boundary(mesh, 2.0 * params.max_half_thickness);
    let in_rim: Vec<bool> = (0..mesh.vertices.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|v| distance[v].is_finite() && is_rim(evaluator, mesh.vertices[v], normals[v], params))
        .collect();
    let mut out = mesh.clone();
    out.triangles
        .retain(|t| t.iter().filter(|&&v| in_rim[v as usize]).count() < 2);
    let removed = mesh.triangles.len() - out.triangles.len();
    (out, removed)
}

/// True when the object surface is closer than `factor · h(p)` along some direction
/// perpendicular to `e` (see the module documentation).
pub fn is_rim(evaluator: &PuEvaluator<'_>, p: DVec3, e: DVec3, params: &RimTrimParams) -> bool {
    let Some(h) = half_thickness(evaluator, p, e, params) else {
        return false;
    };
    let reach = params.factor * h;
    let u = e.any_orthonormal_vector();
    let v = e.cross(u);
    (0..DIRECTIONS).any(|k| {
        let angle = std::f64::consts::TAU * k as f64 / DIRECTIONS as f64;
        let dir = angle.cos() * u + angle.sin() * v;
        let mut s = params.step;
        while s <= reach {
            if evaluator
                .value(p + s * dir)
                .is_none_or(|f| f < params.surface_level)
            {
                return true;
            }
            s += params.step;
        }
        false
    })
}

/// The half-thickness of the object at `p` along `±e`: the mean distance to the first
/// point where `f` falls below the surface level on each side (linear interpolation between
/// march steps). `None` when `f` is undefined at `p` or never falls below the level.
pub fn half_thickness(
    evaluator: &PuEvaluator<'_>,
    p: DVec3,
    e: DVec3,
    params: &RimTrimParams,
) -> Option<f64> {
    let a = surface_distance(evaluator, p, e, params)?;
    let b = surface_distance(evaluator, p, -e, params)?;
    Some(0.5 * (a + b))
}

/// The distance from `p` along the unit direction `d` to the first point where `f` falls
/// below the surface level (linear interpolation between march steps), or `None` when `f`
/// is undefined at `p` or does not fall below the level within the largest half-thickness.
pub fn surface_distance(
    evaluator: &PuEvaluator<'_>,
    p: DVec3,
    d: DVec3,
    params: &RimTrimParams,
) -> Option<f64> {
    let level = params.surface_level;
    let mut prev = (0.0, evaluator.value(p)?);
    let mut s = params.step;
    while s <= params.max_half_thickness + params.step {
        let v = evaluator.value(p + s * d).unwrap_or(f64::NEG_INFINITY);
        if v < level {
            let denom = prev.1 - v;
            let frac = if denom.is_finite() && denom > 0.0 {
                (prev.1 - level) / denom
            } else {
                0.5
            };
            return Some(prev.0 + frac.clamp(0.0, 1.0) * (s - prev.0));
        }
        prev = (s, v);
        s += params.step;
    }
    None
}

/// Geodesic (shortest path over edges) distance from every vertex to the mesh boundary (the
/// vertices of edges used by one triangle), `+∞` beyond `limit` or without a boundary.
pub fn distance_to_boundary(mesh: &TriMesh, limit: f64) -> Vec<f64> {
    let n = mesh.vertices.len();
    let mut edges: Vec<(u32, u32)> = mesh
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
        .collect();
    edges.sort_unstable();
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
                    heap.push(State { d: 0.0, v });
                }
            }
        }
        k = j;
    }
    while let Some(State { d, v }) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        for &w in &adjacency[v as usize] {
            let nd = d + mesh.vertices[v as usize].distance(mesh.vertices[w as usize]);
            if nd < dist[w as usize] && nd < limit {
                dist[w as usize] = nd;
                heap.push(State { d: nd, v: w });
            }
        }
    }
    dist
}

#[derive(PartialEq)]
struct State {
    d: f64,
    v: u32,
}

impl Eq for State {}

impl PartialOrd for State {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for State {
    /// Reversed, for a min-heap; ties by vertex.
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .d
            .total_cmp(&self.d)
            .then_with(|| other.v.cmp(&self.v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
