//! Trimming: dropping the triangles far from every seed (surface invented where there were no
//! samples).
//!
//! It works on the finished mesh rather than on the grid, and only when the caller asks for
//! it, so it sits after the extraction and before the fan splitting it can make necessary.

use std::borrow::Cow;

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{DisjointSets, PointIndex, TriMesh, remove_unused_vertices, triangle_area};

use super::PolygoniseParams;

/// Drops triangles whose centroid is farther than `limit` from every seed, given each
/// triangle's squared distance to the nearest (`distance2`); returns how many.
pub(super) fn trim(mesh: &mut TriMesh, distance2: &[f64], limit: f64) -> usize {
    let limit2 = limit * limit;
    let drop: Vec<bool> = distance2.iter().map(|&d2| d2 > limit2).collect();
    drop_triangles(mesh, &drop)
}

/// The points whose distance to the seeds the trimming `params` ask for reads: the
/// triangles' centroids for a trim at a distance, the vertices for [`UnseenTrim`] (which
/// cuts along the level of that distance), none without trimming.
pub(crate) fn trimming_points<'m>(
    mesh: &'m TriMesh,
    params: &PolygoniseParams,
) -> Option<Cow<'m, [DVec3]>> {
    if params.trim.is_some() {
        Some(Cow::Owned(
            mesh.triangles
                .par_iter()
                .map(|t| t.iter().map(|&v| mesh.vertices[v as usize]).sum::<DVec3>() / 3.0)
                .collect(),
        ))
    } else if params.unseen.is_some() {
        Some(Cow::Borrowed(&mesh.vertices))
    } else {
        None
    }
}

/// What [`trim_unseen`] reads of each vertex's squared distance to the nearest point of
/// `seeds`, given the level `near` it cuts along: the distance itself at the vertices with no
/// seed nearer than `near` and at their neighbours (the region test and the cut read those),
/// and 0 at the others, which the trim only compares with `near`. A vertex with a seed within
/// a hair less than `near` (the search stops at the first) is nearer than `near` whatever the
/// rounding, so it keeps, as with the exact distances, every decision and every cut's bits.
pub(crate) fn unseen_distances_squared(mesh: &TriMesh, seeds: &PointIndex, near: f64) -> Vec<f64> {
    let inner = near * (1.0 - 1e-9);
    let seen: Vec<bool> = mesh
        .vertices
        .par_iter()
        .map(|&v| seeds.any_within(v, inner))
        .collect();
    let mut read: Vec<bool> = seen.iter().map(|&s| !s).collect();
    for t in &mesh.triangles {
        if t.iter().any(|&v| !seen[v as usize]) {
            for &v in t {
                read[v as usize] = true;
            }
        }
    }
    let wanted: Vec<usize> = (0..read.len()).filter(|&v| read[v]).collect();
    let points: Vec<DVec3> = wanted.iter().map(|&v| mesh.vertices[v]).collect();
    let mut distance2 = vec![0.0; read.len()];
    for (&v, d2) in wanted.iter().zip(distances_squared(&points, seeds)) {
        distance2[v] = d2;
    }
    distance2
}

/// The squared distance from each of `points` to the nearest point of `seeds` (an index).
pub(crate) fn distances_squared(points: &[DVec3], seeds: &PointIndex) -> Vec<f64> {
    // Consecutive points (mesh vertices or triangle centres) mostly lie close together, so
    // the previous point's nearest seed bounds each search from the start.
    points
        .par_iter()
        .map_init(
            || None,
            |hint, &p| match seeds.nearest_distance2(p, *hint) {
                Some((d2, slot)) => {
                    *hint = Some(slot);
                    d2
                }
                None => f64::INFINITY,
            },
        )
        .collect()
}

/// Removes the triangles marked in `drop` and the vertices left unused; returns how many
/// triangles went.
fn drop_triangles(mesh: &mut TriMesh, drop: &[bool]) -> usize {
    let before = mesh.triangles.len();
    let mut d = drop.iter();
    mesh.triangles.retain(|_| !*d.next().unwrap_or(&false));
    remove_unused_vertices(mesh);
    before - mesh.triangles.len()
}

