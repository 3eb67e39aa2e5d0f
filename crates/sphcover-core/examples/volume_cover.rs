//! Builds the volume cover of a NIfTI file and prints its statistics.
//!
//! `cargo run --release -p sphcover-core --example volume_cover -- FILE.nii.gz THRESHOLD
//! [linear|scattered] [order=random|deepest|greedy] [eliminate=no|centres|corners]
//! [min=MIN_SAMPLES] [eps=E]`
//! (THRESHOLD in the file's units; `linear` builds the bounding-box linear variant;
//! `scattered` gives the voxel centres and values to the scattered-sample builder instead;
//! the `key=value` options set [`VolumeCoverParams`] fields, library defaults otherwise).
//! FILE may also be `plate:T[:EPS]`: the tests' tilted plate phantom of `T` voxels
//! (40 × 40 × 24 voxels of 0.1, PSF 0.8 voxel, HU −1000/+2000) at tolerance EPS (default
//! 0.05).

#[path = "../tests/volume_common/mod.rs"]
mod volume_common;

use std::path::PathBuf;
use std::time::Instant;

use sphcover_core::io::{ReadOptions, read_nifti};
use sphcover_core::{
    CentreOrder, Cover, DVec3, Elimination, PuEvaluator, Threshold, Volume, VolumeCoverParams,
    VolumeCoverStats, VolumeCoverVariant, VoxelValues, build_scattered_cover, build_volume_cover,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: volume_cover FILE.nii[.gz] THRESHOLD [linear|scattered] \
                 [order=random|deepest|greedy] [eliminate=no|centres|corners] [min=MIN_SAMPLES] [eps=E]";
    let path = PathBuf::from(args.next().ok_or(usage)?);
    let threshold: f64 = args.next().ok_or(usage)?.parse()?;
    let defaults = VolumeCoverParams::default();
    let (mut linear, mut scattered) = (false, false);
    let mut centre_order = defaults.centre_order;
    let mut elimination = defaults.elimination;
    let mut min_samples = defaults.min_samples;
    let mut tolerance = defaults.tolerance;
    for arg in args {
        match arg.split_once('=') {
            None if arg == "linear" => linear = true,
            None if arg == "scattered" => scattered = true,
            Some(("order", v)) => {
                centre_order = match v {
                    "random" => CentreOrder::Random,
                    "deepest" => CentreOrder::DeepestFirst,
                    "greedy" => CentreOrder::MostUncovered,
                    _ => return Err(usage.into()),
                }
            }
            Some(("eliminate", v)) => {
                elimination = match v {
                    "no" => Elimination::Off,
                    "centres" => Elimination::VoxelCentres,
                    "corners" => Elimination::CellCorners,
                    _ => return Err(usage.into()),
                }
            }
            Some(("min", v)) => min_samples = v.parse()?,
            Some(("eps", v)) => tolerance = v.parse()?,
            _ => return Err(usage.into()),
        }
    }

    let name = path.to_string_lossy().into_owned();
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
        let (volume, info) = read_nifti(&path, &ReadOptions::default())?;
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
        centre_order,
        elimination,
        min_samples,
        tolerance,
        ..defaults
    };
    let start = Instant::now();
    let (cover, stats) = if scattered {
        // Non-finite voxels are no samples, as for the grid builder.
        let (points, values): (Vec<DVec3>, Vec<f64>) = (0..volume.len())
            .filter(|&i| volume.value(i).is_finite())
            .map(|i| (volume.voxel_centre(volume.ijk(i)), volume.value(i)))
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
    blend_check(&volume, &cover, &stats, threshold)?;
    Ok(())
}

/// The blended function against the normalised voxel values at the object voxels' centres
/// (RMS and largest error, and how many lie in no ball), and the corners of the object
/// voxels' cells that lie in no ball (gaps between voxel centres).
fn blend_check(
    volume: &Volume,
    cover: &Cover,
    stats: &VolumeCoverStats,
    threshold: f64,
) -> Result<(), Box<dyn std::error::Error>> {
    let start = Instant::now();
    let (lo, hi) = stats.value_range;
    let f = PuEvaluator::new(cover, 1.0)?;
    let object: Vec<usize> = (0..volume.len())
        .filter(|&i| volume.value(i) > threshold)
        .collect();
    let centres: Vec<DVec3> = object
        .iter()
        .map(|&i| volume.voxel_centre(volume.ijk(i)))
        .collect();
    let values = f.values(&centres);
    let (mut sum, mut worst, mut outside) = (0.0, 0.0f64, 0usize);
    for (&i, v) in object.iter().zip(&values) {
        match v {
            Some(v) => {
                let e = v - (volume.value(i) - lo) / (hi - lo);
                sum += e * e;
                worst = worst.max(e.abs());
            }
            None => outside += 1,
        }
    }
    let half = volume.affine().matrix3 * DVec3::splat(0.5);
    let mut corners = Vec::with_capacity(8 * centres.len());
    for c in &centres {
        for k in 0..8 {
            let s = DVec3::new(
                if k & 1 == 0 { -1.0 } else { 1.0 },
                if k & 2 == 0 { -1.0 } else { 1.0 },
                if k & 4 == 0 { -1.0 } else { 1.0 },
            );
            corners.push(*c + half * s);
        }
    }
    let gaps = f.values(&corners).iter().filter(|v| v.is_none()).count();
    println!(
        "blend at object voxels: RMS {:.4}, max |error| {:.4}, outside every ball {}; \
         voxel-cell corners outside every ball {} of {} ({:.3?})",
        (sum / (object.len() - outside).max(1) as f64).sqrt(),
        worst,
        outside,
        gaps,
        corners.len(),
        start.elapsed()
    );
    Ok(())
}
