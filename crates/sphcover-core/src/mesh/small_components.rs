//! Removal of small disconnected pieces of a reconstructed surface.
//!
//! Reconstruction from scans with outliers can leave small floating pieces (Poisson tools are
//! known for them); users ask for one clean surface. Components are those of
//! [`MeshTopology`] (triangles sharing a vertex are connected), measured by area, so the
//! rule does not depend on how finely each piece is triangulated.

use rayon::prelude::*;

use super::unused_vertices::remove_unused_vertices;
use super::{TriMesh, triangle_area};
use crate::mesh_topology::MeshTopology;

/// Why components could not be filtered. The mesh is left unchanged.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SmallComponentsError {
    /// The fraction is not in `[0, 1]`.
    #[error("min_fraction = {value} is invalid: it must lie in [0, 1]")]
    InvalidFraction {
        /// The value given.
        value: f64,
    },
    /// The topology given is not the mesh's.
    #[error("the topology describes {found} triangles, the mesh has {expected}")]
    TopologyMismatch {
        /// Triangles of the mesh.
        expected: usize,
        /// Triangles the topology describes.
        found: usize,
    },
}

/// What [`remove_small_components`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SmallComponentsStats {
    /// Components before filtering.
    pub components_before: usize,
    /// Components removed.
    pub components_removed: usize,
    /// Triangles removed (of removed components, and invalid triangles).
    pub triangles_removed: usize,
    /// Vertices no longer used, removed.
    pub vertices_removed: usize,
    /// Area of the largest component.
    pub largest_area: f64,
}

/// Removes every connected component whose area is below `min_fraction` times the area of
/// the largest one (`0` keeps everything, `1` keeps only the largest and those as large),
/// then the vertices no triangle uses. Invalid triangles (an index out of range or repeated)
/// belong to no component and are removed too.
///
/// `topo` is the mesh's topology ([`MeshTopology::of`]), which callers usually have already;
/// when nothing is removed it stays the mesh's. Deterministic: areas are summed in triangle
/// order.
pub fn remove_small_components(
    mesh: &mut TriMesh,
    topo: &MeshTopology,
    min_fraction: f64,
) -> Result<SmallComponentsStats, SmallComponentsError> {
    if !(0.0..=1.0).contains(&min_fraction) {
        return Err(SmallComponentsError::InvalidFraction {
            value: min_fraction,
        });
    }
    let areas = component_areas(mesh, topo)?;
    let largest = areas.iter().copied().fold(0.0, f64::max);
    let keep: Vec<bool> = areas.iter().map(|&a| a >= min_fraction * largest).collect();
    let (triangles_removed, vertices_removed) = remove_components(mesh, topo, &keep)?;
    Ok(SmallComponentsStats {
        components_before: topo.components,
        components_removed: keep.iter().filter(|&&k| !k).count(),
        triangles_removed,
        vertices_removed,
        largest_area: largest,
    })
}

/// Removes the triangles of every component `c` of `topo` (the mesh's topology) without
/// `keep[c]` (a component past the end of `keep` is removed), and the invalid triangles,
/// which belong to no component; then the vertices no triangle uses. Returns how many
/// triangles and vertices went. For a caller that decides by more than the area of a piece
/// (the samples it holds), with [`component_areas`].
pub fn remove_components(
    mesh: &mut TriMesh,
    topo: &MeshTopology,
    keep: &[bool],
) -> Result<(usize, usize), SmallComponentsError> {
    check_topology(mesh, topo)?;
    let before = mesh.triangles.len();
    let mut component = topo.triangle_component.iter();
    mesh.triangles.retain(|_| {
        component
            .next()
            .is_some_and(|&c| keep.get(c as usize).copied().unwrap_or(false))
    });
    let triangles_removed = before - mesh.triangles.len();
    Ok((triangles_removed, remove_unused_vertices(mesh)))
}

/// Refuses a topology that is not of `mesh` (another number of triangles).
fn check_topology(mesh: &TriMesh, topo: &MeshTopology) -> Result<(), SmallComponentsError> {
    if topo.triangle_component.len() != mesh.triangles.len() {
        return Err(SmallComponentsError::TopologyMismatch {
            expected: mesh.triangles.len(),
            found: topo.triangle_component.len(),
        });
    }
    Ok(())
}

