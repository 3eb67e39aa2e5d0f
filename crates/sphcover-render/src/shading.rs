//! Lighting: two-sided Lambert under one light above and left of the camera, plus ambient
//! light so that surfaces edge-on to the light stay visible. Two-sided, because scans and
//! reconstructions often have inconsistently oriented normals, and a preview must show the
//! shape whatever the orientation.

use glam::DVec3;
use rayon::prelude::*;

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

/// Area-weighted vertex normals of a triangle mesh (unit; zero for a vertex of no triangle
/// with area), for smooth shading of a mesh that comes without normals.
///
/// The same arithmetic as `sphcover_core::vertex_normals`, repeated here so that a program
/// that only draws does not need the core's file formats, solvers and their dependencies.
pub(crate) fn vertex_normals(positions: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let faces: Vec<DVec3> = triangles
        .par_iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            let f = (b - a).cross(c - a);
            if f.is_finite() { f } else { DVec3::ZERO }
        })
        .collect();
    // Each thread sums into its own range of vertices, walking all triangles in order: every
    // vertex adds its triangles' normals in triangle order, whatever the thread count.
    let mut sums = vec![DVec3::ZERO; positions.len()];
    let part_len = positions
        .len()
        .div_ceil(rayon::current_num_threads().max(1))
        .max(1);
    sums.par_chunks_mut(part_len)
        .enumerate()
        .for_each(|(part, sums)| {
            let lo = part * part_len;
            for (t, f) in triangles.iter().zip(&faces) {
                for &v in t {
                    if let Some(sum) = (v as usize).checked_sub(lo).and_then(|i| sums.get_mut(i)) {
                        *sum += *f;
                    }
                }
            }
            for sum in sums.iter_mut() {
                *sum = sum.normalize_or_zero();
            }
        });
    sums
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A unit cube of twelve outward-wound triangles.
    fn cube() -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let positions = (0..8)
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
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        (positions, triangles)
    }

    #[test]
    fn vertex_normals_of_a_closed_box_point_outward() {
        let (positions, triangles) = cube();
        let normals = vertex_normals(&positions, &triangles);
        for (p, n) in positions.iter().zip(&normals) {
            let outward = (*p - DVec3::splat(0.5)).normalize();
            assert!(n.dot(outward) > 0.9, "{p} {n}");
        }
    }

    #[test]
    fn vertex_normals_do_not_depend_on_the_thread_count() {
        let (mut positions, triangles) = cube();
        // A vertex of no triangle gets a zero normal.
        positions.push(DVec3::splat(7.0));
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| vertex_normals(&positions, &triangles))
        };
        let one = run(1);
        assert_eq!(one[8], DVec3::ZERO);
        for threads in [2, 3, 5] {
            assert_eq!(run(threads), one);
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
