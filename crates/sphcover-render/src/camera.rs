//! The camera: a direction of view around an up axis, orthographic or perspective, fitted so
//! that the geometry fills the viewport.

use glam::DVec3;
use rayon::prelude::*;

/// Fraction of the viewport left free on each side of the fitted geometry.
pub(crate) const MARGIN: f64 = 0.05;

/// Elevation of the isometric view: the cube diagonal points at the camera.
const ISO_ELEVATION_DEG: f64 = 35.264_389_682_754_654;

/// The world axis drawn pointing up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpAxis {
    /// `+x` up.
    X,
    /// `+y` up (the Stanford scans, most mesh tools).
    Y,
    /// `+z` up (LiDAR, CAD, CT).
    Z,
}

impl UpAxis {
    /// Parses `x`, `y` or `z`.
    pub fn parse(text: &str) -> Result<UpAxis, String> {
        match text.to_ascii_lowercase().as_str() {
            "x" => Ok(UpAxis::X),
            "y" => Ok(UpAxis::Y),
            "z" => Ok(UpAxis::Z),
            _ => Err(format!("up axis {text:?}: expected x, y or z")),
        }
    }

    /// (up, front, right): the front view looks from `front` towards the object with
    /// `right` pointing right; `right = up × front`, so the frame is right-handed.
    fn frame(self) -> (DVec3, DVec3, DVec3) {
        match self {
            UpAxis::Y => (DVec3::Y, DVec3::Z, DVec3::X),
            UpAxis::Z => (DVec3::Z, DVec3::NEG_Y, DVec3::X),
            UpAxis::X => (DVec3::X, DVec3::Y, DVec3::Z),
        }
    }
}

/// Where the camera looks from, in degrees: azimuth around the up axis from the front view
/// towards the right view, elevation above the horizontal plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewAngles {
    /// Degrees around the up axis; 90 is the right view.
    pub azimuth: f64,
    /// Degrees above the horizontal plane, in [-90, 90]; 90 is the top view.
    pub elevation: f64,
}

impl ViewAngles {
    /// Parses a view name (`front`, `back`, `left`, `right`, `top`, `bottom`, `iso`) or
    /// `AZ,EL` in degrees.
    pub fn parse(text: &str) -> Result<ViewAngles, String> {
        let (azimuth, elevation) = match text.to_ascii_lowercase().as_str() {
            "front" => (0.0, 0.0),
            "back" => (180.0, 0.0),
            "right" => (90.0, 0.0),
            "left" => (-90.0, 0.0),
            "top" => (0.0, 90.0),
            "bottom" => (0.0, -90.0),
            "iso" => (45.0, ISO_ELEVATION_DEG),
            other => {
                let bad = || {
                    format!(
                        "view {text:?}: expected front, back, left, right, top, bottom, iso or AZ,EL in degrees (e.g. 30,20)"
                    )
                };
                let (a, e) = other.split_once(',').ok_or_else(bad)?;
                let a: f64 = a.trim().parse().map_err(|_| bad())?;
                let e: f64 = e.trim().parse().map_err(|_| bad())?;
                if !a.is_finite() || !e.is_finite() {
                    return Err(bad());
                }
                if !(-90.0..=90.0).contains(&e) {
                    return Err(format!(
                        "view {text:?}: the elevation must lie in [-90, 90] degrees"
                    ));
                }
                (a, e)
            }
        };
        Ok(ViewAngles { azimuth, elevation })
    }
}

/// How 3D points map to the image plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Parallel rays: sizes do not depend on depth (measurable views, the default).
    Orthographic,
    /// A pinhole camera with this vertical field of view in degrees, placed so that the
    /// bounding sphere just fits in it.
    Perspective {
        /// Field of view, degrees, in (0, 170).
        fov_deg: f64,
    },
}

/// An image-plane position in pixels (x right, y down) and its depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projected {
    /// Pixels from the left edge.
    pub x: f64,
    /// Pixels from the top edge.
    pub y: f64,
    /// Distance from the camera along the view direction (orthographic: from a plane
    /// through the scene centre, so it may be negative).
    pub distance: f64,
}

