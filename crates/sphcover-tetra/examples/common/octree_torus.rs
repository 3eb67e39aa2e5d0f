//! An adaptive octree cover of a torus, shared by the example and the benchmark.
//!
//! Octree cells of the unit cube are refined while the surface may cross them (distance below half the diagonal) (major
//! radius 0.3, tube radius 0.1, centred in the cube); each leaf gets a support at its centre
//! with radius 0.75 × its diagonal (the thesis's volume covers). Centres of equal cells are
//! co-spherical, so the set is full of ties.

use sphcover_core::DVec3;

/// Distance from `p` to the torus surface.
fn torus_distance(p: DVec3) -> f64 {
    let q = p - DVec3::splat(0.5);
    let ring = (q.x * q.x + q.y * q.y).sqrt() - 0.3;
    (ring * ring + q.z * q.z).sqrt() - 0.1
}

/// Leaves of the octree refined to `max_depth` near the torus: centres and radii.
pub fn octree_torus_cover(max_depth: u32) -> (Vec<DVec3>, Vec<f64>) {
    let mut centers = Vec::new();
    let mut radii = Vec::new();
    let mut stack = vec![(DVec3::splat(0.5), 0.5f64, 0u32)];
    while let Some((c, half, depth)) = stack.pop() {
        let diag = 2.0 * half * 3f64.sqrt();
        if depth < max_depth && torus_distance(c).abs() < 0.5 * diag {
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
            centers.push(c);
            radii.push(0.75 * diag);
        }
    }
    (centers, radii)
}

/// The smallest depth whose cover has at least `n` supports (capped at 12), and the cover.
pub fn octree_torus_cover_of_size(n: usize) -> (u32, Vec<DVec3>, Vec<f64>) {
    let mut depth = 3;
    loop {
        let (c, r) = octree_torus_cover(depth);
        if c.len() >= n || depth >= 12 {
            return (depth, c, r);
        }
        depth += 1;
    }
}
