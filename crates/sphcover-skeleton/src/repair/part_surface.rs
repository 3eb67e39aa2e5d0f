//! The part's surface as the repairs probe it: material where the cover's function exceeds
//! the threshold's level, and the distance to the part's faces along a direction, found by
//! marching.

use glam::DVec3;
use sphcover_core::PuEvaluator;

/// The part around a sheet: the intensity cover's function, the level of the part's surface
/// and how far its faces are searched.
#[derive(Clone, Copy, Debug)]
pub struct PartSurface<'a> {
    /// The cover's function (σ = 1).
    pub function: &'a PuEvaluator<'a>,
    /// Material is where the function exceeds this level.
    pub level: f64,
    /// Largest half-thickness of the part searched (world units): the cover's largest
    /// support radius, since thicker parts have no sheet the cover could carry.
    pub max_half_thickness: f64,
}

impl PartSurface<'_> {
    /// Whether there is material at `x`.
    pub fn is_material(&self, x: DVec3) -> bool {
        self.function.value(x).is_some_and(|v| v > self.level)
    }

    /// Whether the function is undefined at `x` or falls below the surface level there.
    pub(crate) fn is_outside(&self, x: DVec3) -> bool {
        self.function.value(x).is_none_or(|f| f < self.level)
    }

    /// The distance from `p` along the unit direction `d` to the first point where the
    /// function falls below the surface level, marching in steps of `step` (world units) and
    /// interpolating linearly between them; `None` when the function is undefined at `p` or
    /// does not fall below the level within the largest half-thickness.
    pub fn surface_distance(&self, p: DVec3, d: DVec3, step: f64) -> Option<f64> {
        let level = self.level;
        let mut prev = (0.0, self.function.value(p)?);
        let mut s = step;
        while s <= self.max_half_thickness + step {
            let v = self.function.value(p + s * d).unwrap_or(f64::NEG_INFINITY);
            if v < level {
                let denom = prev.1 - v;
                let frac = if denom.is_finite() && denom > 0.0 {
                    (prev.1 - level) / denom
                } else {
                    0.5
                };
                return Some(prev.0 + frac.clamp(0.0, 1.0) * (s - prev.0));
            }
            prev = (s, v);
            s += step;
        }
        None
    }

    /// The half-thickness of the part at `p` along `±e`: the mean of the surface distances
    /// ([`PartSurface::surface_distance`]) on both sides.
    pub fn half_thickness(&self, p: DVec3, e: DVec3, step: f64) -> Option<f64> {
        let a = self.surface_distance(p, e, step)?;
        let b = self.surface_distance(p, -e, step)?;
        Some(0.5 * (a + b))
    }
}