/// A camera fitted to a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Unit vector from the scene towards the camera.
    pub toward_viewer: DVec3,
    /// Unit vector pointing right in the image.
    pub right: DVec3,
    /// Unit vector pointing up in the image.
    pub up: DVec3,
    projection: Projection,
    /// Orthographic: the scene centre; perspective: the eye.
    origin: DVec3,
    /// Pixels per unit of the image-plane coordinate (world units, or tangent for
    /// perspective).
    scale: f64,
    /// Image-plane coordinates that land at the viewport centre.
    plane_centre: [f64; 2],
    /// Viewport centre in pixels.
    pixel_centre: [f64; 2],
}

/// The rectangle of the image the geometry is fitted into, in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viewport {
    /// Left edge.
    pub x: f64,
    /// Top edge.
    pub y: f64,
    /// Width.
    pub width: f64,
    /// Height.
    pub height: f64,
}

/// The view-frame axes of a direction: (toward viewer, right, up).
pub(crate) fn view_frame(angles: ViewAngles, up_axis: UpAxis) -> (DVec3, DVec3, DVec3) {
    let (up, front, right) = up_axis.frame();
    let (sa, ca) = angles.azimuth.to_radians().sin_cos();
    let (se, ce) = angles.elevation.to_radians().sin_cos();
    let toward = (ce * (ca * front + sa * right) + se * up).normalize();
    let image_right = (ca * right - sa * front).normalize();
    let image_up = toward.cross(image_right).normalize();
    (toward, image_right, image_up)
}

