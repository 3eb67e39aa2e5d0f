//! An adaptive octree cover of a torus, shared by the example, the criterion benchmark and
//! `tetra-bench` (each includes this file).
//!
//! Octree cells of the unit cube are refined while the surface may cross them (distance below half the diagonal) (major
//! radius 0.3, tube radius 0.1, centred in the cube); each leaf gets a support at its centre
//! with radius 0.75 × its diagonal (the thesis's volume covers). Centres of equal cells are
//! co-spherical, so the set is full of ties.

use sphcover_core::DVec3;
use sphcover_core::synthetic::Surface;

const TORUS: Surface = Surface::Torus {
    centre: DVec3::splat(0.5),
    major_radius: 0.3,
    minor_radius: 0.1,
};

/// Leaves of the octree refined to `max_depth` where the surface is closer than `band` times
/// the cell diagonal (`band ≥ 0.5` refines every cell the surface may cross; larger values
/// grade the cell sizes more smoothly): centres and radii.
pub fn octree_torus_cover(max_depth: u32, band: f64) -> (Vec<DVec3>, Vec<f64>) {
    let mut centres = Vec::new();
    let mut radii = Vec::new();
    let mut stack = vec![(DVec3::splat(0.5), 0.5f64, 0u32)];
    while let Some((c, half, depth)) = stack.pop() {
        let diag = 2.0 * half * 3f64.sqrt();
        if depth < max_depth && TORUS.signed_distance(c).abs() < band * diag {
            let h = half / 2.0;
            for i in 0..8 {
                let o = DVec3::new(
                    if i & 1 == 0 { -h } else { h },
                    if i & 2 == 0 { -h } else { h },
                    if i & 4 == 0 { -h } else { h },
                );
                stack.push((c + o, h, depth + 1));
            }
        } else if depth >= 2 {
            centres.push(c);
            radii.push(0.75 * diag);
        }
    }
    (centres, radii)
}

/// A cover with about `n` supports (within a few percent, for `n` ≥ 10⁴): the deepest
/// octree whose cover with `band = 1` stays below `n`, then `band` raised by bisection (in
/// `[1, 4]`: smoothly graded cell sizes, as in the thesis's covers). Returns the depth, the
/// band, the centres and the radii.
pub fn octree_torus_cover_of_size(n: usize) -> (u32, f64, Vec<DVec3>, Vec<f64>) {
    let mut depth = 3;
    while depth < 12 && octree_torus_cover(depth + 1, 1.0).0.len() <= n {
        depth += 1;
    }
    let (mut lo, mut hi) = (1.0, 4.0);
    for _ in 0..12 {
        let mid = 0.5 * (lo + hi);
        if octree_torus_cover(depth, mid).0.len() < n {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let (c, r) = octree_torus_cover(depth, hi);
    (depth, hi, c, r)
}