/// Which surface far from the seeds is left out by default: the parts the scanner never saw,
/// while holes in a closed object are closed.
///
/// The vertices farther than `near` from every seed are grouped into regions (connected
/// through edges). A region whose every vertex lies within `reach` of a seed is a hole the
/// samples surround and is kept; a region that reaches farther is the unseen side of an open
/// scan (the back of a single view, the gap between two scans) and is cut away along the
/// line where the distance to the seeds is `near`, interpolated along the edges, so the
/// open boundary follows the samples' edge instead of the mesh's cells.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnseenTrim {
    /// Distance from every seed beyond which surface is invented.
    pub near: f64,
    /// Farthest a kept region may reach from every seed.
    pub reach: f64,
}

/// What [`trim_unseen`] removed: the triangles removed or cut, and the share of the area.
pub(super) struct UnseenRemoval {
    pub triangles: usize,
    pub area_fraction: f64,
}

/// Cuts away the regions of surface that reach farther than `unseen.reach` from every seed
/// (see [`UnseenTrim`]), given each vertex's squared distance to the nearest (`distance2`).
pub(super) fn trim_unseen(
    mesh: &mut TriMesh,
    distance2: &[f64],
    unseen: &UnseenTrim,
) -> UnseenRemoval {
    let distance: Vec<f64> = distance2.iter().map(|d2| d2.sqrt()).collect();
    let cut = unseen_vertices(mesh, &distance, unseen);
    if !cut.contains(&true) {
        return UnseenRemoval {
            triangles: 0,
            area_fraction: 0.0,
        };
    }
    let area_before: f64 = mesh.triangles.iter().map(|t| triangle_area(mesh, t)).sum();
    let triangles = clip_at_distance(mesh, &distance, &cut, unseen.near);
    remove_unused_vertices(mesh);
    let area_after: f64 = mesh.triangles.iter().map(|t| triangle_area(mesh, t)).sum();
    UnseenRemoval {
        triangles,
        area_fraction: (1.0 - area_after / area_before.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0),
    }
}

/// Per vertex: farther than `unseen.near` from every seed, in a region that reaches farther
/// than `unseen.reach`.
fn unseen_vertices(mesh: &TriMesh, distance: &[f64], unseen: &UnseenTrim) -> Vec<bool> {
    let far = |v: u32| distance[v as usize] > unseen.near;
    let mut regions = DisjointSets::new(mesh.vertices.len());
    for t in &mesh.triangles {
        for (u, v) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if far(u) && far(v) {
                regions.union(u, v);
            }
        }
    }
    let mut reach = vec![0.0f64; mesh.vertices.len()];
    for v in 0..mesh.vertices.len() as u32 {
        if far(v) {
            let root = regions.find(v) as usize;
            reach[root] = reach[root].max(distance[v as usize]);
        }
    }
    (0..mesh.vertices.len() as u32)
        .map(|v| far(v) && reach[regions.find(v) as usize] > unseen.reach)
        .collect()
}

