//! Lighting: two-sided Lambert under one light above and left of the camera, plus ambient
//! light so that surfaces edge-on to the light stay visible. Two-sided, because scans and
//! reconstructions often have inconsistently oriented normals, and a preview must show the
//! shape whatever the orientation.

use glam::DVec3;
use rayon::prelude::*;

/// Light reaching every surface whatever its orientation.
pub const AMBIENT: f64 = 0.18;
/// Weight of the directional light.
pub const DIFFUSE: f64 = 0.82;

/// The light direction (unit, towards the light) for a camera frame.
pub fn light_direction(toward_viewer: DVec3, right: DVec3, up: DVec3) -> DVec3 {
    (toward_viewer + 0.55 * up - 0.35 * right).normalize()
}

/// Brightness of a surface with unit normal `n` (either orientation).
#[inline]
pub fn lambert(n: DVec3, light: DVec3) -> f64 {
    AMBIENT + DIFFUSE * n.dot(light).abs()
}

/// Area-weighted vertex normals of a triangle mesh (unit; zero for a vertex of no
/// triangle with area).
pub fn vertex_normals(positions: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let faces: Vec<DVec3> = triangles
        .par_iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            let f = (b - a).cross(c - a);
            if f.is_finite() { f } else { DVec3::ZERO }
        })
        .collect();
    // One pass in triangle order: the sums are the same whatever the thread count.
    let mut sums = vec![DVec3::ZERO; positions.len()];
    for (t, f) in triangles.iter().zip(&faces) {
        for &v in t {
            sums[v as usize] += *f;
        }
    }
    sums.par_iter_mut().for_each(|s| *s = s.normalize_or_zero());
    sums
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn vertex_normals_of_a_closed_box_point_outward() {
        // A unit cube of twelve outward-wound triangles.
        let positions: Vec<DVec3> = (0..8)
            .map(|i| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let triangles: Vec<[u32; 3]> = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        let normals = vertex_normals(&positions, &triangles);
        for (p, n) in positions.iter().zip(&normals) {
            let outward = (*p - DVec3::splat(0.5)).normalize();
            assert!(n.dot(outward) > 0.9, "{p} {n}");
        }
    }

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
