//! `extract_skeleton` on tiny volumes decoded from the bytes: dimensions 1..=12 per axis, a
//! voxel size from 2^-8 to 2^7, then one byte per voxel (repeated cyclically when the input
//! is short). It must return a mesh or a typed error.

#![no_main]

use glam::{DAffine3, DVec3};
use libfuzzer_sys::fuzz_target;
use sphcover_core::{Volume, VoxelValues};
use sphcover_skeleton::{SkeletonParams, extract_skeleton};

/// Small enough that one run takes milliseconds.
const MAX_DIM: u8 = 12;

fuzz_target!(|bytes: &[u8]| {
    let Some((&[nx, ny, nz, size], samples)) = bytes.split_first_chunk::<4>() else {
        return;
    };
    if samples.is_empty() {
        return;
    }
    let dims = [nx, ny, nz].map(|d| usize::from(d % MAX_DIM) + 1);
    let voxel = 2f64.powi(i32::from(size % 16) - 8);
    let count = dims.iter().product::<usize>();
    let values = (0..count)
        .map(|i| f32::from(samples[i % samples.len()]))
        .collect();
    let Ok(volume) = Volume::new(
        dims,
        VoxelValues::F32(values),
        DAffine3::from_scale(DVec3::splat(voxel)),
    ) else {
        return;
    };
    if let Ok((mesh, _stats)) = extract_skeleton(&volume, &SkeletonParams::default()) {
        let n = mesh.vertices.len();
        assert!(mesh.vertices.iter().all(|v| v.is_finite()));
        assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < n));
    }
});