/// Replaces every triangle touching a `cut` vertex by its part where the distance,
/// interpolated linearly along its edges, is at most `near`. A vertex next to a cut one is
/// not far (or it would be in the cut one's region), so the level is crossed once on each
/// such edge; the crossing is one new vertex shared by the triangles on both sides of the
/// edge. Crossings within a thousandth of an edge from its kept end are that end, so the cut
/// leaves no slivers. Returns how many triangles were removed or cut.
fn clip_at_distance(mesh: &mut TriMesh, distance: &[f64], cut: &[bool], near: f64) -> usize {
    let mut crossings: std::collections::HashMap<[u32; 2], u32> = Default::default();
    let mut crossing = |mesh: &mut TriMesh, kept: u32, gone: u32| -> u32 {
        let (dk, dg) = (distance[kept as usize], distance[gone as usize]);
        let t = ((near - dk) / (dg - dk)).clamp(0.0, 1.0);
        if t < 1e-3 {
            return kept;
        }
        *crossings.entry([kept, gone]).or_insert_with(|| {
            interpolate_vertex(mesh, kept as usize, gone as usize, t);
            mesh.vertices.len() as u32 - 1
        })
    };
    let triangles = std::mem::take(&mut mesh.triangles);
    let mut clipped = Vec::with_capacity(triangles.len());
    let mut touched = 0;
    for t in triangles {
        let gone = t.map(|v| cut[v as usize]);
        let count = gone.iter().filter(|&&g| g).count();
        touched += usize::from(count > 0);
        match count {
            0 => clipped.push(t),
            3 => {}
            count => {
                // Rotate so that the lone vertex (the cut one, or the kept one) comes first.
                let lone = (0..3).find(|&i| gone[i] == (count == 1)).unwrap_or(0);
                let [a, b, c] = [t[lone], t[(lone + 1) % 3], t[(lone + 2) % 3]];
                if count == 1 {
                    // `a` is cut: the kept quad b, c, (c→a), (a→b).
                    let ca = crossing(mesh, c, a);
                    let ab = crossing(mesh, b, a);
                    clipped.push([b, c, ca]);
                    clipped.push([b, ca, ab]);
                } else {
                    // Only `a` is kept: the triangle a, (a→b), (a→c).
                    let ab = crossing(mesh, a, b);
                    let ac = crossing(mesh, a, c);
                    clipped.push([a, ab, ac]);
                }
            }
        }
    }
    clipped.retain(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0]);
    mesh.triangles = clipped;
    touched
}

/// Appends the vertex at `t` along the edge from `a` to `b`, its attributes interpolated
/// (colours from the nearer end).
fn interpolate_vertex(mesh: &mut TriMesh, a: usize, b: usize, t: f64) {
    let n = mesh.vertices.len();
    mesh.vertices
        .push(mesh.vertices[a].lerp(mesh.vertices[b], t));
    if let Some(normals) = mesh.normals.as_mut().filter(|x| x.len() == n) {
        let normal = normals[a].lerp(normals[b], t);
        normals.push(normal.try_normalize().unwrap_or(normals[a]));
    }
    if let Some(values) = mesh.values.as_mut().filter(|x| x.len() == n) {
        values.push(values[a] + t * (values[b] - values[a]));
    }
    if let Some(colors) = mesh.colors.as_mut().filter(|x| x.len() == n) {
        colors.push(colors[if t < 0.5 { a } else { b }]);
    }
}

#[cfg(test)]
mod tests {
    use super::{distances_squared, triangle_area, trim_unseen, unseen_distances_squared};
    use crate::polygonise::tests::{cover_of, params};
    use crate::polygonise::{PolygoniseParams, UnseenTrim, polygonise};
    use glam::DVec3;
    use proptest::prelude::*;
    use sphcover_core::MeshTopology;
    use sphcover_core::TriMesh;
    use sphcover_core::{PointIndex, PuEvaluator};
    use sphcover_evaluation::sphere;

    /// A flat `n` × `n` grid of unit squares, two triangles each, in the plane z = 0.
    fn grid(n: u32) -> TriMesh {
        let vertices = (0..=n)
            .flat_map(|j| (0..=n).map(move |i| DVec3::new(f64::from(i), f64::from(j), 0.0)))
            .collect();
        let v = |i: u32, j: u32| j * (n + 1) + i;
        let triangles = (0..n)
            .flat_map(|j| {
                (0..n).flat_map(move |i| {
                    [
                        [v(i, j), v(i + 1, j), v(i + 1, j + 1)],
                        [v(i, j), v(i + 1, j + 1), v(i, j + 1)],
                    ]
                })
            })
            .collect();
        TriMesh::new(vertices, triangles)
    }

