//! Which components of a reconstructed surface stay: small pieces and open sheets are
//! weighed by the samples that lie nearest to them, not by their area alone.

use rayon::prelude::*;
use sphcover_core::{
    DVec3, MeshTopology, PointIndex, SmallComponentsError, TriMesh, component_areas,
    remove_components,
};

use super::{ReconError, ReconParams};

/// A component far smaller than the largest ([`ReconParams::min_component_fraction`]) stays
/// when it is open, at least this many samples vote for it ([`sample_votes`]: every 4th
/// sample counts, so about four times as many lie nearest to it) and they are at least
/// [`SHEET_DENSITY`] as dense as the object's: a piece of seen surface that the rest of the
/// surface does not reach, as a single view's occlusions leave them. On the single view of
/// the femur, dropping such pieces by their area left 1.9% of the samples farther than two
/// nearest-neighbour distances from the surface, three pieces of 134–515 samples among them;
/// keeping them, 0.9%.
const SMALL_PART_VOTES: usize = 16;

/// Drops the components far smaller than the largest (`params.min_component_fraction`),
/// except the open ones that enough samples support ([`SMALL_PART_VOTES`]); `votes` gives
/// the samples' votes for the components of the mesh it is given (asked only when a small
/// component is open). Returns how many components went, and the topology of what is left.
pub(super) fn drop_small_components(
    mesh: &mut TriMesh,
    params: &ReconParams,
    votes: impl FnOnce(&TriMesh, &MeshTopology) -> Result<Vec<usize>, ReconError>,
) -> Result<(usize, MeshTopology), ReconError> {
    let fraction = params.min_component_fraction;
    if !(0.0..=1.0).contains(&fraction) {
        return Err(SmallComponentsError::InvalidFraction { value: fraction }.into());
    }
    let topology = MeshTopology::of(mesh);
    let areas = component_areas(mesh, &topology)?;
    let largest = areas.iter().copied().fold(0.0, f64::max);
    let small = |c: usize| areas[c] < fraction * largest;
    let small_open = |c: usize| small(c) && topology.open_component[c];
    let supported = if (0..topology.components).any(small_open) {
        let votes = votes(mesh, &topology)?;
        let object = most_voted(&votes).unwrap_or(0);
        let object_density = vote_density(&votes, &areas, object);
        (0..topology.components)
            .map(|c| {
                small_open(c)
                    && votes[c] >= SMALL_PART_VOTES
                    && vote_density(&votes, &areas, c) >= SHEET_DENSITY * object_density
            })
            .collect()
    } else {
        vec![false; topology.components]
    };
    let keep: Vec<bool> = (0..topology.components)
        .map(|c| !small(c) || supported[c])
        .collect();
    let (triangles, vertices) = remove_components(mesh, &topology, &keep)?;
    let topology = if triangles > 0 || vertices > 0 {
        MeshTopology::of(mesh)
    } else {
        topology
    };
    Ok((keep.iter().filter(|&&k| !k).count(), topology))
}

/// Votes per unit area of component `c`.
fn vote_density(votes: &[usize], areas: &[f64], c: usize) -> f64 {
    votes[c] as f64 / areas[c].max(f64::MIN_POSITIVE)
}

/// An open component that fewer than this share of the samples lie nearest to, and whose
/// samples are sparser than [`SHEET_DENSITY`] of the object's, is surface made up around
/// stray samples: on a 30K-point bunny with 1% uniform outliers, a sheet of 3% of the
/// bunny's area had 0.1% of the samples nearest (a thirtieth of the bunny's density). Small
/// parts of a scene are sampled as densely as the rest and stay.
const SHEET_SUPPORT: f64 = 0.01;

/// See [`SHEET_SUPPORT`].
const SHEET_DENSITY: f64 = 0.1;

/// Removes the open components of `mesh` that few samples lie nearest to for their area
/// (see [`SHEET_SUPPORT`] and [`sample_votes`]); returns how many went.
pub(super) fn drop_unsupported_sheets(
    mesh: &mut TriMesh,
    topology: &MeshTopology,
    points: &[DVec3],
    isolated: &[bool],
) -> Result<usize, ReconError> {
    if !may_hold_sheets(topology) {
        return Ok(0);
    }
    let votes = sample_votes(mesh, topology, points, isolated)?;
    let dropped = drop_sheets_by_votes(mesh, topology, &votes)?;
    Ok(dropped.iter().filter(|&&d| d).count())
}

