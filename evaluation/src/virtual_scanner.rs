//! The virtual range scanner behind [`ScanParams::scanner`](crate::scan_simulation::ScanParams):
//! cameras that cast regular grids of rays at a mesh and record the first surface each ray
//! meets, unless it is seen at a grazing angle.
//!
//! A triangulation scanner (laser line or structured light) also needs its projector to light
//! the point it records, and the projector stands a *baseline* beside the camera. Where the
//! surface behind a depth jump is seen by the camera but hidden from the projector by the
//! nearer surface, nothing is recorded: a narrow unsampled *shadow* runs along the occluding
//! edge, on the side away from the projector, about `depth gap × baseline / distance` wide.
//! [`VirtualScanner::projector_baseline`] adds that projector; at 0 (the default) every hit
//! the camera sees is kept, and the scans are those of a scanner without one.

use rayon::prelude::*;
use sphcover_core::{DVec3, TriMesh};

use crate::scan_simulation::ScanError;
use crate::triangle_bvh::TriangleBvh;

/// Rays per side of the pilot grid that estimates how much of a camera's view the object
/// fills.
const PILOT_GRID: usize = 48;

/// How far the test of the projector's light starts from the hit, towards the projector, in
/// bounding-box diagonals: far above the rounding of a hit point (about 1e-16 of the camera's
/// distance), far below any sample spacing, so the hit's own triangle is never taken for an
/// occluder and nothing thinner than this is missed.
const PROJECTOR_RAY_OFFSET: f64 = 1e-7;

/// A virtual range scanner, set up like a turntable scan: cameras around the `up` axis,
/// alternately at a low and a high elevation, each casting a regular grid of rays over the
/// object's bounding sphere. With both elevations positive (the default) the underside is
/// never seen, as when the object stands on the turntable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VirtualScanner {
    /// Number of camera positions, evenly spaced in azimuth.
    pub views: usize,
    /// Distance of the cameras from the bounding-box centre, in bounding-box diagonals
    /// (more than 0.5, so they are outside the bounding sphere).
    pub distance: f64,
    /// The turntable's axis.
    pub up: DVec3,
    /// Elevation of the even views above the plane normal to `up`, in degrees.
    pub low_elevation_degrees: f64,
    /// Elevation of the odd views, in degrees.
    pub high_elevation_degrees: f64,
    /// Standard deviation of the noise along each ray, as a fraction of the diagonal.
    pub range_noise: f64,
    /// Hits at a larger angle between ray and surface normal are dropped, as real scanners
    /// lose grazing returns (degrees, in (0, 90]). With a projector, the angle between the
    /// normal and the direction to the projector is bounded too.
    pub max_incidence_degrees: f64,
    /// Distance from each camera to its projector, along the camera's horizontal image axis
    /// (the direction of `forward × up`), in bounding-box diagonals (≥ 0). With a projector a
    /// hit is kept only where the projector lights it too: the segment from the hit to the
    /// projector meets no other surface, on the camera's side of the triangle, and not at a
    /// grazing angle. 0 (the default) means no projector.
    pub projector_baseline: f64,
}

impl Default for VirtualScanner {
    fn default() -> VirtualScanner {
        VirtualScanner {
            views: 6,
            distance: 1.5,
            up: DVec3::Y,
            low_elevation_degrees: 10.0,
            high_elevation_degrees: 40.0,
            range_noise: 0.001,
            max_incidence_degrees: 80.0,
            projector_baseline: 0.0,
        }
    }
}

/// One camera of the virtual scanner.
struct Camera {
    position: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    /// Tangent of the half opening angle that just holds the bounding sphere.
    tan_half: f64,
    /// Where its projector stands, if it has one.
    projector: Option<DVec3>,
}

impl Camera {
    /// Direction of the ray through image coordinates `(x, y) ∈ [-1, 1]²`.
    fn ray(&self, x: f64, y: f64) -> DVec3 {
        self.forward + self.tan_half * (x * self.right + y * self.up)
    }
}

/// A sample of the scanner: the hit point, the unit normal of the triangle hit and the unit
/// ray.
pub(crate) type ScannerSample = (DVec3, DVec3, DVec3);

/// What one ray of a camera records.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Return {
    /// A sample: the hit point, the unit normal of the triangle hit and the unit ray.
    Sample(DVec3, DVec3, DVec3),
    /// Surface the camera sees, not at a grazing angle, but hidden from the projector by
    /// other surface: the shadow of a depth jump.
    Shadow,
    /// No surface, surface seen at a grazing angle, or surface the projector cannot light
    /// for its own angle.
    Nothing,
}

/// The cameras of a [`VirtualScanner`] set up around one mesh, and the mesh's BVH they cast
/// rays at.
pub(crate) struct Rig {
    bvh: TriangleBvh,
    cameras: Vec<Camera>,
    min_cos: f64,
    ray_offset: f64,
}

