//! Trimming: dropping the triangles far from every seed (surface invented where there were no
//! samples).
//!
//! It works on the finished mesh rather than on the grid, and only when the caller asks for
//! it, so it sits after the extraction and before the fan splitting it can make necessary.

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{DisjointSets, PointIndex, TriMesh, remove_unused_vertices, triangle_area};

use super::PolygoniseError;

/// Drops triangles whose centroid is farther than `limit` from every seed, given each
/// triangle's squared distance to the nearest (`distance2`); returns how many.
pub(super) fn trim(mesh: &mut TriMesh, distance2: &[f64], limit: f64) -> usize {
    let limit2 = limit * limit;
    let drop: Vec<bool> = distance2.iter().map(|&d2| d2 > limit2).collect();
    drop_triangles(mesh, &drop)
}

/// The squared distance from each triangle's centroid to the nearest seed.
pub(crate) fn centroid_distances_squared(
    mesh: &TriMesh,
    seeds: &[DVec3],
) -> Result<Vec<f64>, PolygoniseError> {
    let index = PointIndex::new(seeds)?;
    Ok(mesh
        .triangles
        .par_iter()
        .map_init(Vec::new, |found, t| {
            let centroid = t.iter().map(|&v| mesh.vertices[v as usize]).sum::<DVec3>() / 3.0;
            index.nearest_k_with_distances(centroid, 1, found);
            found.first().map_or(f64::INFINITY, |&(d2, _)| d2)
        })
        .collect())
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
/// The triangles farther than `near` from every seed are grouped into regions (connected
/// through shared edges). A region whose every triangle lies within `reach` of a seed is a
/// hole the samples surround and is kept; a region that reaches farther is the unseen side
/// of an open scan (the back of a single view, the gap between two scans) and is dropped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnseenTrim {
    /// Distance from every seed beyond which a triangle is invented surface.
    pub near: f64,
    /// Farthest a kept region may reach from every seed.
    pub reach: f64,
}

/// What [`trim_unseen`] removed.
pub(super) struct UnseenRemoval {
    pub triangles: usize,
    pub area_fraction: f64,
}

/// Drops the regions of surface that reach farther than `unseen.reach` from every seed (see
/// [`UnseenTrim`]), given each triangle's squared distance to the nearest (`distance2`).
pub(super) fn trim_unseen(
    mesh: &mut TriMesh,
    distance2: &[f64],
    unseen: &UnseenTrim,
) -> UnseenRemoval {
    let near2 = unseen.near * unseen.near;
    let far: Vec<u32> = (0..distance2.len() as u32)
        .filter(|&t| distance2[t as usize] > near2)
        .collect();
    let none = UnseenRemoval {
        triangles: 0,
        area_fraction: 0.0,
    };
    if far.is_empty() {
        return none;
    }
    // Far triangles sharing an edge are one region.
    let mut edges: Vec<([u32; 2], u32)> = far
        .iter()
        .enumerate()
        .flat_map(|(i, &t)| {
            let [a, b, c] = mesh.triangles[t as usize];
            [[a, b], [b, c], [c, a]].map(|[u, v]| ([u.min(v), u.max(v)], i as u32))
        })
        .collect();
    edges.par_sort_unstable();
    let mut regions = DisjointSets::new(far.len());
    for pair in edges.windows(2) {
        if pair[0].0 == pair[1].0 {
            regions.union(pair[0].1, pair[1].1);
        }
    }
    let mut reach2 = vec![0.0f64; far.len()];
    for (i, &t) in far.iter().enumerate() {
        let root = regions.find(i as u32) as usize;
        reach2[root] = reach2[root].max(distance2[t as usize]);
    }
    let mut drop = vec![false; mesh.triangles.len()];
    for (i, &t) in far.iter().enumerate() {
        let root = regions.find(i as u32) as usize;
        drop[t as usize] = reach2[root] > unseen.reach * unseen.reach;
    }
    let removed = drop.iter().filter(|&&d| d).count();
    if removed == 0 {
        return none;
    }
    let area = |keep: bool| -> f64 {
        mesh.triangles
            .iter()
            .zip(&drop)
            .filter(|(_, d)| **d != keep)
            .map(|(t, _)| triangle_area(mesh, t))
            .sum()
    };
    let (dropped_area, kept_area) = (area(false), area(true));
    drop_triangles(mesh, &drop);
    UnseenRemoval {
        triangles: removed,
        area_fraction: dropped_area / (dropped_area + kept_area).max(f64::MIN_POSITIVE),
    }
}

#[cfg(test)]
mod tests {
    use crate::polygonise::tests::{cover_of, params};
    use crate::polygonise::{PolygoniseParams, UnseenTrim, polygonise};
    use glam::DVec3;
    use sphcover_core::MeshTopology;
    use sphcover_core::PuEvaluator;
    use sphcover_evaluation::sphere;

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
