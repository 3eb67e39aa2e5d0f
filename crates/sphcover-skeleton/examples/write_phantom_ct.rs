//! Writes a CT phantom of any size as a NIfTI-1 file (float32, axis-aligned), for measuring
//! `sphcover skeleton` on volumes of growing size (`docs/benchmarks.md`, *Memory*): the curved
//! plate of the fixtures generator (thickness 4 voxels, PSF 0.8 voxel) scaled to span an N³
//! grid, 10 % noise, padded with noisy air, as in the `bench_160` example.
//!
//! `cargo run --release -p sphcover-skeleton --example write_phantom_ct -- N OUT.nii`
use sphcover_core::random::XorShift64;
use sphcover_evaluation::thin_phantoms::{
    AIR_HU, MATERIAL_HU, PhantomParams, ThinShape, thin_phantom,
};

fn main() {
    let mut args = std::env::args().skip(1);
    let (Some(n), Some(out)) = (
        args.next().and_then(|a| a.parse::<usize>().ok()),
        args.next(),
    ) else {
        eprintln!("usage: write_phantom_ct N OUT.nii");
        std::process::exit(2);
    };
    let noise = 0.1;
    let params = PhantomParams {
        noise,
        scale: n as f64 / 48.0,
        seed: 5,
        ..PhantomParams::default()
    };
    let phantom = thin_phantom(ThinShape::CurvedPlate, &params);
    let [nx, ny, nz] = phantom.volume.dims();
    assert!(
        nx <= n && ny <= n && nz <= n,
        "the phantom ({nx}×{ny}×{nz}) exceeds {n}³"
    );
    // Noisy air around the phantom (xorshift + Box–Muller, seeded).
    let mut rng = XorShift64::new(0x9e37_79b9_7f4a_7c15u64);
    let mut uniform = move || rng.uniform();
    let dz = (n - nz) / 2;
    let voxel = params.voxel as f32;
    // NIfTI-1 header: 348 bytes, 4 bytes of extension flags, data at 352.
    let mut bytes = vec![0u8; 352];
    bytes[0..4].copy_from_slice(&348i32.to_le_bytes());
    let dim = [3i16, n as i16, n as i16, n as i16, 1, 1, 1, 1];
    for (k, d) in dim.iter().enumerate() {
        bytes[40 + 2 * k..42 + 2 * k].copy_from_slice(&d.to_le_bytes());
    }
    bytes[70..72].copy_from_slice(&16i16.to_le_bytes()); // float32
    bytes[72..74].copy_from_slice(&32i16.to_le_bytes());
    let pixdim = [1.0f32, voxel, voxel, voxel, 1.0, 1.0, 1.0, 1.0];
    for (k, p) in pixdim.iter().enumerate() {
        bytes[76 + 4 * k..80 + 4 * k].copy_from_slice(&p.to_le_bytes());
    }
    bytes[108..112].copy_from_slice(&352f32.to_le_bytes());
    bytes[344..348].copy_from_slice(b"n+1\0");
    bytes.reserve(4 * n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let v = if i < nx && j < ny && k >= dz && k < dz + nz {
                    phantom.volume.value(phantom.volume.index(i, j, k - dz))
                } else {
                    let (u1, u2) = (1.0 - uniform(), uniform());
                    let g = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                    AIR_HU + noise * (MATERIAL_HU - AIR_HU) * g
                };
                bytes.extend_from_slice(&(v as f32).to_le_bytes());
            }
        }
    }
    std::fs::write(&out, bytes).unwrap_or_else(|e| panic!("writing {out}: {e}"));
    eprintln!("{out}: {n}³ voxels, curved plate {nx}×{ny}×{nz}");
}
