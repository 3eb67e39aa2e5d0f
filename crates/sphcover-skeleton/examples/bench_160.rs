//! Times the skeleton pipeline on a 160³ CT phantom: the curved plate of the fixtures
//! generator scaled to span the grid, 10 % noise, embedded in a 160³ grid of air with the
//! same noise.
//!
//! `cargo run --release -p sphcover-skeleton --example bench_160`
use sphcover_core::random::XorShift64;
use sphcover_core::{DVec3, Volume, VoxelValues};
use sphcover_evaluation::sheet_metrics::score_mesh;
use sphcover_evaluation::thin_phantoms::{
    AIR_HU, MATERIAL_HU, PhantomParams, ThinShape, thin_phantom,
};
use sphcover_skeleton::{SkeletonParams, extract_skeleton};

const N: usize = 160;

fn main() {
    let noise = 0.1;
    let params = PhantomParams {
        noise,
        scale: N as f64 / 48.0,
        seed: 5,
        ..PhantomParams::default()
    };
    let shape = std::env::args()
        .nth(1)
        .and_then(|name| ThinShape::ALL.into_iter().find(|s| s.name() == name))
        .unwrap_or(ThinShape::CurvedPlate);
    let phantom = thin_phantom(shape, &params);
    let [nx, ny, nz] = phantom.volume.dims();
    // Embed in N³, centred in z, padding with noisy air (xorshift + Box–Muller, seeded).
    let mut rng = XorShift64::new(0x9e37_79b9_7f4a_7c15u64);
    let mut uniform = move || rng.uniform();
    let dz = (N - nz) / 2;
    let mut values = Vec::with_capacity(N * N * N);
    for k in 0..N {
        for j in 0..N {
            for i in 0..N {
                let v = if i < nx && j < ny && k >= dz && k < dz + nz {
                    phantom.volume.value(phantom.volume.index(i, j, k - dz))
                } else {
                    let (u1, u2) = (1.0 - uniform(), uniform());
                    let g = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                    AIR_HU + noise * (MATERIAL_HU - AIR_HU) * g
                };
                values.push(v as f32);
            }
        }
    }
    let voxel = params.voxel;
    let volume = Volume::axis_aligned(
        [N, N, N],
        VoxelValues::F32(values),
        DVec3::splat(voxel),
        DVec3::new(0.0, 0.0, -(dz as f64) * voxel),
    )
    .unwrap();
    let start = std::time::Instant::now();
    let (mesh, stats) = extract_skeleton(&volume, &SkeletonParams::default(), &|_| {}).unwrap();
    let total = start.elapsed().as_secs_f64();
    println!(
        "{} in {N}³ ({nx}×{ny}×{nz} phantom), noise {noise}: {:.2} s; {} object voxels, {} supports, {} tetrahedra, {} ridge points, {} triangles, {} components, χ {}",
        shape.name(),
        total,
        stats.cover.object_points,
        stats.cover.supports,
        stats.tetrahedra,
        stats.ridge_points,
        stats.triangles,
        stats.components,
        stats.euler_characteristic
    );
    for (name, t) in &stats.stages {
        println!("  {name:<18} {:.3} s", t.as_secs_f64());
    }
    let m = score_mesh(&mesh, &phantom.truth, 1.0);
    println!(
        "  coverage {:.3}, spurious {:.3} (away from rim {:.3}), p95 away from rim {:.2} voxel, boundary reach {:.2} voxel, χ {:?} (true {})",
        m.coverage,
        m.spurious,
        m.spurious_interior,
        m.distance_interior_p95,
        m.boundary_reach_mean,
        m.euler_characteristic,
        phantom.truth.euler_characteristic
    );
}
