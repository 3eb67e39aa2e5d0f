//! Axis-aligned boxes and the bounding-box normalisation of thesis §3.4.1.

use glam::DVec3;

/// An axis-aligned bounding box. An empty box has `min > max` on every axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Smallest coordinate on each axis.
    pub min: DVec3,
    /// Largest coordinate on each axis.
    pub max: DVec3,
}

impl Aabb {
    /// The empty box: adding any point makes it that point.
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// The box of the finite points among `points` (non-finite points are skipped).
    pub fn from_points(points: &[DVec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |mut b, &p| {
            if p.is_finite() {
                b.add(p);
            }
            b
        })
    }

    /// Grows the box to hold `p`.
    pub fn add(&mut self, p: DVec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// True when the box holds no point.
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// Edge lengths (zero vector for an empty box).
    pub fn extent(&self) -> DVec3 {
        if self.is_empty() {
            DVec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// Centre of the box (origin for an empty box).
    pub fn centre(&self) -> DVec3 {
        if self.is_empty() {
            DVec3::ZERO
        } else {
            0.5 * (self.min + self.max)
        }
    }

    /// Length of the diagonal.
    pub fn diagonal(&self) -> f64 {
        self.extent().length()
    }

    /// Length of the longest edge.
    pub fn longest_edge(&self) -> f64 {
        self.extent().max_element()
    }

    /// True when `p` lies in the closed box.
    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}

/// The similarity that maps input coordinates into the unit frame of thesis §3.4.1: translate
/// the bounding-box centre to the origin and scale so the longest box edge is 1.
///
/// Every length parameter of the surface pipeline is given in the unit frame; outputs are
/// mapped back with [`Normalisation::to_input`]. Directions (normals) are unchanged because
/// the scale is uniform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normalisation {
    /// Centre of the input bounding box, in input coordinates.
    pub centre: DVec3,
    /// Longest edge of the input bounding box: one unit-frame length in input units.
    pub scale: f64,
}

impl Normalisation {
    /// The identity map.
    pub const IDENTITY: Normalisation = Normalisation {
        centre: DVec3::ZERO,
        scale: 1.0,
    };

    /// The normalisation of a box. A box with no extent (one point, or all points equal)
    /// keeps scale 1 so the map stays invertible; `None` for an empty box or a box whose
    /// extent is not finite.
    pub fn of_box(bbox: &Aabb) -> Option<Normalisation> {
        if bbox.is_empty() {
            return None;
        }
        let edge = bbox.longest_edge();
        let centre = bbox.centre();
        if !edge.is_finite() || !centre.is_finite() {
            return None;
        }
        let scale = if edge > 0.0 { edge } else { 1.0 };
        Some(Normalisation { centre, scale })
    }

    /// The normalisation of the bounding box of `points`.
    pub fn of_points(points: &[DVec3]) -> Option<Normalisation> {
        Normalisation::of_box(&Aabb::from_points(points))
    }

    /// Input coordinates → unit frame.
    #[inline]
    pub fn to_unit(&self, p: DVec3) -> DVec3 {
        (p - self.centre) / self.scale
    }

    /// Unit frame → input coordinates.
    #[inline]
    pub fn to_input(&self, p: DVec3) -> DVec3 {
        p * self.scale + self.centre
    }

    /// A length in the unit frame → input units.
    #[inline]
    pub fn length_to_input(&self, l: f64) -> f64 {
        l * self.scale
    }

    /// A length in input units → the unit frame.
    #[inline]
    pub fn length_to_unit(&self, l: f64) -> f64 {
        l / self.scale
    }

    /// Maps every point into the unit frame in place.
    pub fn points_to_unit(&self, points: &mut [DVec3]) {
        points.iter_mut().for_each(|p| *p = self.to_unit(*p));
    }

    /// Maps every point back to input coordinates in place.
    pub fn points_to_input(&self, points: &mut [DVec3]) {
        points.iter_mut().for_each(|p| *p = self.to_input(*p));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_frame_has_longest_edge_one_and_inverts() {
        let pts = [DVec3::new(1.0, 2.0, 3.0), DVec3::new(5.0, 3.0, 4.0)];
        let n = Normalisation::of_points(&pts).unwrap();
        let mut unit = pts;
        n.points_to_unit(&mut unit);
        let b = Aabb::from_points(&unit);
        assert!((b.longest_edge() - 1.0).abs() < 1e-15);
        assert!(b.centre().length() < 1e-15);
        n.points_to_input(&mut unit);
        for (a, b) in unit.iter().zip(pts.iter()) {
            assert!((*a - *b).length() < 1e-14);
        }
    }

    #[test]
    fn degenerate_boxes() {
        assert!(Normalisation::of_points(&[]).is_none());
        let one = Normalisation::of_points(&[DVec3::ONE]).unwrap();
        assert_eq!(one.scale, 1.0);
        assert_eq!(one.to_unit(DVec3::ONE), DVec3::ZERO);
        assert!(Normalisation::of_points(&[DVec3::ZERO, DVec3::splat(f64::MAX)]).is_some());
        assert!(
            Normalisation::of_points(&[DVec3::splat(-f64::MAX), DVec3::splat(f64::MAX)]).is_none()
        );
    }
}