/// Whether `topology` has open components among others, which may be sheets around stray
/// samples (and the object among them needs the samples' votes to be told).
pub(super) fn may_hold_sheets(topology: &MeshTopology) -> bool {
    topology.components > 1 && topology.open_component.contains(&true)
}

/// [`drop_unsupported_sheets`] given the samples' votes for each component; says which
/// components went.
pub(super) fn drop_sheets_by_votes(
    mesh: &mut TriMesh,
    topology: &MeshTopology,
    votes: &[usize],
) -> Result<Vec<bool>, ReconError> {
    let areas = component_areas(mesh, topology)?;
    let density = |c: usize| vote_density(votes, &areas, c);
    let total: usize = votes.iter().sum();
    let object = most_voted(votes).unwrap_or(0);
    let drop: Vec<bool> = (0..topology.components)
        .map(|c| {
            topology.open_component[c]
                && (votes[c] as f64) < SHEET_SUPPORT * total as f64
                && density(c) < SHEET_DENSITY * density(object)
        })
        .collect();
    if drop.contains(&true) {
        let keep: Vec<bool> = drop.iter().map(|&d| !d).collect();
        remove_components(mesh, topology, &keep)?;
    }
    Ok(drop)
}

/// The component of `mesh` that the most samples lie nearest to (see [`sample_votes`]);
/// the first such on ties. `None` for a mesh without components.
pub(super) fn object_component(
    mesh: &TriMesh,
    topology: &MeshTopology,
    points: &[DVec3],
    isolated: &[bool],
) -> Result<Option<usize>, ReconError> {
    let votes = sample_votes(mesh, topology, points, isolated)?;
    Ok(most_voted(&votes))
}

/// The component the most samples voted for; the first such on ties.
pub(super) fn most_voted(votes: &[usize]) -> Option<usize> {
    (0..votes.len()).rev().max_by_key(|&c| votes[c])
}

/// For each component of `mesh`, how many samples (every 4th, isolated ones left out) have
/// their nearest vertex on it.
pub(super) fn sample_votes(
    mesh: &TriMesh,
    topology: &MeshTopology,
    points: &[DVec3],
    isolated: &[bool],
) -> Result<Vec<usize>, ReconError> {
    let (positions, components) = vertex_components(mesh, topology);
    let voters: Vec<usize> = (0..points.len())
        .step_by(4)
        .filter(|&s| !isolated.get(s).copied().unwrap_or(false))
        .collect();
    component_votes(
        &positions,
        &components,
        topology.components,
        points,
        &voters,
    )
}

/// The vertices of `mesh` that some triangle uses, and the component of each.
pub(super) fn vertex_components(mesh: &TriMesh, topology: &MeshTopology) -> (Vec<DVec3>, Vec<u32>) {
    let mut vertex_component = vec![u32::MAX; mesh.vertices.len()];
    for (t, &c) in mesh.triangles.iter().zip(&topology.triangle_component) {
        for &v in t {
            vertex_component[v as usize] = c;
        }
    }
    (0..mesh.vertices.len())
        .filter(|&v| vertex_component[v] != u32::MAX)
        .map(|v| (mesh.vertices[v], vertex_component[v]))
        .unzip()
}

