//! `sphcover cover`: a spherical cover of oriented scan points (thesis §3.4.1) or of a CT
//! volume (thesis §3.4.2), written as a cover file the library reads back.

use std::path::Path;

use sphcover_core::io::{self, CoverFileMeta};
use sphcover_core::{
    CentreOrder, Cover, Elimination, Normalisation, SurfaceCoverParams, Threshold,
    VolumeCoverParams, VolumeCoverStats, VolumeCoverVariant, build_scattered_cover,
    build_surface_cover_from_cloud, build_volume_cover,
};

use crate::args::{CoverArgs, CoverCentreOrder, CoverElimination};
use crate::exit::BadInput;
use crate::memory_limit::MemoryLimit;
use crate::report::Reporter;

/// Runs `sphcover cover`.
pub fn run(args: &CoverArgs, reporter: &Reporter) -> anyhow::Result<()> {
    if let Some(eps) = args.eps
        && !(eps.is_finite() && eps > 0.0)
    {
        return Err(BadInput(format!("--eps {eps} must be a positive number")).into());
    }
    let limit = args.memory.limit();
    let (cover, meta) = if let Some(property) = &args.value_property {
        scattered_cover(args, property, &limit, reporter)?
    } else if io::is_volume_path(&args.input) {
        volume_cover(args, &limit, reporter)?
    } else {
        if args.threshold.is_some()
            || args.linear
            || args.centre_order != CoverCentreOrder::Random
            || args.elimination != CoverElimination::Corners
        {
            return Err(BadInput(
                "--threshold, --linear, --centre-order and --elimination apply to volumes (.nii, .nii.gz, .inr) and to scattered samples (--value-property) only".to_owned(),
            )
            .into());
        }
        surface_cover(args, &limit, reporter)?
    };
    let stage = reporter.stage("write");
    let options = super::write_options(&args.input, args.ascii);
    io::write_cover(&args.output, &cover, &meta, &options)?;
    stage.finish();
    Ok(())
}

fn surface_cover(
    args: &CoverArgs,
    limit: &MemoryLimit,
    reporter: &Reporter,
) -> anyhow::Result<(Cover, CoverFileMeta)> {
    let stage = reporter.stage("read points");
    let cloud = io::read_point_cloud(&args.input, &args.read.read_options(limit))
        .map_err(|e| limit.explain(e))?;
    stage.finish();
    if cloud.normals.is_none() {
        return Err(BadInput(format!(
            "{}: the points have no normals: the surface cover needs outward normals (estimating them from unoriented points is part of `sphcover recon`){}",
            args.input.display(),
            if cloud.values.is_some() {
                "; for a volume cover of scattered samples with values, name their property with --value-property"
            } else {
                ""
            }
        ))
        .into());
    }
    let params = SurfaceCoverParams {
        eps: args.eps.unwrap_or(SurfaceCoverParams::default().eps),
        seed: args.seed,
        // Sparse scans with ε below their sampling: octants whose children cannot be fitted
        // on their own points stay unrefined, and their error is reported.
        sampling_stop: true,
        ..SurfaceCoverParams::default()
    };
    let bar = reporter.progress(None, "building the surface cover");
    let (cover, normalisation, stats) = build_surface_cover_from_cloud(&cloud, &params)
        .map_err(|e| BadInput(format!("{}: {e}", args.input.display())))?;
    bar.finish_and_clear();
    let t = &stats.timings;
    for (name, d) in [
        ("point index", t.index),
        ("octree", t.octree),
        ("growth", t.growth),
        ("elimination", t.elimination),
    ] {
        reporter.detail(&format!("  {name:<24} {:>9.3} s", d.as_secs_f64()));
    }
    reporter.detail(&format!(
        "  octants per level {:?}; leaves per level {:?}",
        stats.octants_per_level, stats.leaves_per_level
    ));
    if stats.skipped_normals > 0 {
        reporter.warn(&format!(
            "{}: skipped {} points with zero-length normals",
            args.input.display(),
            stats.skipped_normals
        ));
    }
    reporter.summary(&format!(
        "{} points ({} used): {} supports ({} before expansion), {} over ε = {} ({:.1} %; {} octants left unrefined for the sampling density; largest error {:.3e}), {:.3} s -> {}",
        stats.input_points,
        stats.used_points,
        stats.supports_after_expansion,
        stats.supports_before_expansion,
        stats.supports_over_eps,
        params.eps,
        100.0 * stats.supports_over_eps as f64 / stats.supports_after_expansion.max(1) as f64,
        stats.sampling_limited_octants,
        stats.max_error,
        t.total.as_secs_f64(),
        args.output.display()
    ));
    let meta = CoverFileMeta {
        normalisation,
        notes: vec![notes(
            &args.input,
            &format!("surface cover eps={} seed={}", params.eps, params.seed),
        )],
        ..CoverFileMeta::default()
    };
    Ok((cover, meta))
}