/// The image coordinate in `[-1, 1]` of the centre of ray `i` of a grid `side` rays wide.
pub(crate) fn grid_coordinate(side: usize, i: f64) -> f64 {
    -1.0 + (2.0 * i + 1.0) / side as f64
}

impl Rig {
    /// The cameras of `scanner` around `mesh`, whose bounding box has the diagonal `diagonal`.
    pub(crate) fn new(
        mesh: &TriMesh,
        scanner: &VirtualScanner,
        diagonal: f64,
    ) -> Result<Rig, ScanError> {
        let bvh = TriangleBvh::new(mesh)?;
        let centre = mesh.bounding_box().centre();
        let radius = 0.5 * diagonal;
        let distance = scanner.distance * diagonal;
        let up = scanner.up.normalize();
        let e1 = up.any_orthonormal_vector();
        let e2 = up.cross(e1);
        let tan_half = radius / (distance * distance - radius * radius).sqrt();
        let baseline = scanner.projector_baseline * diagonal;
        let cameras = (0..scanner.views)
            .map(|k| {
                let azimuth = std::f64::consts::TAU * k as f64 / scanner.views as f64;
                let elevation = if k % 2 == 0 {
                    scanner.low_elevation_degrees
                } else {
                    scanner.high_elevation_degrees
                }
                .to_radians();
                let dir = elevation.cos() * (azimuth.cos() * e1 + azimuth.sin() * e2)
                    + elevation.sin() * up;
                let forward = -dir;
                let right = forward.cross(up).try_normalize().unwrap_or(e1);
                let position = centre + distance * dir;
                Camera {
                    position,
                    forward,
                    right,
                    up: right.cross(forward),
                    tan_half,
                    projector: (baseline > 0.0).then(|| position + baseline * right),
                }
            })
            .collect();
        Ok(Rig {
            bvh,
            cameras,
            min_cos: scanner.max_incidence_degrees.to_radians().cos(),
            ray_offset: PROJECTOR_RAY_OFFSET * diagonal,
        })
    }

    /// Where camera `camera` stands, and the direction (not unit) of its ray through image
    /// coordinates `(x, y)`.
    pub(crate) fn ray(&self, camera: usize, x: f64, y: f64) -> (DVec3, DVec3) {
        let cam = &self.cameras[camera];
        (cam.position, cam.ray(x, y))
    }

    /// The BVH of the mesh the rig scans.
    pub(crate) fn mesh_bvh(&self) -> &TriangleBvh {
        &self.bvh
    }

    /// Is the segment from the point `p` (of a triangle of unit normal `n`, seen along the
    /// unit ray `unit`) to the projector at `projector` free, and does it leave the triangle
    /// on the camera's side, not at a grazing angle? `None` for the angle, `Some(false)` when
    /// other surface is in between.
    fn lit(&self, projector: DVec3, p: DVec3, n: DVec3, unit: DVec3) -> Option<bool> {
        let to_projector = projector - p;
        let length = to_projector.length();
        let towards = to_projector / length;
        let cos = n.dot(towards);
        if cos.abs() < self.min_cos || cos * n.dot(unit) > 0.0 || length <= self.ray_offset {
            return None;
        }
        Some(
            self.bvh
                .first_hit(
                    p + self.ray_offset * towards,
                    towards,
                    length - self.ray_offset,
                )
                .is_none(),
        )
    }

    /// What camera `camera` records along its ray through image coordinates `(x, y)`.
    pub(crate) fn cast(&self, camera: usize, x: f64, y: f64) -> Return {
        let cam = &self.cameras[camera];
        let d = cam.ray(x, y);
        let Some(hit) = self.bvh.first_hit(cam.position, d, f64::INFINITY) else {
            return Return::Nothing;
        };
        let n = self.bvh.triangle_normal(hit.triangle);
        let unit = d.normalize();
        if n.dot(unit).abs() < self.min_cos {
            return Return::Nothing;
        }
        let p = cam.position + hit.t * d;
        match cam
            .projector
            .map(|projector| self.lit(projector, p, n, unit))
        {
            None | Some(Some(true)) => Return::Sample(p, n, unit),
            Some(Some(false)) => Return::Shadow,
            Some(None) => Return::Nothing,
        }
    }

