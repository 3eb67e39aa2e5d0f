//! `reconstruct` on tiny point sets decoded from the bytes: up to 48 points on a signed
//! 8-bit lattice scaled by a power of two from 2^-128 to 2^127 (hostile magnitudes), with or
//! without normals (which may be zero or unnormalised), every method, trimming on or off.
//! It must return a mesh or a typed error.

#![no_main]

use glam::DVec3;
use libfuzzer_sys::fuzz_target;
use sphcover_core::PointCloud;
use sphcover_recon::{Method, ReconParams, Trim, reconstruct};

/// Bytes per point: position, then normal.
const POINT_BYTES: usize = 6;
/// Few enough that one run takes milliseconds.
const MAX_POINTS: usize = 48;

fuzz_target!(|bytes: &[u8]| {
    let Some((&[flags, exponent], rest)) = bytes.split_first_chunk::<2>() else {
        return;
    };
    let scale = 2f64.powi(i32::from(exponent as i8));
    let lattice = |b: &[u8]| DVec3::new(f64::from(b[0] as i8), f64::from(b[1] as i8), f64::from(b[2] as i8));
    let chunks: Vec<&[u8]> = rest.chunks_exact(POINT_BYTES).take(MAX_POINTS).collect();
    let positions = chunks.iter().map(|c| lattice(&c[..3]) * scale).collect();
    let normals = (flags & 1 == 1).then(|| chunks.iter().map(|c| lattice(&c[3..])).collect());
    let cloud = PointCloud {
        positions,
        normals,
        confidence: None,
        values: None,
    };
    let params = ReconParams {
        method: match (flags >> 1) & 3 {
            0 => Method::Integrated,
            1 => Method::Diffusion,
            2 => Method::PartitionOfUnity,
            _ => Method::GraphCut,
        },
        depth: Some(4),
        trim: if flags & 8 != 0 {
            Trim::SampleSpacings(3.0)
        } else {
            Trim::Off
        },
        ..ReconParams::default()
    };
    if let Ok(recon) = reconstruct(&cloud, &params, &|_| {}) {
        let n = recon.mesh.vertices.len();
        assert!(recon.mesh.vertices.iter().all(|v| v.is_finite()));
        assert!(recon.mesh.triangles.iter().flatten().all(|&i| (i as usize) < n));
    }
});
