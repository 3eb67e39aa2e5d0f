//! Shared helpers of the integration tests.
#![allow(dead_code)]

use sphcover_tetra::spatial_sort::SplitMix64;

/// Uniform random points in the unit cube with weights in `[0, wmax)`.
pub fn random_points(n: usize, wmax: f64, seed: u64) -> (Vec<[f64; 3]>, Vec<f64>) {
    let mut rng = SplitMix64::new(seed);
    let mut u = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let pts: Vec<[f64; 3]> = (0..n).map(|_| [u(), u(), u()]).collect();
    let w: Vec<f64> = (0..n).map(|_| u() * wmax).collect();
    (pts, w)
}

/// Points of an `n³` integer grid (scaled by `h`), all weights `w`.
pub fn grid(n: usize, h: f64, w: f64) -> (Vec<[f64; 3]>, Vec<f64>) {
    let mut pts = Vec::new();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                pts.push([i as f64 * h, j as f64 * h, k as f64 * h]);
            }
        }
    }
    let ws = vec![w; pts.len()];
    (pts, ws)
}