fn volume_cover(
    args: &CoverArgs,
    limit: &MemoryLimit,
    reporter: &Reporter,
) -> anyhow::Result<(Cover, CoverFileMeta)> {
    let stage = reporter.stage("read volume");
    let (volume, _info) =
        crate::volume_input::read_volume(&args.input, &args.read, limit, reporter)?;
    stage.finish();
    let params = volume_params(args);
    let bar = reporter.progress(None, "building the volume cover");
    let (cover, stats) = build_volume_cover(&volume, &params)
        .map_err(|e| BadInput(format!("{}: {e}", args.input.display())))?;
    bar.finish_and_clear();
    reporter.detail(&format!(
        "  distance transform       {:>9.3} s\n  cover                    {:>9.3} s",
        stats.time_distance_transform.as_secs_f64(),
        stats.time_cover.as_secs_f64()
    ));
    reporter.detail(&format!(
        "  radii {:.4} .. {:.4} (mean {:.4}); r_min {:.4}, r_max {:.4}; {} fits",
        stats.radius_min, stats.radius_max, stats.radius_mean, stats.r_min, stats.r_max, stats.fits
    ));
    let meta = summarise_volume_cover(args, reporter, &params, &stats, "points", "volume cover");
    Ok((cover, meta))
}

fn scattered_cover(
    args: &CoverArgs,
    property: &str,
    limit: &MemoryLimit,
    reporter: &Reporter,
) -> anyhow::Result<(Cover, CoverFileMeta)> {
    let (positions, values) = crate::value_samples::read_value_samples(
        &args.input,
        property,
        &args.read,
        limit,
        reporter,
    )?;
    let params = volume_params(args);
    let bar = reporter.progress(None, "building the volume cover of scattered samples");
    let (cover, stats) = build_scattered_cover(&positions, &values, &params)
        .map_err(|e| BadInput(format!("{}: {e}", args.input.display())))?;
    bar.finish_and_clear();
    reporter.detail(&format!(
        "  thickness (nearest background) {:>9.3} s\n  cover                    {:>9.3} s",
        stats.time_distance_transform.as_secs_f64(),
        stats.time_cover.as_secs_f64()
    ));
    reporter.detail(&format!(
        "  sample spacing {:.4}; radii {:.4} .. {:.4} (mean {:.4}); r_min {:.4}, r_max {:.4}; {} fits",
        stats.sample_spacing,
        stats.radius_min,
        stats.radius_max,
        stats.radius_mean,
        stats.r_min,
        stats.r_max,
        stats.fits
    ));
    let meta = summarise_volume_cover(
        args,
        reporter,
        &params,
        &stats,
        "samples",
        &format!("scattered-sample cover property={property}"),
    );
    Ok((cover, meta))
}

/// The volume builders' parameters from the command line (library defaults otherwise).
fn volume_params(args: &CoverArgs) -> VolumeCoverParams {
    let defaults = VolumeCoverParams::default();
    VolumeCoverParams {
        threshold: args.threshold.map_or(defaults.threshold, Threshold::Raw),
        tolerance: args.eps.unwrap_or(defaults.tolerance),
        variant: if args.linear {
            VolumeCoverVariant::BoundingBoxLinear
        } else {
            VolumeCoverVariant::ObjectQuadratic
        },
        centre_order: match args.centre_order {
            CoverCentreOrder::Random => CentreOrder::Random,
            CoverCentreOrder::Deepest => CentreOrder::DeepestFirst,
            CoverCentreOrder::Greedy => CentreOrder::MostUncovered,
        },
        elimination: match args.elimination {
            CoverElimination::Off => Elimination::Off,
            CoverElimination::Centres => Elimination::VoxelCentres,
            CoverElimination::Corners => Elimination::CellCorners,
        },
        seed: args.seed,
        ..defaults
    }
}

/// Prints the summary line of a volume cover (of voxels or of scattered `samples`) and
/// returns its file metadata, whose note starts with `description`.
fn summarise_volume_cover(
    args: &CoverArgs,
    reporter: &Reporter,
    params: &VolumeCoverParams,
    stats: &VolumeCoverStats,
    samples: &str,
    description: &str,
) -> CoverFileMeta {
    reporter.summary(&format!(
        "{} object {samples} of {} candidates: {} supports ({:.1} {samples} per support), largest RMS error {:.4} ({} over ε = {}) -> {}",
        stats.object_points,
        stats.candidates,
        stats.supports,
        stats.object_points as f64 / stats.supports.max(1) as f64,
        stats.max_rms,
        stats.above_tolerance,
        params.tolerance,
        args.output.display()
    ));
    CoverFileMeta {
        normalisation: Normalisation::IDENTITY,
        notes: vec![notes(
            &args.input,
            &format!(
                "{description} tolerance={} variant={:?} seed={}",
                params.tolerance, params.variant, params.seed
            ),
        )],
        ..CoverFileMeta::default()
    }
}

/// A provenance note: which file and which parameters made the cover.
fn notes(input: &Path, what: &str) -> String {
    let name = input.file_name().map_or_else(
        || input.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    format!("{what} from {name}")
}
