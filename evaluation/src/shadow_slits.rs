//! Whether a reconstruction of a scan from the virtual range scanner keeps its shadow slits
//! open.
//!
//! A triangulation scanner records nothing where its projector cannot light the surface the
//! camera sees: beside every depth jump lies a narrow unsampled *shadow*
//! ([`crate::virtual_scanner`]). Along a row of the camera's image a shadow is a run of rays
//! between two samples, the near side of the jump on one end and the far side on the other
//! (with the rays that graze the occluder's rim, which record nothing either). A
//! reconstruction keeps the slit *open* when, in the cross-section of the output by the plane
//! of that row, the surface at one end does not reach the surface at the other without
//! leaving the slit's neighbourhood.
//!
//! The scanner saw a gap there, so surface joining the two ends is a guess. Where the truth
//! leaves the slit open too (a free edge before surface set back behind it) any bridge is made
//! up. Where the shadow falls on a steep face continuous with both ends, a bridge may follow
//! the face; how far it lies from the truth tells the two apart
//! ([`SlitRow::deviation_rays`]).
//!
//! The scan has one sample per ray, so on surface facing the camera a ray of the grid is one
//! sample spacing: a slit `w` rays wide is about `w` spacings wide.

use rayon::prelude::*;
use sphcover_core::{DVec3, TriMesh, VertexTriangles};

use crate::scan_simulation::{ScanError, ScanParams, scanned_grid_sides};
use crate::triangle_bvh::{TriangleBvh, TriangleBvhError, closest_point_on_triangle};
use crate::virtual_scanner::{Return, Rig, grid_coordinate};

/// How far the cross-section's neighbourhood of a slit reaches beyond the two ends, in rays
/// of the grid at the slit's depth: a bridge may bulge a little out of the straight line
/// between them, while the surface around the end of the slit lies farther.
const NEIGHBOURHOOD_RAYS: f64 = 2.0;

/// Half the thickness of the slab around a row's plane that makes its cross-section, in rays
/// of the grid at the slit's depth: thick enough that output triangles crossing the plane
/// chain together, thin enough that a path around the slit's end along the next rows leaves
/// it.
const SLAB_RAYS: f64 = 0.75;

/// How far from the sample at an end of a run, in rays of the grid, the output may pass and
/// still hold the surface at that end: above the scan's range noise (under a ray), below the
/// depth of any slit.
const END_REACH_RAYS: f64 = 3.0;

/// The output's distance to the truth across a bridged run is read along the rays at
/// `k / DEVIATION_RAYS` of the way from one end ray to the other, `0 < k < DEVIATION_RAYS`.
const DEVIATION_RAYS: usize = 8;

/// Why the slits could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum ShadowSlitError {
    /// The scan parameters have no virtual scanner.
    #[error("the scan has no virtual scanner, so it has no shadows")]
    NoScanner,
    /// The ground truth cannot be scanned again.
    #[error(transparent)]
    Scan(#[from] ScanError),
    /// The output cannot be ray cast.
    #[error("cannot ray cast the output: {0}")]
    Output(TriangleBvhError),
}

/// One row of one slit: a run of rays between two samples that holds shadowed rays (and
/// perhaps rays lost to a grazing angle at the occluder's rim).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlitRow {
    /// Rays in the run.
    pub width: usize,
    /// The samples at its two ends, in the order of the row.
    pub ends: [DVec3; 2],
    /// Whether the output holds surface at both ends: it passes within 3 rays of both end
    /// samples (else the slit is open there by the output's own border).
    pub ends_covered: bool,
    /// Whether the output joins the two ends across the run.
    pub bridged: bool,
    /// For a bridged row, how far the output lies from the truth across the run: the
    /// largest distance from the truth of the output's first hits along rays between the two
    /// ends, in rays of the grid at the slit's depth. Where the shadow falls on a steep face
    /// the truth is continuous across the run, and a bridge that follows it fills a gap of
    /// a sample or two; a bridge far from it is made up.
    pub deviation_rays: Option<f64>,
    /// Whether the truth itself joins the two ends across the run (the shadow falls on
    /// surface continuous with both, such as a steep face, rather than on surface set back
    /// behind a free edge).
    pub truth_joined: bool,
}

