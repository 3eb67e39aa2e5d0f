//! Builds the volume cover of a NIfTI file and prints its statistics.
//!
//! `cargo run --release -p sphcover-core --example volume_cover -- FILE.nii.gz THRESHOLD [linear]`
//! (THRESHOLD in the file's units; `linear` builds the bounding-box linear variant;
//! `scattered` gives the voxel centres and values to the scattered-sample builder instead).
//! FILE may also be `plate:T[:EPS]`: the tests' tilted plate phantom of `T` voxels
//! (40 × 40 × 24 voxels of 0.1, PSF 0.8 voxel, HU −1000/+2000) at tolerance EPS (default
//! 0.05). Set `DEEPEST=1` for the deepest-first centre order.

#[path = "../tests/volume_common/mod.rs"]
mod volume_common;

use std::path::PathBuf;
use std::time::Instant;

use sphcover_core::io::read_nifti;
use sphcover_core::{
    CentreOrder, DVec3, Threshold, Volume, VolumeCoverParams, VolumeCoverVariant, VoxelValues,
    build_scattered_cover, build_volume_cover,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: volume_cover FILE.nii[.gz] THRESHOLD [linear|scattered]";
    let path = PathBuf::from(args.next().ok_or(usage)?);
    let threshold: f64 = args.next().ok_or(usage)?.parse()?;
    let mode = args.next();
    let linear = mode.as_deref() == Some("linear");
    let scattered = mode.as_deref() == Some("scattered");
    let deepest = std::env::var_os("DEEPEST").is_some();

    let name = path.to_string_lossy().into_owned();
    let mut tolerance = VolumeCoverParams::default().tolerance;
    let volume = if let Some(spec) = name.strip_prefix("plate:") {
        let mut parts = spec.split(':');
        let thickness: f64 = parts.next().ok_or(usage)?.parse()?;
        if let Some(e) = parts.next() {
            tolerance = e.parse()?;
        }
        let dims = [40, 40, 24];
        let values = volume_common::thin_plate(dims, thickness, 20.0, 0.8);
        println!("plate phantom: {thickness} voxels thick, {dims:?} voxels of 0.1");
        Volume::axis_aligned(
            dims,
            VoxelValues::F64(values),
            DVec3::splat(0.1),
            DVec3::ZERO,
        )?
    } else {
        let start = Instant::now();
        let (volume, info) = read_nifti(&path)?;
        println!(
            "{}: NIfTI-{} {} {:?} voxels {:.4?}, {} frame(s), affine from {:?}, read in {:.3?}",
            path.display(),
            info.version,
            info.datatype.name(),
            info.dims,
            info.voxel_size.to_array(),
            info.frames,
            info.affine_source,
            start.elapsed()
        );
        volume
    };
    let params = VolumeCoverParams {
        threshold: Threshold::Raw(threshold),
        variant: if linear {
            VolumeCoverVariant::BoundingBoxLinear
        } else {
            VolumeCoverVariant::ObjectQuadratic
        },
        centre_order: if deepest {
            CentreOrder::DeepestFirst
        } else {
            CentreOrder::Random
        },
        tolerance,
        ..VolumeCoverParams::default()
    };
    let start = Instant::now();
    let (cover, stats) = if scattered {
        // Non-finite voxels are no samples, as for the grid builder.
        let (points, values): (Vec<DVec3>, Vec<f64>) = (0..volume.len())
            .filter(|&i| volume.value(i).is_finite())
            .map(|i| (volume.voxel_center(volume.ijk(i)), volume.value(i)))
            .unzip();
        build_scattered_cover(&points, &values, &params)?
    } else {
        build_volume_cover(&volume, &params)?
    };
    let total = start.elapsed();
    println!("value range        {:?}", stats.value_range);
    println!("object voxels      {}", stats.object_points);
    println!("candidates         {}", stats.candidates);
    println!("supports           {}", cover.len());
    println!(
        "ratio              {:.1}",
        stats.candidates as f64 / cover.len() as f64
    );
    println!(
        "r_min / r_max      {:.4} / {:.4} (thickness {:?})",
        stats.r_min, stats.r_max, stats.thickness
    );
    println!(
        "radius min/mean/max {:.4} / {:.4} / {:.4}",
        stats.radius_min, stats.radius_mean, stats.radius_max
    );
    println!(
        "max RMS            {:.4} (ε = {}), above ε: {}",
        stats.max_rms, params.tolerance, stats.above_tolerance
    );
    println!("fits               {}", stats.fits);
    println!(
        "time               {:.3?} (distance transform {:.3?}, cover {:.3?})",
        total, stats.time_distance_transform, stats.time_cover
    );
    Ok(())
}