/// For each of `count` components, how many of the samples `voters` (indices into `points`)
/// have their nearest vertex among `positions` on it (`components` gives each vertex's).
pub(super) fn component_votes(
    positions: &[DVec3],
    components: &[u32],
    count: usize,
    points: &[DVec3],
    voters: &[usize],
) -> Result<Vec<usize>, ReconError> {
    let empty = vec![0usize; count];
    if positions.is_empty() {
        return Ok(empty);
    }
    let index = PointIndex::new(positions)?;
    Ok(voters
        .par_iter()
        .fold(
            || (empty.clone(), Vec::new()),
            |(mut votes, mut near), &s| {
                index.nearest_k(points[s], 1, &mut near);
                if let Some(&v) = near.first() {
                    votes[components[v as usize] as usize] += 1;
                }
                (votes, near)
            },
        )
        .map(|(votes, _)| votes)
        .reduce(
            || empty.clone(),
            |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
        ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_evaluation::ground_truth_meshes::icosphere;

    /// A flat square grid of `n × n` vertices spanning `size` at `origin` (an open sheet).
    fn square(origin: DVec3, size: f64, n: u32) -> TriMesh {
        let vertices = (0..n * n)
            .map(|k| {
                origin + size * DVec3::new((k % n) as f64, (k / n) as f64, 0.0) / (n - 1) as f64
            })
            .collect();
        let triangles = (0..n - 1)
            .flat_map(|j| (0..n - 1).map(move |i| (i, j)))
            .flat_map(|(i, j)| {
                let v = j * n + i;
                [[v, v + 1, v + n + 1], [v, v + n + 1, v + n]]
            })
            .collect();
        TriMesh::new(vertices, triangles)
    }

    #[test]
    fn sheets_around_stray_samples_go_and_small_sampled_parts_stay() {
        // A closed sphere sampled at its vertices; a large open sheet with 5 stray samples
        // (its samples a thirtieth as dense); a small open plate sampled as densely as the
        // sphere.
        let sphere = icosphere(DVec3::ZERO, 0.3, 4);
        let sheet = square(DVec3::new(0.5, -0.3, 0.0), 0.3, 20);
        let plate = square(DVec3::new(-0.6, -0.6, 0.0), 0.02, 4);
        let mut mesh = sphere.clone();
        let mut points = sphere.vertices.clone();
        for part in [&sheet, &plate] {
            let base = mesh.vertices.len() as u32;
            mesh.vertices.extend_from_slice(&part.vertices);
            mesh.triangles
                .extend(part.triangles.iter().map(|t| t.map(|v| v + base)));
        }
        points.extend((0..5).map(|k| DVec3::new(0.55 + 0.05 * f64::from(k), -0.2, 0.0)));
        points.extend(&plate.vertices);
        // Every 4th sample votes: repeat each so that every one is counted.
        let points: Vec<DVec3> = points.iter().flat_map(|&p| [p; 4]).collect();
        let topology = MeshTopology::of(&mesh);
        assert_eq!(topology.components, 3);
        let isolated = vec![false; points.len()];
        let dropped = drop_unsupported_sheets(&mut mesh, &topology, &points, &isolated).unwrap();
        assert_eq!(dropped, 1);
        let after = MeshTopology::of(&mesh);
        assert_eq!(after.components, 2);
        assert_eq!(
            mesh.triangles.len(),
            sphere.triangles.len() + plate.triangles.len()
        );
        assert!(
            mesh.vertices.iter().all(|v| v.x < 0.45),
            "the sheet is gone"
        );
    }

    /// `parts` appended to one mesh.
    fn joined(parts: &[&TriMesh]) -> TriMesh {
        let mut mesh = TriMesh::default();
        for part in parts {
            let base = mesh.vertices.len() as u32;
            mesh.vertices.extend_from_slice(&part.vertices);
            mesh.triangles
                .extend(part.triangles.iter().map(|t| t.map(|v| v + base)));
        }
        mesh
    }

    #[test]
    fn small_open_parts_stay_when_enough_samples_support_them() {
        // Beside a sphere sampled at its vertices, all far below 1% of its area: an open
        // plate sampled as densely (kept), an open plate with 4 samples (dropped) and a
        // closed blob sampled as densely (dropped: a closed piece is no seen surface cut off
        // by an occlusion).
        let sphere = icosphere(DVec3::ZERO, 0.3, 4);
        let seen = square(DVec3::new(-0.6, -0.6, 0.0), 0.05, 8);
        let sparse = square(DVec3::new(0.6, -0.6, 0.0), 0.05, 8);
        let blob = icosphere(DVec3::new(0.0, 0.6, 0.0), 0.02, 2);
        let mut mesh = joined(&[&sphere, &seen, &sparse, &blob]);
        let mut points = sphere.vertices.clone();
        points.extend(&seen.vertices);
        points.extend(&sparse.vertices[..4]);
        points.extend(&blob.vertices);
        // Every 4th sample votes: repeat each so that every one is counted.
        let points: Vec<DVec3> = points.iter().flat_map(|&p| [p; 4]).collect();
        let isolated = vec![false; points.len()];
        let params = ReconParams::default();
        let (dropped, topology) = drop_small_components(&mut mesh, &params, |mesh, topology| {
            sample_votes(mesh, topology, &points, &isolated)
        })
        .unwrap();
        assert_eq!((dropped, topology.components), (2, 2));
        assert_eq!(
            mesh.triangles.len(),
            sphere.triangles.len() + seen.triangles.len()
        );
        assert!(mesh.vertices.iter().all(|v| v.x < 0.45 && v.y < 0.45));

        // Without a small open piece the samples are not asked.
        let mut closed = joined(&[&sphere, &blob]);
        let (dropped, _) = drop_small_components(&mut closed, &params, |_, _| {
            panic!("no small open component needs votes")
        })
        .unwrap();
        assert_eq!(dropped, 1);
    }
}