    #[test]
    fn unseen_surface_is_cut_along_the_level_of_the_distance() {
        // Distance grows along x; beyond 4.5 it is unseen, and the region reaches 10.
        let mut mesh = grid(10);
        mesh.values = Some(mesh.vertices.iter().map(|p| p.y).collect());
        let d2: Vec<f64> = mesh.vertices.iter().map(|p| p.x * p.x).collect();
        let unseen = UnseenTrim {
            near: 4.5,
            reach: 6.0,
        };
        let removed = trim_unseen(&mut mesh, &d2, &unseen);
        assert_eq!(removed.triangles, 120);
        assert!((removed.area_fraction - 0.55).abs() < 1e-12);
        assert!(mesh.vertices.iter().all(|p| p.x <= 4.5 + 1e-12));
        let topo = MeshTopology::of(&mesh);
        assert!(topo.is_manifold() && topo.components == 1, "{topo:?}");
        // The cut's vertices are shared: 21 on the line x = 4.5 (on the grid's edges and its
        // diagonals), and the boundary is the rectangle 4.5 × 10 (20 edges along the cut,
        // 5 + 5 + 10 along the grid's sides).
        assert_eq!(mesh.vertices.iter().filter(|p| p.x == 4.5).count(), 21);
        assert_eq!(topo.boundary_edges, 40, "{topo:?}");
        assert_eq!(topo.inconsistent_edges, 0, "{topo:?}");
        // Attributes are interpolated with the positions.
        let values = mesh.values.as_ref().unwrap();
        assert!(mesh.vertices.iter().zip(values).all(|(p, &v)| v == p.y));
        // A region that stays within `reach` is kept whole.
        let mut kept = grid(10);
        let near_only = UnseenTrim {
            near: 4.5,
            reach: 10.0,
        };
        assert_eq!(trim_unseen(&mut kept, &d2, &near_only).triangles, 0);
        assert_eq!(kept, grid(10));
    }

    proptest! {
        /// The distances read lazily cut exactly as the exact distances do (the same mesh,
        /// bit for bit), whatever the seeds and the level.
        #[test]
        fn the_unseen_trim_reads_the_distances_it_needs(
            seeds in proptest::collection::vec((-1.0f64..9.0, -1.0f64..9.0, -1.0f64..1.0), 1..30),
            near in 0.3f64..3.0,
            reach in 0.0f64..4.0,
        ) {
            let mesh = grid(8);
            let seeds: Vec<DVec3> = seeds.iter().map(|&(x, y, z)| DVec3::new(x, y, z)).collect();
            let index = PointIndex::new(&seeds).unwrap();
            let unseen = UnseenTrim { near, reach };
            let exact = distances_squared(&mesh.vertices, &index);
            let lazy = unseen_distances_squared(&mesh, &index, near);
            let (mut a, mut b) = (mesh.clone(), mesh.clone());
            let removed_a = trim_unseen(&mut a, &exact, &unseen);
            let removed_b = trim_unseen(&mut b, &lazy, &unseen);
            prop_assert_eq!(a, b);
            prop_assert_eq!(removed_a.triangles, removed_b.triangles);
            prop_assert_eq!(removed_a.area_fraction.to_bits(), removed_b.area_fraction.to_bits());
        }

        #[test]
        fn cutting_keeps_what_is_seen_and_shares_the_cut(
            distances in proptest::collection::vec(0.0f64..3.0, 49),
            near in 0.5f64..2.5,
        ) {
            let mut mesh = grid(6);
            let area = 36.0;
            let d2: Vec<f64> = distances.iter().map(|d| d * d).collect();
            let unseen = UnseenTrim { near, reach: near };
            let cut: Vec<bool> = distances.iter().map(|&d| d > near).collect();
            let before = mesh.clone();
            let removed = trim_unseen(&mut mesh, &d2, &unseen);
            // Triangles within `near` stay whole, and the cut ones are gone.
            for t in &before.triangles {
                let gone = t.iter().filter(|&&v| cut[v as usize]).count();
                prop_assert_eq!(gone == 0, mesh.triangles.iter().any(|u| u
                    .map(|v| mesh.vertices[v as usize])
                    == t.map(|v| before.vertices[v as usize])));
            }
            // No vertex is doubled, and every edge still has at most two triangles.
            let mut positions: Vec<[u64; 3]> =
                mesh.vertices.iter().map(|p| p.to_array().map(f64::to_bits)).collect();
            positions.sort_unstable();
            prop_assert!(positions.windows(2).all(|w| w[0] != w[1]));
            let topo = MeshTopology::of(&mesh);
            prop_assert_eq!(topo.non_manifold_edges, 0);
            let kept: f64 = mesh.triangles.iter().map(|t| triangle_area(&mesh, t)).sum();
            prop_assert!(kept <= area + 1e-9);
            prop_assert!((removed.area_fraction - (1.0 - kept / area)).abs() < 1e-9);
            prop_assert_eq!(removed.triangles == 0, !cut.contains(&true));
        }
    }