/// The shadow slits of a scan, row by row, and which the output bridges.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShadowSlits {
    /// Every slit row of every camera, camera after camera, row after row.
    pub rows: Vec<SlitRow>,
}

impl ShadowSlits {
    /// The slit rows at most `max_width` rays wide, and how many of them the output bridges.
    pub fn bridged_up_to(&self, max_width: usize) -> (usize, usize) {
        self.bridged_within(1, max_width)
    }

    /// The slit rows `min_width..=max_width` rays wide, and how many of them the output
    /// bridges.
    pub fn bridged_within(&self, min_width: usize, max_width: usize) -> (usize, usize) {
        let rows = self.rows_within(min_width, max_width);
        rows.fold((0, 0), |(c, b), r| (c + 1, b + usize::from(r.bridged)))
    }

    /// How many slit rows `min_width..=max_width` rays wide the output bridges with surface
    /// that is not the truth's: where the truth does not join the two ends, or farther than
    /// `rays` from it (see [`SlitRow::deviation_rays`]).
    pub fn bridged_off_truth(&self, min_width: usize, max_width: usize, rays: f64) -> usize {
        let rows = self.rows_within(min_width, max_width);
        rows.filter(|r| {
            r.bridged && (!r.truth_joined || r.deviation_rays.is_some_and(|d| d > rays))
        })
        .count()
    }

    /// How many slit rows `min_width..=max_width` rays wide lack the output's surface at an
    /// end (see [`SlitRow::ends_covered`]): open because the output left out what the scanner
    /// saw there.
    pub fn unheld_within(&self, min_width: usize, max_width: usize) -> usize {
        let rows = self.rows_within(min_width, max_width);
        rows.filter(|r| !r.ends_covered).count()
    }

    fn rows_within(&self, min_width: usize, max_width: usize) -> impl Iterator<Item = &SlitRow> {
        self.rows
            .iter()
            .filter(move |r| (min_width..=max_width).contains(&r.width))
    }
}

/// A run of shadowed rays found in a camera's image, with its two end rays.
struct Run {
    camera: usize,
    side: usize,
    row: usize,
    /// The sample rays just before and just after the run.
    first: usize,
    last: usize,
    /// Their samples.
    ends: [DVec3; 2],
}