    /// The side of each camera's square grid of rays, sized for about `target` samples in
    /// all (`None` for a camera that sees nothing of the mesh).
    pub(crate) fn grid_sides(&self, target: f64) -> Result<Vec<Option<usize>>, ScanError> {
        let per_view = target / self.cameras.len() as f64;
        let sides: Vec<Option<usize>> = (0..self.cameras.len())
            .map(|camera| {
                let pilot = (0..PILOT_GRID * PILOT_GRID)
                    .into_par_iter()
                    .filter(|&k| {
                        let (x, y) = ((k % PILOT_GRID) as f64, (k / PILOT_GRID) as f64);
                        matches!(
                            self.cast(
                                camera,
                                grid_coordinate(PILOT_GRID, x),
                                grid_coordinate(PILOT_GRID, y)
                            ),
                            Return::Sample(..)
                        )
                    })
                    .count();
                (pilot > 0).then(|| {
                    let fill = pilot as f64 / (PILOT_GRID * PILOT_GRID) as f64;
                    ((per_view / fill).sqrt().ceil() as usize).max(1)
                })
            })
            .collect();
        if sides.iter().all(Option::is_none) {
            return Err(ScanError::NothingVisible);
        }
        Ok(sides)
    }

    /// Every return of camera `camera` on its grid `side` rays wide, row after row.
    pub(crate) fn image(&self, camera: usize, side: usize) -> Vec<Return> {
        (0..side * side)
            .into_par_iter()
            .map(|k| {
                let (x, y) = ((k % side) as f64, (k / side) as f64);
                self.cast(camera, grid_coordinate(side, x), grid_coordinate(side, y))
            })
            .collect()
    }

    /// The samples of every camera on the grids `sides` (see [`Rig::grid_sides`]): points,
    /// unit normals of the triangles hit and unit ray directions, camera after camera, row
    /// after row.
    pub(crate) fn samples(&self, sides: &[Option<usize>]) -> Vec<ScannerSample> {
        let mut samples = Vec::new();
        for (camera, side) in sides.iter().enumerate() {
            if let Some(side) = *side {
                samples.extend(
                    self.image(camera, side)
                        .into_iter()
                        .filter_map(|r| match r {
                            Return::Sample(p, n, unit) => Some((p, n, unit)),
                            _ => None,
                        }),
                );
            }
        }
        samples
    }
}