    #[test]
    fn trimming_a_sphere_seeded_on_one_half_opens_it() {
        let cloud = sphere(DVec3::ZERO, 0.4, 4000);
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let upper: Vec<DVec3> = cloud
            .positions
            .iter()
            .copied()
            .filter(|p| p.z > 0.0)
            .collect();
        let p = PolygoniseParams {
            trim: Some(0.03),
            ..params(6)
        };
        let (mesh, stats) = polygonise(&eval, &upper, &p).unwrap();
        assert!(stats.trimmed_triangles > 0);
        assert!(mesh.vertices.iter().all(|v| v.z > -0.06));
        let topo = MeshTopology::of(&mesh);
        assert!(topo.is_manifold() && topo.boundary_edges > 0, "{topo:?}");
        assert_eq!(topo.components, 1);
    }

    #[test]
    fn unseen_sides_are_left_out_and_holes_closed() {
        // A sphere of radius 0.4 whose cover knows the whole surface, seeded (a) on one half,
        // as a single view would see it, and (b) everywhere but a cap of radius 0.05 (a hole):
        // the far region of (a) reaches 0.4 from every seed, that of (b) 0.05.
        let cloud = sphere(DVec3::ZERO, 0.4, 4000);
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let seeds = |keep: &dyn Fn(DVec3) -> bool| -> Vec<DVec3> {
            cloud
                .positions
                .iter()
                .copied()
                .filter(|&p| keep(p))
                .collect()
        };
        let p = PolygoniseParams {
            unseen: Some(UnseenTrim {
                near: 0.03,
                reach: 0.1,
            }),
            ..params(6)
        };
        let (half, stats) = polygonise(&eval, &seeds(&|p| p.z > 0.0), &p).unwrap();
        assert!(stats.trimmed_triangles > 0);
        assert!(
            (0.3..0.5).contains(&stats.unseen_area_fraction),
            "{}",
            stats.unseen_area_fraction
        );
        assert!(half.vertices.iter().all(|v| v.z > -0.06));
        let topo = MeshTopology::of(&half);
        assert!(topo.is_manifold() && topo.boundary_edges > 0, "{topo:?}");

        let cap = DVec3::new(0.0, 0.0, 0.4);
        let (holed, stats) = polygonise(&eval, &seeds(&|p| (p - cap).length() > 0.05), &p).unwrap();
        assert_eq!(stats.trimmed_triangles, 0);
        assert_eq!(stats.unseen_area_fraction, 0.0);
        let topo = MeshTopology::of(&holed);
        assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
        // Trimming everywhere opens the hole.
        let everywhere = PolygoniseParams {
            trim: Some(0.03),
            ..p.clone()
        };
        let (opened, _) =
            polygonise(&eval, &seeds(&|p| (p - cap).length() > 0.05), &everywhere).unwrap();
        assert!(MeshTopology::of(&opened).boundary_edges > 0);
    }
}