/// The shadow slits of the scan `params` describe on `truth` (the same cameras and grids as
/// [`generate_scan`](crate::scan_simulation::generate_scan)), and whether `output` bridges
/// each.
///
/// ```
/// use sphcover_core::{DVec3, TriMesh};
/// use sphcover_evaluation::scan_simulation::{ScanParams, VirtualScanner};
/// use sphcover_evaluation::shadow_slits::shadow_slits;
///
/// // A plate before a wall, seen from +z by one camera whose projector stands beside it.
/// let quad = |z: f64, h: f64| {
///     let v = [(-h, -h), (h, -h), (h, h), (-h, h)].map(|(x, y)| DVec3::new(x, y, z));
///     TriMesh::new(v.to_vec(), vec![[0, 1, 2], [0, 2, 3]])
/// };
/// let mut truth = quad(0.0, 1.0);
/// let plate = quad(0.2, 0.4);
/// truth.triangles.extend(plate.triangles.iter().map(|t| t.map(|v| v + 4)));
/// truth.vertices.extend(plate.vertices);
/// let params = ScanParams {
///     count: 20_000,
///     scanner: Some(VirtualScanner {
///         views: 1,
///         up: DVec3::NEG_Y,
///         low_elevation_degrees: 0.0,
///         projector_baseline: 0.15,
///         ..VirtualScanner::default()
///     }),
///     ..ScanParams::default()
/// };
/// // The truth itself joins nothing across the slits: the plate floats before the wall.
/// let slits = shadow_slits(&truth, &params, &truth)?;
/// let (rows, bridged) = slits.bridged_up_to(usize::MAX);
/// assert!(rows > 10);
/// assert_eq!(bridged, 0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn shadow_slits(
    truth: &TriMesh,
    params: &ScanParams,
    output: &TriMesh,
) -> Result<ShadowSlits, ShadowSlitError> {
    let scanner = params.scanner.as_ref().ok_or(ShadowSlitError::NoScanner)?;
    let diagonal = truth.bounding_box().diagonal();
    let rig = Rig::new(truth, scanner, diagonal)?;
    let sides = scanned_grid_sides(truth, params, &rig)?;

    let mut runs = Vec::new();
    for (camera, side) in sides.iter().enumerate() {
        let Some(side) = *side else { continue };
        let image = rig.image(camera, side);
        for (row, returns) in image.chunks(side).enumerate() {
            // Gaps between samples holding shadow; the occluder's own rim may be lost to
            // grazing rays on the way.
            let mut last_sample: Option<(usize, DVec3)> = None;
            let mut shadowed = false;
            for (x, r) in returns.iter().enumerate() {
                match *r {
                    Return::Sample(p, ..) => {
                        if let Some((first, q)) = last_sample.filter(|_| shadowed) {
                            runs.push(Run {
                                camera,
                                side,
                                row,
                                first,
                                last: x,
                                ends: [q, p],
                            });
                        }
                        last_sample = Some((x, p));
                        shadowed = false;
                    }
                    Return::Shadow => shadowed = true,
                    Return::Nothing => {}
                }
            }
        }
    }

    let output_bvh = match TriangleBvh::new(output) {
        Ok(bvh) => Some(bvh),
        Err(TriangleBvhError::NoTriangles) => None,
        Err(e) => return Err(ShadowSlitError::Output(e)),
    };
    let around = VertexTriangles::of(output);
    let truth_around = VertexTriangles::of(truth);
    let rows = runs
        .par_iter()
        .map(|run| {
            let across = output_bvh
                .as_ref()
                .and_then(|bvh| joined_across(&rig, bvh, &around, output, run));
            let bridged = across == Some(true);
            SlitRow {
                width: run.last - run.first - 1,
                ends: run.ends,
                ends_covered: across.is_some(),
                bridged,
                deviation_rays: output_bvh
                    .as_ref()
                    .filter(|_| bridged)
                    .map(|bvh| deviation_from_truth(&rig, bvh, run)),
                truth_joined: joined_across(&rig, rig.mesh_bvh(), &truth_around, truth, run)
                    == Some(true),
            }
        })
        .collect();
    Ok(ShadowSlits { rows })
}

/// The ray through image column `x` (fractional) of `run`'s row: the camera's position and
/// the ray's direction.
fn run_ray(rig: &Rig, run: &Run, x: f64) -> (DVec3, DVec3) {
    let y = grid_coordinate(run.side, run.row as f64);
    rig.ray(run.camera, grid_coordinate(run.side, x), y)
}

/// The width of one ray of the grid at the depth of the farther end of `run`.
fn ray_width(rig: &Rig, run: &Run) -> f64 {
    let (origin, d_first) = run_ray(rig, run, run.first as f64);
    let (_, d_last) = run_ray(rig, run, run.last as f64);
    let depth = (run.ends[0] - origin)
        .length()
        .max((run.ends[1] - origin).length());
    depth * (d_last - d_first).length() / (d_first.length() * (run.last - run.first) as f64)
}

/// How far the output (`bvh`) lies from the truth across `run`, in rays (see
/// [`SlitRow::deviation_rays`]).
fn deviation_from_truth(rig: &Rig, bvh: &TriangleBvh, run: &Run) -> f64 {
    let span = (run.last - run.first) as f64;
    let largest = (1..DEVIATION_RAYS)
        .filter_map(|k| {
            let f = k as f64 / DEVIATION_RAYS as f64;
            let (origin, direction) = run_ray(rig, run, run.first as f64 + f * span);
            let hit = bvh.first_hit(origin, direction, f64::INFINITY)?;
            let closest = rig.mesh_bvh().closest_point(origin + hit.t * direction)?;
            Some(closest.distance_squared.sqrt())
        })
        .fold(0.0, f64::max);
    largest / ray_width(rig, run)
}