/// Casts the ray grid of every camera, sized for about `target` hits in all; returns the hit
/// points, the unit normals of the triangles hit and the unit ray directions, camera after
/// camera, row after row.
#[cfg(test)]
fn scan_with_cameras(
    mesh: &TriMesh,
    scanner: &VirtualScanner,
    target: f64,
    diagonal: f64,
) -> Result<Vec<ScannerSample>, ScanError> {
    let rig = Rig::new(mesh, scanner, diagonal)?;
    Ok(rig.samples(&rig.grid_sides(target)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ground_truth_meshes::{boxes, icosphere};
    use crate::scan_simulation::{ScanCase, ScanParams, generate_scan};

    /// A square `[-1, 1]²` in the plane `z = 0` and, 0.3 in front of it (towards +z), a box
    /// `[-0.6, 0.6] × [-0.2, 0.2] × [0.3, 0.4]`: a depth jump along each of the box's sides.
    fn box_before_wall() -> TriMesh {
        let mut m = boxes(&[(DVec3::new(-0.6, -0.2, 0.3), DVec3::new(0.6, 0.2, 0.4))]);
        m.vertices.extend([
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ]);
        m.triangles.extend([[8, 9, 10], [8, 10, 11]]);
        m
    }

    /// One camera straight in front (+z), looking at the wall and the box: with `up` = −y
    /// the azimuth 0 lies along +z, and the camera's right axis, `forward × up` =
    /// (−z) × (−y), is −x, so the projector stands on the −x side.
    fn front_camera(baseline: f64) -> VirtualScanner {
        assert_eq!(DVec3::NEG_Y.any_orthonormal_vector(), DVec3::Z);
        assert_eq!(DVec3::NEG_Z.cross(DVec3::NEG_Y), DVec3::NEG_X);
        VirtualScanner {
            views: 1,
            up: DVec3::NEG_Y,
            low_elevation_degrees: 0.0,
            range_noise: 0.0,
            projector_baseline: baseline,
            ..VirtualScanner::default()
        }
    }

    fn hits(mesh: &TriMesh, scanner: &VirtualScanner, target: f64) -> Vec<DVec3> {
        let diagonal = mesh.bounding_box().diagonal();
        scan_with_cameras(mesh, scanner, target, diagonal)
            .unwrap()
            .into_iter()
            .map(|h| h.0)
            .collect()
    }

    #[test]
    fn a_projector_leaves_a_shadow_beside_the_occluder_on_the_far_side() {
        let mesh = box_before_wall();
        let bbox = mesh.bounding_box();
        let diagonal = bbox.diagonal();
        let plain = hits(&mesh, &front_camera(0.0), 40_000.0);
        let shadowed = hits(&mesh, &front_camera(0.15), 40_000.0);

        // Camera at height `h` above the wall (on the z axis), projector `b` beside it at −x.
        // The box's front edge at x = 0.6, z = 0.4 hides the wall from the camera up to
        // x = 0.6 + 0.6 · 0.4 / (h − 0.4), and from the projector up to
        // x = 0.6 + (0.6 + b) · 0.4 / (h − 0.4): between the two the camera sees wall the
        // projector does not light, a strip 0.4 · b / (h − 0.4) wide (about 0.04 here, four
        // rays of the grid).
        let h = bbox.centre().z + 1.5 * diagonal;
        let b = 0.15 * diagonal;
        let seen_from = 0.6 + 0.6 * 0.4 / (h - 0.4);
        let lit_from = 0.6 + (0.6 + b) * 0.4 / (h - 0.4);
        let wall = |p: &DVec3| p.z.abs() < 1e-9 && p.y.abs() < 0.15;
        let in_shadow = |p: &&DVec3| wall(p) && p.x > seen_from && p.x < lit_from - 1e-3;
        let plain_in_shadow = plain.iter().filter(in_shadow).count();
        assert!(plain_in_shadow > 50, "{plain_in_shadow}");
        assert_eq!(shadowed.iter().filter(in_shadow).count(), 0);
        // The shadow is narrow: beyond it the wall is sampled again.
        assert!(
            shadowed
                .iter()
                .any(|p| wall(p) && p.x > lit_from + 1e-3 && p.x < lit_from + 0.02)
        );
        // On the projector's side of the box the wall is lit wherever the camera sees it.
        let other_side = |p: &&DVec3| wall(p) && p.x < -0.6;
        let nearest = |v: &[DVec3]| {
            v.iter()
                .filter(other_side)
                .map(|p| p.x)
                .fold(f64::NEG_INFINITY, f64::max)
        };
        // (Within a ray of the grid, about 0.01 apart on the wall, of where the camera's
        // view begins.)
        assert!(
            nearest(&shadowed) > -seen_from - 0.015,
            "{}",
            nearest(&shadowed)
        );
        assert!(nearest(&plain) > -seen_from - 0.015);
        // The box's front face is lit and seen alike.
        assert!(shadowed.iter().any(|p| (p.z - 0.4).abs() < 1e-9));
        // Shadows take surface away; the pilot grid makes up for it, so about the target
        // count is still reached.
        assert!(shadowed.len() as f64 > 0.9 * 40_000.0, "{}", shadowed.len());
    }

    #[test]
    fn the_projector_test_drops_nothing_on_a_convex_shape_it_sees_squarely() {
        // On a sphere nothing casts a shadow; only hits too grazing for the projector go.
        let mesh = icosphere(DVec3::ZERO, 1.0, 4);
        let plain = hits(&mesh, &front_camera(0.0), 10_000.0);
        let shadowed = hits(&mesh, &front_camera(0.05), 10_000.0);
        assert!(shadowed.len() as f64 > 0.9 * plain.len() as f64);
        let far_from_the_rim = |v: &[DVec3]| v.iter().filter(|p| p.z > 0.5).count();
        let lost = far_from_the_rim(&plain) as f64 - far_from_the_rim(&shadowed) as f64;
        assert!(
            lost.abs() < 0.05 * far_from_the_rim(&plain) as f64,
            "{lost}"
        );
    }

    #[test]
    fn a_zero_baseline_is_the_scanner_without_a_projector() {
        assert_eq!(VirtualScanner::default().projector_baseline, 0.0);
        let mesh = box_before_wall();
        let params = |scanner| ScanParams {
            count: 5000,
            seed: 4,
            scanner: Some(scanner),
            ..ScanParams::default()
        };
        let default = generate_scan(&mesh, &ScanCase::Scanner.params(5000, 4)).unwrap();
        let zero = generate_scan(
            &mesh,
            &params(VirtualScanner {
                projector_baseline: 0.0,
                ..VirtualScanner::default()
            }),
        )
        .unwrap();
        assert_eq!(default, zero);
        let with = generate_scan(
            &mesh,
            &params(VirtualScanner {
                projector_baseline: 0.15,
                ..VirtualScanner::default()
            }),
        )
        .unwrap();
        assert_ne!(default.cloud.positions, with.cloud.positions);
    }

    #[test]
    fn bad_baselines_are_refused() {
        let mesh = icosphere(DVec3::ZERO, 1.0, 2);
        for baseline in [-0.1, f64::NAN, f64::INFINITY] {
            let params = ScanParams {
                scanner: Some(VirtualScanner {
                    projector_baseline: baseline,
                    ..VirtualScanner::default()
                }),
                ..ScanParams::default()
            };
            assert!(matches!(
                generate_scan(&mesh, &params),
                Err(ScanError::InvalidParameter(sphcover_core::ParameterError {
                    name: "scanner.projector_baseline",
                    ..
                }))
            ));
        }
    }
}
