//! Whether a reconstruction of a scan from the virtual range scanner keeps its shadow slits
//! open.
//!
//! A triangulation scanner records nothing where its projector cannot light the surface the
//! camera sees: beside every depth jump lies a narrow unsampled *shadow*
//! ([`crate::virtual_scanner`]). Along a row of the camera's image a shadow is a run of rays
//! between two samples, the near side of the jump on one end and the far side on the other.
//! Surface joining the two across the run is made up: the scanner saw a gap there, and the
//! true surface (the wall of the jump, seen edge on, and the unlit strip beyond) cannot be
//! told from it. A reconstruction keeps the slit *open* when, in the cross-section of the
//! output by the plane of that row, the surface at one end does not reach the surface at the
//! other without leaving the slit's neighbourhood.
//!
//! The scan has one sample per ray, so on surface facing the camera a ray of the grid is one
//! sample spacing: a slit `w` rays wide is about `w` spacings wide.

use rayon::prelude::*;
use sphcover_core::{DVec3, TriMesh, VertexTriangles};

use crate::scan_simulation::{ScanError, ScanParams, scanner_grids, surface_defects};
use crate::surface_sampling::SurfaceSampler;
use crate::triangle_bvh::{TriangleBvh, TriangleBvhError};
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
    /// Whether the output holds surface along both end rays (else the slit is open there by
    /// the output's own border).
    pub ends_covered: bool,
    /// Whether the output joins the two ends across the run.
    pub bridged: bool,
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
        let rows = self
            .rows
            .iter()
            .filter(|r| (min_width..=max_width).contains(&r.width));
        let (count, bridged) = rows.fold((0, 0), |(c, b), r| (c + 1, b + usize::from(r.bridged)));
        (count, bridged)
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
    // The grids `generate_scan` cast: the holes and gradient are drawn first from the seed.
    let sampler = SurfaceSampler::new(truth).map_err(ScanError::from)?;
    let mut rng = <rand_pcg::Pcg64 as rand::SeedableRng>::seed_from_u64(params.seed);
    let (in_hole, gradient) = surface_defects(truth, params, &sampler, &mut rng);
    let keep_probability = |p: DVec3| {
        if in_hole(p) {
            0.0
        } else {
            gradient.as_ref().map_or(1.0, |g| g(p))
        }
    };
    let (sides, _) = scanner_grids(&rig, params.count, keep_probability)?;

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
                    Return::Shadow(_) => shadowed = true,
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
    let rows = runs
        .par_iter()
        .map(|run| {
            let width = run.last - run.first - 1;
            let bridged = output_bvh
                .as_ref()
                .and_then(|bvh| joined_across(&rig, bvh, &around, output, run));
            SlitRow {
                width,
                ends: run.ends,
                ends_covered: bridged.is_some(),
                bridged: bridged == Some(true),
            }
        })
        .collect();
    Ok(ShadowSlits { rows })
}

/// Whether `output` joins the surface at the two end rays of `run` within the slab of the
/// run's row (`None` when an end ray misses the output).
fn joined_across(
    rig: &Rig,
    bvh: &TriangleBvh,
    around: &VertexTriangles,
    output: &TriMesh,
    run: &Run,
) -> Option<bool> {
    let y = grid_coordinate(run.side, run.row as f64);
    let end = |x: usize| {
        let (origin, direction) = rig.ray(run.camera, grid_coordinate(run.side, x as f64), y);
        let hit = bvh.first_hit(origin, direction, f64::INFINITY)?;
        Some((origin, direction, hit.triangle, origin + hit.t * direction))
    };
    let (origin, d_first, from, p_first) = end(run.first)?;
    let (_, d_last, to, p_last) = end(run.last)?;
    if from == to {
        return Some(true);
    }
    let normal = d_first.cross(d_last).try_normalize()?;
    // One ray of the grid at the depth of the farther end.
    let depth = (p_first - origin).length().max((p_last - origin).length());
    let ray_width =
        depth * (d_last - d_first).length() / (d_first.length() * (run.last - run.first) as f64);
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
        let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
        lo <= half_slab && hi >= -half_slab && centroid.distance(centre) <= radius
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
        let mut vertices = quad(0.0, 1.0).to_vec();
        vertices.extend(quad(gap, 0.4));
        let mut triangles = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        if joined {
            // The plate's rim joined to the wall by four skirts sharing its vertices: a
            // truncated pyramid, as a reconstruction bridging every slit would give.
            vertices.extend(quad(0.0, 0.4 + gap));
            for k in 0..4u32 {
                let (a, b) = (4 + k, 4 + (k + 1) % 4);
                let (c, d) = (8 + k, 8 + (k + 1) % 4);
                triangles.push([c, d, b]);
                triangles.push([c, b, a]);
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
        }
    }

    #[test]
    fn an_output_without_the_surface_at_the_ends_bridges_nothing() {
        let truth = plate_before_wall(0.2, false);
        let empty = TriMesh::new(Vec::new(), Vec::new());
        let slits = shadow_slits(&truth, &params(2), &empty).unwrap();
        assert!(!slits.rows.is_empty());
        assert!(slits.rows.iter().all(|r| !r.ends_covered && !r.bridged));
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
