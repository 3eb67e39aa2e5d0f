//! Lighting: two-sided Lambert under one light above and left of the camera, plus ambient
//! light so that surfaces edge-on to the light stay visible. Two-sided, because scans and
//! reconstructions often have inconsistently oriented normals, and a preview must show the
//! shape whatever the orientation.

use glam::DVec3;

/// Light reaching every surface whatever its orientation.
pub(crate) const AMBIENT: f64 = 0.18;
/// Weight of the directional light.
pub(crate) const DIFFUSE: f64 = 0.82;

/// The light direction (unit, towards the light) for a camera frame.
pub(crate) fn light_direction(toward_viewer: DVec3, right: DVec3, up: DVec3) -> DVec3 {
    (toward_viewer + 0.55 * up - 0.35 * right).normalize()
}

/// Brightness of a surface with unit normal `n` (either orientation).
#[inline]
pub(crate) fn lambert(n: DVec3, light: DVec3) -> f64 {
    AMBIENT + DIFFUSE * n.dot(light).abs()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Two-sided: a normal and its opposite are lit alike, within [AMBIENT, 1].
        #[test]
        fn lambert_is_two_sided(n in prop::array::uniform3(-1.0..1.0f64), az in -3.0..3.0f64) {
            let n = DVec3::from_array(n);
            prop_assume!(n.length() > 1e-3);
            let n = n.normalize();
            let light = light_direction(DVec3::Z, DVec3::new(az.cos(), az.sin(), 0.0), DVec3::new(-az.sin(), az.cos(), 0.0));
            let (a, b) = (lambert(n, light), lambert(-n, light));
            prop_assert_eq!(a, b);
            prop_assert!((AMBIENT..=1.0 + 1e-12).contains(&a));
        }
    }
}