/// Whether the mesh `output` (with its BVH and vertex index) joins its surface at the two
/// end samples of `run` within the slab of the run's row: `None` when it passes no nearer
/// than [`END_REACH_RAYS`] to an end's sample.
fn joined_across(
    rig: &Rig,
    bvh: &TriangleBvh,
    around: &VertexTriangles,
    output: &TriMesh,
    run: &Run,
) -> Option<bool> {
    let (origin, d_first) = run_ray(rig, run, run.first as f64);
    let (_, d_last) = run_ray(rig, run, run.last as f64);
    let ray_width = ray_width(rig, run);
    // The output's surface at each end: its triangle nearest the end's sample, if near. (Not
    // the end ray's hit: past a rounded corner of the output that ray reaches what lies
    // behind, and two ends on the surface behind would read as joined.)
    let reach = END_REACH_RAYS * ray_width;
    let held = |sample: DVec3| {
        let closest = bvh.closest_point(sample)?;
        (closest.distance_squared <= reach * reach).then_some((closest.triangle, closest.point))
    };
    let (from, p_first) = held(run.ends[0])?;
    let (to, p_last) = held(run.ends[1])?;
    if from == to {
        return Some(true);
    }
    let Some(normal) = d_first.cross(d_last).try_normalize() else {
        return Some(false);
    };
    let half_slab = SLAB_RAYS * ray_width;
    let centre = 0.5 * (p_first + p_last);
    let radius = 0.5 * (p_last - p_first).length() + NEIGHBOURHOOD_RAYS * ray_width;
    let inside = |t: u32| {
        let corners = output.triangles[t as usize].map(|v| output.vertices[v as usize]);
        let side = corners.map(|c| (c - origin).dot(normal));
        let (lo, hi) = (
            side[0].min(side[1]).min(side[2]),
            side[0].max(side[1]).max(side[2]),
        );
        let [a, b, c] = corners;
        lo <= half_slab
            && hi >= -half_slab
            && closest_point_on_triangle(centre, a, b, c).distance(centre) <= radius
    };
    let mut seen = std::collections::HashSet::from([from]);
    let mut stack = vec![from];
    while let Some(t) = stack.pop() {
        for &v in &output.triangles[t as usize] {
            for &next in around.triangles_at(v as usize) {
                if next == to {
                    return Some(true);
                }
                if inside(next) && seen.insert(next) {
                    stack.push(next);
                }
            }
        }
    }
    Some(false)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan_simulation::VirtualScanner;

    /// A wall `z = 0` of half-width 1 and a plate of half-width 0.4 at `z = gap` before it.
    fn plate_before_wall(gap: f64, joined: bool) -> TriMesh {
        let quad =
            |z: f64, h: f64| [(-h, -h), (h, -h), (h, h), (-h, h)].map(|(x, y)| DVec3::new(x, y, z));
        // The wall's outer corners (0–3) and the corners of the square behind the plate
        // (4–7), then the plate (8–11).
        let mut vertices = quad(0.0, 1.0).to_vec();
        vertices.extend(quad(0.0, 0.4));
        vertices.extend(quad(gap, 0.4));
        let mut triangles = vec![[4, 5, 6], [4, 6, 7], [8, 9, 10], [8, 10, 11]];
        for k in 0..4u32 {
            let next = (k + 1) % 4;
            triangles.push([k, next, 4 + next]);
            triangles.push([k, 4 + next, 4 + k]);
            if joined {
                // The plate's rim joined straight down to the wall by skirts sharing its
                // vertices and the wall's, as a reconstruction bridging every slit would.
                triangles.push([4 + k, 4 + next, 8 + next]);
                triangles.push([4 + k, 8 + next, 8 + k]);
            }
        }
        TriMesh::new(vertices, triangles)
    }

    fn params(seed: u64) -> ScanParams {
        ScanParams {
            count: 20_000,
            seed,
            scanner: Some(VirtualScanner {
                views: 1,
                up: DVec3::NEG_Y,
                low_elevation_degrees: 0.0,
                projector_baseline: 0.15,
                ..VirtualScanner::default()
            }),
            ..ScanParams::default()
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(12))]

        /// Whatever the depth jump and the seed, the truth (the plate floats before the wall)
        /// bridges none of its own slits, and skirts joining the plate's rim to the wall
        /// bridge every one.
        #[test]
        fn a_floating_plate_leaves_its_slits_open_and_skirts_bridge_them(
            gap in 0.1f64..0.4,
            seed in 0u64..1000,
        ) {
            let truth = plate_before_wall(gap, false);
            let open = shadow_slits(&truth, &params(seed), &truth).unwrap();
            let (rows, bridged) = open.bridged_up_to(usize::MAX);
            // The shadow runs along one side of the plate, a few rays wide (`gap` × 0.1 of
            // the diagonal, 2–6 rays), on every row the plate covers.
            proptest::prop_assert!(rows > 20, "{}", rows);
            proptest::prop_assert_eq!(bridged, 0);
            proptest::prop_assert!(open.rows.iter().all(|r| r.ends_covered && r.width < 12));
            let skirted = plate_before_wall(gap, true);
            let closed = shadow_slits(&truth, &params(seed), &skirted).unwrap();
            proptest::prop_assert_eq!(closed.rows.len(), rows);
            proptest::prop_assert_eq!(closed.bridged_up_to(usize::MAX), (rows, rows));
            // The truth does not join the ends, so no bridge is the truth's.
            proptest::prop_assert!(open.rows.iter().all(|r| !r.truth_joined));
            proptest::prop_assert_eq!(closed.bridged_off_truth(1, usize::MAX, 2.0), rows);
        }
    }

    #[test]
    fn a_bridge_that_follows_the_truth_over_a_steep_face_is_on_it() {
        // A step seen from +z: a ledge at z = 0.4 for x < 0, a steep face down to the floor
        // at x = 0.02, the floor beyond. The camera sees the face at a grazing angle, and the
        // ledge's edge hides the floor's first stretch from the projector (on the −x side).
        let profile = [(-1.0, 0.4), (0.0, 0.4), (0.02, 0.0), (1.0, 0.0)];
        let vertices: Vec<DVec3> = profile
            .iter()
            .flat_map(|&(x, z)| [DVec3::new(x, -1.0, z), DVec3::new(x, 1.0, z)])
            .collect();
        let triangles = (0..3u32)
            .flat_map(|k| {
                let (a, b, c, d) = (2 * k, 2 * k + 2, 2 * k + 3, 2 * k + 1);
                [[a, b, c], [a, c, d]]
            })
            .collect();
        let step = TriMesh::new(vertices, triangles);
        let slits = shadow_slits(&step, &params(3), &step).unwrap();
        let (rows, bridged) = slits.bridged_up_to(usize::MAX);
        assert!(rows > 20, "{rows}");
        // The truth joins the ends (over the face), and lies on itself.
        assert_eq!(bridged, rows);
        assert!(slits.rows.iter().all(|r| r.truth_joined));
        assert!(
            slits
                .rows
                .iter()
                .all(|r| r.deviation_rays.is_some_and(|d| d < 1e-9))
        );
        assert_eq!(slits.bridged_off_truth(1, usize::MAX, 1e-9), 0);
    }

    #[test]
    fn an_output_without_the_surface_at_the_ends_bridges_nothing() {
        let truth = plate_before_wall(0.2, false);
        let empty = TriMesh::new(Vec::new(), Vec::new());
        let slits = shadow_slits(&truth, &params(2), &empty).unwrap();
        assert!(!slits.rows.is_empty());
        assert!(slits.rows.iter().all(|r| !r.ends_covered && !r.bridged));
        // Without the plate, the rays at its end reach the wall behind it, far from the
        // plate's samples: that end is not held either, though the wall joins the rays.
        let mut wall = truth.clone();
        wall.triangles.retain(|t| t.iter().all(|&v| v < 8));
        let slits = shadow_slits(&truth, &params(2), &wall).unwrap();
        assert!(slits.rows.iter().all(|r| !r.ends_covered && !r.bridged));
        assert_eq!(slits.unheld_within(1, usize::MAX), slits.rows.len());
    }

    #[test]
    fn a_scan_without_a_scanner_is_refused() {
        let truth = plate_before_wall(0.2, false);
        assert!(matches!(
            shadow_slits(&truth, &ScanParams::default(), &truth),
            Err(ShadowSlitError::NoScanner)
        ));
    }
}
