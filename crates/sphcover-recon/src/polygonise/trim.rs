//! Trimming: dropping the triangles far from every seed (surface invented where there were no
//! samples).
//!
//! It works on the finished mesh rather than on the grid, and only when the caller asks for
//! it, so it sits after the extraction and before the fan splitting it can make necessary.

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{PointIndex, TriMesh, remove_unused_vertices};

use super::PolygoniseError;

/// Drops triangles whose centroid is farther than `limit` from every seed; returns how many.
pub(super) fn trim(
    mesh: &mut TriMesh,
    seeds: &[DVec3],
    limit: f64,
) -> Result<usize, PolygoniseError> {
    let index = PointIndex::new(seeds)?;
    let keep: Vec<bool> = mesh
        .triangles
        .par_iter()
        .map_init(Vec::new, |found, t| {
            let centroid = t.iter().map(|&v| mesh.vertices[v as usize]).sum::<DVec3>() / 3.0;
            index.nearest_k_with_distances(centroid, 1, found);
            found.first().is_some_and(|&(d2, _)| d2 <= limit * limit)
        })
        .collect();
    let before = mesh.triangles.len();
    let mut k = keep.iter();
    mesh.triangles.retain(|_| *k.next().unwrap_or(&false));
    remove_unused_vertices(mesh);
    Ok(before - mesh.triangles.len())
}

#[cfg(test)]
mod tests {
    use crate::polygonise::tests::{cover_of, params};
    use crate::polygonise::{PolygoniseParams, polygonise};
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
}