impl Camera {
    /// The camera looking from `angles` that fits `positions` (with optional ball radii)
    /// into `viewport`, leaving 5% of the viewport free on each side. Non-finite positions
    /// are ignored. `None` when no position is finite.
    pub fn fit(
        positions: &[DVec3],
        radii: Option<&[f64]>,
        angles: ViewAngles,
        up_axis: UpAxis,
        projection: Projection,
        viewport: Viewport,
    ) -> Option<Camera> {
        let (toward, right, up) = view_frame(angles, up_axis);
        let radius_of = |i: usize| radii.map_or(0.0, |r| r[i].abs());
        let usable = |i: usize| positions[i].is_finite() && radius_of(i).is_finite();
        // Min and max are exact, so the reduction order cannot change the result.
        let bounds = (0..positions.len())
            .into_par_iter()
            .filter(|&i| usable(i))
            .map(|i| {
                let r = DVec3::splat(radius_of(i));
                (positions[i] - r, positions[i] + r)
            })
            .reduce_with(|a, b| (a.0.min(b.0), a.1.max(b.1)))?;
        let centre = 0.5 * (bounds.0 + bounds.1);
        let mut camera = Camera {
            toward_viewer: toward,
            right,
            up,
            projection,
            origin: centre,
            scale: 1.0,
            plane_centre: [0.0, 0.0],
            pixel_centre: [
                viewport.x + 0.5 * viewport.width,
                viewport.y + 0.5 * viewport.height,
            ],
        };
        if let Projection::Perspective { fov_deg } = projection {
            let bounding_radius = (0..positions.len())
                .into_par_iter()
                .filter(|&i| usable(i))
                .map(|i| (positions[i] - centre).length() + radius_of(i))
                .reduce(|| 0.0, f64::max);
            let half = (0.5 * fov_deg).to_radians();
            let distance = bounding_radius.max(f64::MIN_POSITIVE) / half.sin();
            camera.origin = centre + toward * distance;
        }
        let extent = (0..positions.len())
            .into_par_iter()
            .filter(|&i| usable(i))
            .map(|i| camera.plane_box(positions[i], radius_of(i)))
            .reduce_with(|a, b| {
                [
                    a[0].min(b[0]),
                    a[1].min(b[1]),
                    a[2].max(b[2]),
                    a[3].max(b[3]),
                ]
            })?;
        let (w, h) = (extent[2] - extent[0], extent[3] - extent[1]);
        let fill = 1.0 - 2.0 * MARGIN;
        let scale_w = viewport.width * fill / w;
        let scale_h = viewport.height * fill / h;
        // A flat or single-point scene has a zero extent on one or both axes.
        let scale = match (w > 0.0, h > 0.0) {
            (true, true) => scale_w.min(scale_h),
            (true, false) => scale_w,
            (false, true) => scale_h,
            (false, false) => 1.0,
        };
        camera.scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            1.0
        };
        camera.plane_centre = [0.5 * (extent[0] + extent[2]), 0.5 * (extent[1] + extent[3])];
        Some(camera)
    }

    /// The image-plane box (min a, min b, max a, max b) of a ball, before scaling.
    fn plane_box(&self, p: DVec3, radius: f64) -> [f64; 4] {
        let (a, b, w) = self.plane(p);
        let r = match self.projection {
            Projection::Orthographic => radius,
            Projection::Perspective { .. } => radius / w.max(f64::MIN_POSITIVE),
        };
        [a - r, b - r, a + r, b + r]
    }

    /// Image-plane coordinates and distance of a point.
    #[inline]
    fn plane(&self, p: DVec3) -> (f64, f64, f64) {
        let d = p - self.origin;
        let (a, b) = (d.dot(self.right), d.dot(self.up));
        let distance = -d.dot(self.toward_viewer);
        match self.projection {
            Projection::Orthographic => (a, b, distance),
            Projection::Perspective { .. } => (a / distance, b / distance, distance),
        }
    }

    /// Where a point lands in the image.
    #[inline]
    pub fn project(&self, p: DVec3) -> Projected {
        let (a, b, distance) = self.plane(p);
        Projected {
            x: self.pixel_centre[0] + (a - self.plane_centre[0]) * self.scale,
            y: self.pixel_centre[1] - (b - self.plane_centre[1]) * self.scale,
            distance,
        }
    }

    /// Pixels per world unit at a given distance.
    #[inline]
    pub fn pixels_per_unit(&self, distance: f64) -> f64 {
        match self.projection {
            Projection::Orthographic => self.scale,
            Projection::Perspective { .. } => self.scale / distance,
        }
    }

    /// The depth-test key of a distance: smaller is nearer, and affine in image
    /// coordinates over a planar triangle (the distance itself for orthographic views, its
    /// negated reciprocal for perspective ones), so it can be interpolated linearly.
    #[inline]
    pub fn depth_key(&self, distance: f64) -> f64 {
        match self.projection {
            Projection::Orthographic => distance,
            Projection::Perspective { .. } => -1.0 / distance,
        }
    }

    /// True for a perspective camera (attributes then need perspective-correct weights).
    pub fn is_perspective(&self) -> bool {
        matches!(self.projection, Projection::Perspective { .. })
    }

    /// True when the point lies in front of the camera (always, for orthographic views).
    #[inline]
    pub fn in_front(&self, distance: f64) -> bool {
        match self.projection {
            Projection::Orthographic => true,
            Projection::Perspective { .. } => distance > 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const VIEWPORT: Viewport = Viewport {
        x: 0.0,
        y: 0.0,
        width: 400.0,
        height: 300.0,
    };

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-12
    }

    #[test]
    fn named_views_look_along_the_axes() {
        let frame = |name: &str, up: UpAxis| view_frame(ViewAngles::parse(name).unwrap(), up);
        let (t, r, u) = frame("front", UpAxis::Y);
        assert!(close(t, DVec3::Z) && close(r, DVec3::X) && close(u, DVec3::Y));
        let (t, r, u) = frame("right", UpAxis::Y);
        assert!(close(t, DVec3::X) && close(r, DVec3::NEG_Z) && close(u, DVec3::Y));
        let (t, _, u) = frame("top", UpAxis::Y);
        assert!(close(t, DVec3::Y) && close(u, DVec3::NEG_Z));
        let (t, r, u) = frame("front", UpAxis::Z);
        assert!(close(t, DVec3::NEG_Y) && close(r, DVec3::X) && close(u, DVec3::Z));
        let (t, _, _) = frame("iso", UpAxis::Z);
        assert!(close(t, DVec3::new(1.0, -1.0, 1.0).normalize()));
    }

    #[test]
    fn bad_views_are_refused() {
        for bad in ["", "side", "10", "10,", "a,b", "0,91", "nan,0", "1,2,3"] {
            assert!(ViewAngles::parse(bad).is_err(), "{bad}");
        }
        assert_eq!(
            ViewAngles::parse(" -30, 20").unwrap(),
            ViewAngles {
                azimuth: -30.0,
                elevation: 20.0
            }
        );
    }

    proptest! {
        /// The view frame is orthonormal and right-handed for every direction.
        #[test]
        fn view_frame_is_orthonormal(az in -720.0..720.0f64, el in -90.0..=90.0f64, up in 0..3usize) {
            let up = [UpAxis::X, UpAxis::Y, UpAxis::Z][up];
            let (t, r, u) = view_frame(ViewAngles { azimuth: az, elevation: el }, up);
            for v in [t, r, u] {
                prop_assert!((v.length() - 1.0).abs() < 1e-12);
            }
            prop_assert!(t.dot(r).abs() < 1e-12 && t.dot(u).abs() < 1e-12 && r.dot(u).abs() < 1e-12);
            prop_assert!(close(r.cross(u), t));
        }

        /// Every fitted point lands inside the viewport shrunk by the margin, and the fit is
        /// tight on at least one axis.
        #[test]
        fn fitted_points_fill_the_viewport(
            points in prop::collection::vec(prop::array::uniform3(-1e3..1e3f64), 2..40),
            az in -180.0..180.0f64, el in -90.0..=90.0f64, perspective in any::<bool>(),
        ) {
            let positions: Vec<DVec3> = points.iter().map(|p| DVec3::from_array(*p)).collect();
            let projection = if perspective {
                Projection::Perspective { fov_deg: 40.0 }
            } else {
                Projection::Orthographic
            };
            let angles = ViewAngles { azimuth: az, elevation: el };
            let camera =
                Camera::fit(&positions, None, angles, UpAxis::Z, projection, VIEWPORT).unwrap();
            let tol = 1e-6 * VIEWPORT.width;
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for &p in &positions {
                let q = camera.project(p);
                prop_assert!(camera.in_front(q.distance));
                lo = [lo[0].min(q.x), lo[1].min(q.y)];
                hi = [hi[0].max(q.x), hi[1].max(q.y)];
            }
            let m = [MARGIN * VIEWPORT.width, MARGIN * VIEWPORT.height];
            prop_assert!(lo[0] >= m[0] - tol && lo[1] >= m[1] - tol);
            prop_assert!(hi[0] <= VIEWPORT.width - m[0] + tol);
            prop_assert!(hi[1] <= VIEWPORT.height - m[1] + tol);
            let spans = [hi[0] - lo[0], hi[1] - lo[1]];
            let full = [VIEWPORT.width - 2.0 * m[0], VIEWPORT.height - 2.0 * m[1]];
            if spans[0] > 0.0 || spans[1] > 0.0 {
                prop_assert!((spans[0] - full[0]).abs() < tol || (spans[1] - full[1]).abs() < tol);
            }
        }
    }

    #[test]
    fn a_single_point_is_centred() {
        let camera = Camera::fit(
            &[DVec3::new(3.0, 4.0, 5.0), DVec3::NAN],
            None,
            ViewAngles::parse("iso").unwrap(),
            UpAxis::Y,
            Projection::Orthographic,
            VIEWPORT,
        )
        .unwrap();
        let q = camera.project(DVec3::new(3.0, 4.0, 5.0));
        assert!((q.x - 200.0).abs() < 1e-9 && (q.y - 150.0).abs() < 1e-9);
        assert!(
            Camera::fit(
                &[DVec3::NAN],
                None,
                ViewAngles::parse("iso").unwrap(),
                UpAxis::Y,
                Projection::Orthographic,
                VIEWPORT
            )
            .is_none()
        );
    }
}
