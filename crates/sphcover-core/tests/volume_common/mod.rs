//! Synthetic CT phantoms shared by the volume tests and the volume-cover benchmark.
#![allow(dead_code)]

use sphcover_core::synthetic::voxel_subsamples;
use sphcover_core::{DVec3, Volume, VoxelValues};

/// Hounsfield value of air.
pub const AIR: f64 = -1000.0;
/// Hounsfield value of the plate material.
pub const MATERIAL: f64 = 2000.0;

/// Whether `x` lies in the open ball of centre `c` and radius `r` — a support, whose weight
/// vanishes on its sphere. Points on the sphere up to rounding (a relative 1e-9) are out, as
/// the cover builders count them.
pub fn in_open_ball(x: DVec3, c: DVec3, r: f64) -> bool {
    x.distance(c) < r * (1.0 - 1e-9)
}

/// A tilted plate of `thickness` voxels through the middle of a `dims` grid, in Hounsfield units (air −1000, material +2000): partial volume from 4×4×4
/// supersampling of each voxel, then a separable Gaussian blur of `blur` voxels (the scanner's
/// point spread; 0 for none). The plate normal is tilted by `tilt_degrees` from the z axis,
/// towards the direction 30° from the x axis, so no face is aligned with the grid.
pub fn thin_plate(dims: [usize; 3], thickness: f64, tilt_degrees: f64, blur: f64) -> Vec<f64> {
    let [nx, ny, nz] = dims;
    let (t, p) = (tilt_degrees.to_radians(), 30f64.to_radians());
    let normal = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
    let mid = 0.5 * DVec3::new(nx as f64 - 1.0, ny as f64 - 1.0, nz as f64 - 1.0);
    let mut values = vec![0.0; nx * ny * nz];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let voxel = DVec3::new(i as f64, j as f64, k as f64);
                let inside = voxel_subsamples()
                    .filter(|&sub| (voxel + sub - mid).dot(normal).abs() <= 0.5 * thickness)
                    .count();
                let frac = inside as f64 / 64.0;
                values[i + nx * (j + ny * k)] = AIR + frac * (MATERIAL - AIR);
            }
        }
    }
    if blur > 0.0 {
        gaussian_blur(&mut values, dims, blur);
    }
    values
}

/// Separable Gaussian blur with clamped borders.
fn gaussian_blur(values: &mut [f64], dims: [usize; 3], sigma: f64) {
    let radius = (3.0 * sigma).ceil() as i64;
    let weights: Vec<f64> = (-radius..=radius)
        .map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f64 = weights.iter().sum();
    let strides = [1, dims[0], dims[0] * dims[1]];
    for axis in 0..3 {
        let src = values.to_vec();
        let n = dims[axis] as i64;
        for idx in 0..values.len() {
            let c = (idx / strides[axis]) as i64 % n;
            let mut acc = 0.0;
            for (w, d) in weights.iter().zip(-radius..=radius) {
                let q = (c + d).clamp(0, n - 1);
                acc += w * src[(idx as i64 + (q - c) * strides[axis] as i64) as usize];
            }
            values[idx] = acc / total;
        }
    }
}

/// The default test phantom: 40×40×24 voxels of 0.1 mm, a plate 4 voxels thick tilted by
/// 20°, PSF blur 0.8 voxel, stored as `int16`-like `f32` Hounsfield units.
pub fn test_phantom() -> Volume {
    let dims = [40, 40, 24];
    let values = thin_plate(dims, 4.0, 20.0, 0.8);
    Volume::axis_aligned(
        dims,
        VoxelValues::F32(values.iter().map(|&v| v.round() as f32).collect()),
        DVec3::splat(0.1),
        DVec3::new(-2.0, 1.0, 0.5),
    )
    .expect("valid phantom")
}