/// The area of each component of `topo`, the mesh's topology, summed in triangle order.
pub fn component_areas(
    mesh: &TriMesh,
    topo: &MeshTopology,
) -> Result<Vec<f64>, SmallComponentsError> {
    check_topology(mesh, topo)?;
    let triangle_areas: Vec<f64> = mesh
        .triangles
        .par_iter()
        .zip(&topo.triangle_component)
        .map(|(t, &c)| {
            if c == u32::MAX {
                0.0
            } else {
                triangle_area(mesh, t)
            }
        })
        .collect();
    let mut areas = vec![0.0; topo.components];
    for (&c, &area) in topo.triangle_component.iter().zip(&triangle_areas) {
        if c != u32::MAX {
            areas[c as usize] += area;
        }
    }
    Ok(areas)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use proptest::prelude::*;

    /// [`remove_small_components`] with the mesh's own topology.
    fn drop_small(
        mesh: &mut TriMesh,
        min_fraction: f64,
    ) -> Result<SmallComponentsStats, SmallComponentsError> {
        let topo = MeshTopology::of(mesh);
        remove_small_components(mesh, &topo, min_fraction)
    }

    #[test]
    fn a_topology_of_another_mesh_is_refused() {
        let mut mesh = TriMesh::default();
        add_tetrahedron(&mut mesh, DVec3::ZERO, 1.0);
        let other = MeshTopology::of(&TriMesh::default());
        assert_eq!(
            remove_small_components(&mut mesh, &other, 0.5),
            Err(SmallComponentsError::TopologyMismatch {
                expected: 4,
                found: 0
            })
        );
    }

    /// A closed tetrahedron scaled by `s` and moved by `at`, appended to `mesh`.
    fn add_tetrahedron(mesh: &mut TriMesh, at: DVec3, s: f64) {
        let base = mesh.vertices.len() as u32;
        mesh.vertices
            .extend([DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z].map(|v| at + v * s));
        mesh.triangles.extend(
            [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]].map(|t: [u32; 3]| t.map(|v| v + base)),
        );
    }

    #[test]
    fn removes_pieces_below_the_fraction_of_the_largest() {
        let mut mesh = TriMesh::default();
        add_tetrahedron(&mut mesh, DVec3::ZERO, 1.0);
        add_tetrahedron(&mut mesh, DVec3::splat(5.0), 0.1);
        add_tetrahedron(&mut mesh, DVec3::splat(-5.0), 0.5);
        mesh.values = Some((0..12).map(f64::from).collect());
        let stats = drop_small(&mut mesh, 0.05).unwrap();
        assert_eq!(stats.components_before, 3);
        assert_eq!(stats.components_removed, 1);
        assert_eq!(stats.triangles_removed, 4);
        assert_eq!(stats.vertices_removed, 4);
        mesh.check().unwrap();
        assert_eq!(mesh.vertices.len(), 8);
        assert_eq!(mesh.values.as_ref().map(|v| v[4]), Some(8.0));
        let topo = MeshTopology::of(&mesh);
        assert_eq!((topo.components, topo.euler_characteristic()), (2, 4));
        let stats = drop_small(&mut mesh, 1.0).unwrap();
        assert_eq!(stats.components_removed, 1);
        assert_eq!(MeshTopology::of(&mesh).components, 1);
    }

    #[test]
    fn bad_fraction_and_degenerate_meshes() {
        let mut mesh = TriMesh::default();
        add_tetrahedron(&mut mesh, DVec3::ZERO, 1.0);
        let original = mesh.clone();
        for bad in [-0.1, 1.5, f64::NAN] {
            assert!(drop_small(&mut mesh, bad).is_err());
        }
        assert_eq!(mesh, original);
        let mut empty = TriMesh::default();
        assert_eq!(drop_small(&mut empty, 0.5).unwrap().components_before, 0);
        // An invalid triangle goes; the valid ones stay.
        mesh.triangles.push([0, 99, 1]);
        let stats = drop_small(&mut mesh, 0.0).unwrap();
        assert_eq!(stats.triangles_removed, 1);
        assert_eq!(mesh, original);
    }

    #[test]
    fn the_components_not_kept_go_whatever_their_area() {
        let mut mesh = TriMesh::default();
        add_tetrahedron(&mut mesh, DVec3::ZERO, 1.0);
        add_tetrahedron(&mut mesh, DVec3::splat(5.0), 0.1);
        add_tetrahedron(&mut mesh, DVec3::splat(-5.0), 0.5);
        mesh.triangles.push([0, 99, 1]);
        let topo = MeshTopology::of(&mesh);
        let areas = component_areas(&mesh, &topo).unwrap();
        assert!(areas[1] < areas[2] && areas[2] < areas[0], "{areas:?}");
        // The small second piece is kept, the largest goes, the third has no entry.
        assert_eq!(
            remove_components(&mut mesh, &topo, &[false, true]),
            Ok((9, 8))
        );
        mesh.check().unwrap();
        assert_eq!(mesh.vertices.len(), 4);
        assert!(mesh.vertices.iter().all(|v| v.x >= 5.0));
        let other = MeshTopology::of(&TriMesh::default());
        assert!(remove_components(&mut mesh, &other, &[]).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        /// Exactly the components at least `fraction` of the largest survive, untouched.
        #[test]
        fn keeps_exactly_the_large_components(
            scales in prop::collection::vec(0.01f64..2.0, 1..8),
            fraction in 0.0f64..=1.0,
        ) {
            let mut mesh = TriMesh::default();
            for (i, &s) in scales.iter().enumerate() {
                add_tetrahedron(&mut mesh, DVec3::X * (3.0 * i as f64), s);
            }
            let largest = scales.iter().copied().fold(0.0, f64::max);
            // Area scales with s²; leave a margin for rounding at the threshold.
            let ratio = |s: f64| (s / largest).powi(2);
            prop_assume!(scales.iter().all(|&s| (ratio(s) - fraction).abs() > 1e-9));
            let expected = scales.iter().filter(|&&s| ratio(s) >= fraction).count();
            let stats = drop_small(&mut mesh, fraction).unwrap();
            prop_assert_eq!(stats.components_before - stats.components_removed, expected);
            let topo = MeshTopology::of(&mesh);
            prop_assert_eq!(topo.components, expected);
            prop_assert_eq!(mesh.triangles.len(), 4 * expected);
            prop_assert!(topo.is_closed_oriented_manifold());
        }
    }
}
