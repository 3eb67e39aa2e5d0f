//! `sphcover skeleton`: the skeletal sheet of a thin part from a CT volume (thesis §6) or
//! from scattered samples with values, or the non-maximum-suppression baseline for
//! comparison.

use sphcover_core::io::{self, VolumeInfo};
use sphcover_core::{PointCloud, TriMesh};
use sphcover_skeleton::{
    Material, MaterialChoice, MaterialReport, NmsParams, Resampling, SkeletonError, SkeletonParams,
    SkeletonStats, VoxelGridError, check_voxel_grid, extract_skeleton,
    extract_skeleton_from_samples, nms_skeleton,
};

use crate::args::{MaterialArg, SkeletonArgs, SkeletonMethod};
use crate::exit::BadInput;
use crate::memory_limit::MemoryLimit;
use crate::report::{Reporter, show_stage};

/// Runs `sphcover skeleton`.
pub fn run(args: &SkeletonArgs, reporter: &Reporter) -> anyhow::Result<()> {
    if let Some(s) = args.sigma
        && !(s.is_finite() && s > 0.0)
    {
        return Err(BadInput(format!("--sigma {s} must be a positive number")).into());
    }
    if let Some(property) = &args.value_property {
        return run_on_samples(args, property, reporter);
    }
    if !io::is_volume_path(&args.input) {
        return Err(BadInput(format!(
            "{}: expected a CT volume (.nii, .nii.gz, .inr, .inr.gz); for scattered samples with values (PLY), name their value property with --value-property",
            args.input.display()
        ))
        .into());
    }

    // Everything the header decides is checked before the voxels are read.
    let header = io::read_volume_info(&args.input)?;
    let resampling = check_volume(args, &header, reporter)?;
    let grid = crate::skeleton_memory::SkeletonGrid::new(
        header.dims(),
        resampling.as_ref(),
        args.material != MaterialArg::Off && crate::skeleton_memory::stores_ct(&header),
    );
    crate::skeleton_memory::check_budget(args, grid, reporter)?;
    let limit = MemoryLimit::from_flag(args.max_memory);
    let stage = reporter.stage("read volume");
    let (volume, info) =
        crate::volume_input::read_volume(&args.input, &args.read, &limit, reporter)?;
    stage.finish();
    let [nx, ny, nz] = volume.dims();
    let size = volume.voxel_size();
    reporter.detail(&format!(
        "  {nx} x {ny} x {nz} voxels of {:.4} ({})",
        size.x,
        info.format_description()
    ));

    match args.method {
        SkeletonMethod::Ridge => {
            let bar = reporter.stage_bar("extracting the skeletal sheet");
            let result = extract_skeleton(&volume, &ridge_params(args), &|stage| {
                show_stage(&bar, stage)
            });
            bar.finish_and_clear();
            let (sheet, stats) = result.map_err(|e| bad(args, e))?;
            write_sheet(args, &sheet, &stats, reporter)?;
        }
        SkeletonMethod::Nms => {
            let params = NmsParams {
                sigma: args.sigma.unwrap_or(NmsParams::default().sigma),
                threshold: args.threshold,
                ..NmsParams::default()
            };
            let stage = reporter.stage("smoothing and NMS");
            let (points, stats) = nms_skeleton(&volume, &params).map_err(|e| bad(args, e))?;
            stage.finish();
            let stage = reporter.stage("write");
            let cloud = PointCloud {
                positions: points,
                ..PointCloud::default()
            };
            io::write_point_cloud(
                &args.output,
                &cloud,
                &super::write_options(&args.input, args.ascii),
            )?;
            stage.finish();
            reporter.summary(&format!(
                "threshold {:.6} ({}); {} voxels above it after smoothing; {} ridge points -> {}",
                stats.intensity.threshold,
                if stats.intensity.automatic_threshold {
                    "automatic"
                } else {
                    "given"
                },
                stats.candidates,
                stats.points,
                args.output.display()
            ));
        }
    }
    Ok(())
}

/// The sheet of scattered samples with values (a PLY point file and one of its scalar
/// vertex properties), which the grid-based NMS baseline cannot take.
fn run_on_samples(args: &SkeletonArgs, property: &str, reporter: &Reporter) -> anyhow::Result<()> {
    let name = args.input.display();
    if args.method == SkeletonMethod::Nms {
        return Err(BadInput(format!(
            "{name}: --method nms works on a voxel grid; scattered samples take the ridge method"
        ))
        .into());
    }
    if args.max_memory.is_some() {
        return Err(BadInput(
            "--max-memory: the skeleton's memory model is fitted to volumes, not to scattered samples".to_owned(),
        )
        .into());
    }
    let limit = MemoryLimit::machine_default();
    let (positions, values) = crate::value_samples::read_value_samples(
        &args.input,
        property,
        &args.read,
        &limit,
        reporter,
    )?;
    reporter.detail(&format!("  {} samples with `{property}`", positions.len()));
    let bar = reporter.stage_bar("extracting the skeletal sheet of the samples");
    let result =
        extract_skeleton_from_samples(&positions, &values, &ridge_params(args), &|stage| {
            show_stage(&bar, stage)
        });
    bar.finish_and_clear();
    let (sheet, stats) = result.map_err(|e| bad(args, e))?;
    write_sheet(args, &sheet, &stats, reporter)
}

/// The ridge pipeline's parameters: the library's defaults and the command line's.
fn ridge_params(args: &SkeletonArgs) -> SkeletonParams {
    let mut params = SkeletonParams::default();
    params.threshold = args.threshold;
    params.material = match args.material {
        MaterialArg::Auto => MaterialChoice::Auto,
        MaterialArg::Bone => MaterialChoice::Given(Material::Bone),
        MaterialArg::Tissue => MaterialChoice::Given(Material::Tissue),
        MaterialArg::Off => MaterialChoice::Off,
    };
    params.tolerance = args.eps;
    params.sigma = args.sigma.unwrap_or(params.sigma);
    params.seed = args.seed;
    params
}

/// A failure of the input or parameters is bad input (exit 2); a lower-layer failure is an
/// internal error, both named after the input file.
fn bad(args: &SkeletonArgs, e: SkeletonError) -> anyhow::Error {
    match e {
        SkeletonError::Tetra(_) | SkeletonError::Evaluator(_) => {
            anyhow::Error::new(e).context(format!("{}", args.input.display()))
        }
        e => BadInput(format!("{}: {e}", args.input.display())).into(),
    }
}

/// Timings, warnings, the sheet, the optional JSON report and the closing line.
fn write_sheet(
    args: &SkeletonArgs,
    sheet: &TriMesh,
    stats: &SkeletonStats,
    reporter: &Reporter,
) -> anyhow::Result<()> {
    for (name, time) in &stats.stages {
        reporter.detail(&format!("  {name:<24} {:>9.3} s", time.as_secs_f64()));
    }
    if let Some(material) = &stats.material {
        report_material(material, reporter);
    }
    if let Some(stretch) = stats.hessian_slice_stretch {
        let rim = stats
            .rim_slice_stretch
            .map_or(String::new(), |s| format!(", rim test {s:.3}x"));
        reporter.detail(&format!(
            "  thick slices: ridge test with the slice axis compressed {stretch:.3}x{rim}; {} vertices moved to the slices' centroids, {} triangles off the plates collapsed",
            stats.slice_centred_vertices, stats.off_plate_triangles
        ));
    }
    if stats.thickness_exceeds_r_max() {
        reporter.warn(&format!(
            "the object is up to {:.3} thick, more than the largest support radius {:.3}: thick parts may lose their sheet; if the thin part is another material, choose it with --threshold{}",
            stats.cover.thickness.unwrap_or(0.0),
            stats.cover.r_max,
            if stats.material.is_some() { " or --material" } else { "" }
        ));
    }
    if stats.components > 1 {
        reporter.warn(&format!("the sheet has {} components", stats.components));
    }
    let stage = reporter.stage("write");
    io::write_mesh(
        &args.output,
        sheet,
        &super::write_options(&args.input, args.ascii),
    )?;
    stage.finish();
    if let Some(path) = &args.report {
        let text = serde_json::to_string_pretty(&report_json(args, stats))?;
        io::write_atomic(path, std::slice::from_ref(&args.input), |w| {
            w.write_all(text.as_bytes())
        })?;
    }
    reporter.summary(&summary(stats, &args.output.display().to_string()));
    Ok(())
}

/// What the material stage decided on a CT, said once: the material and why, or why none.
fn report_material(m: &MaterialReport, reporter: &Reporter) {
    let levels = format!(
        "CT in Hounsfield units (air {:.0}, soft tissue {:+.0})",
        m.levels.air, m.levels.soft_tissue
    );
    let window = m
        .window
        .map(|(lo, hi)| format!("; values windowed to [{lo:.0}, {hi:.0}] HU and smoothed"))
        .unwrap_or_default();
    let depths = || {
        m.candidates
            .iter()
            .map(|c| match c.depth_p90 {
                Some(d) => format!("{} {d:.1}", c.material.name()),
                None => format!("{} none", c.material.name()),
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match (m.material, m.automatic) {
        (Some(material), true) => reporter.note(&format!(
            "{levels}: {} is the thin material, above {:.0} HU (90% of it within {:.1} mm of its surface; thin is within {:.1} mm){window}; choose another with --material or --threshold",
            material.name(),
            m.candidates.last().map_or(f64::NAN, |c| c.threshold),
            m.candidates.last().and_then(|c| c.depth_p90).unwrap_or(f64::NAN),
            m.thin_depth,
        )),
        (Some(material), false) => reporter.note(&format!(
            "{levels}: {}, above {:.0} HU{window}",
            material.name(),
            material.threshold(&m.levels)
        )),
        (None, true) => reporter.warn(&format!(
            "{levels}, but no material is thin (depth of 90% of its voxels in mm: {}; thin is within {:.1} mm): the threshold splits the two largest classes; choose a material with --material or --threshold",
            depths(),
            m.thin_depth
        )),
        (None, false) => reporter.note(&format!(
            "{levels}: the given threshold is taken as a material's{window} (--material off takes the values as they are)"
        )),
    }
}

/// Refuses, from the header, what the pipeline cannot treat correctly: several frames,
/// voxels more than 8:1 anisotropic, and voxel axes that are not the world axes (up to order
/// and sign). Notes how voxels more than 1.75:1 apart are resampled (returned), and warns about
/// voxels processed though not cubic.
fn check_volume(
    args: &SkeletonArgs,
    info: &VolumeInfo,
    reporter: &Reporter,
) -> anyhow::Result<Option<Resampling>> {
    let name = args.input.display();
    if info.frames() > 1 {
        return Err(BadInput(format!(
            "{name}: a 4D volume with {} frames; extract the frame to process first (e.g. with fslroi)",
            info.frames()
        ))
        .into());
    }
    match check_voxel_grid(info.voxel_size(), info.affine().matrix3) {
        Ok(check) => {
            if let Some(resampling) = &check.resampling {
                // Not only with -v: the sheet is computed on interpolated slices.
                let [nx, ny, nz] = resampling.dims(info.dims());
                reporter.note(&format!(
                    "{name}: {resampling}; {nx} x {ny} x {nz} voxels"
                ));
            }
            if let Some(non_cubic) = check.non_cubic {
                reporter.warn(&format!("{name}: {non_cubic}"));
            }
            Ok(check.resampling)
        }
        Err(VoxelGridError::Oblique) => Err(BadInput(format!(
            "{name}: the voxel axes are oblique to the world axes ({} affine); resample to an axis-aligned grid first",
            info.axes_source()
        ))
        .into()),
        Err(e) => Err(BadInput(format!("{name}: {e}")).into()),
    }
}

/// The `--report` JSON: the closing line's counts and the per-stage seconds.
fn report_json(args: &SkeletonArgs, s: &SkeletonStats) -> serde_json::Value {
    serde_json::json!({
        "input": args.input.display().to_string(),
        "output": args.output.display().to_string(),
        "threshold": s.intensity.threshold,
        "automatic_threshold": s.intensity.automatic_threshold,
        "material": s.material.as_ref().map(|m| serde_json::json!({
            "name": m.material.map(Material::name),
            "automatic": m.automatic,
            "air_hu": m.levels.air,
            "soft_tissue_hu": m.levels.soft_tissue,
            "window": m.window.map(|(lo, hi)| [lo, hi]),
        })),
        "tolerance": s.tolerance,
        "object_voxels": s.cover.object_points,
        "supports": s.cover.supports,
        "tetrahedra": s.tetrahedra,
        "ridge_points": s.ridge_points,
        "triangles": s.triangles,
        "vertices": s.vertices,
        "components": s.components,
        "euler_characteristic": s.euler_characteristic,
        "tunnels_closed": s.tunnels,
        "perforations_cut": s.perforations,
        "material_holes_filled": s.material_holes,
        "flap_triangles_collapsed": s.flap_triangles,
        "slice_centred_vertices": s.slice_centred_vertices,
        "hessian_slice_stretch": s.hessian_slice_stretch,
        "rim_slice_stretch": s.rim_slice_stretch,
        "off_plate_triangles_collapsed": s.off_plate_triangles,
        "resampled": s.resampled.map(|r| serde_json::json!({
            "factors": r.resampling.factors,
            "input_dims": r.original_dims,
            "dims": r.dims,
            "voxel_size": r.resampling.voxel_size().to_array(),
            "seconds": r.time.as_secs_f64(),
        })),
        "stages_seconds": s.stages.iter()
            .map(|(n, t)| serde_json::json!({"stage": n, "seconds": t.as_secs_f64()}))
            .collect::<Vec<_>>(),
    })
}

fn summary(s: &SkeletonStats, output: &str) -> String {
    format!(
        "threshold {:.6} ({}), noise {:.4}, eps {:.4}; {} object voxels, {} supports (radii {:.4}..{:.4}), {} tetrahedra, {} ridge points, {} triangles ({} dropped in {} fragments, {} holes and {} tunnels filled), {} component{}, Euler characteristic {}; {:.2} s -> {output}",
        s.intensity.threshold,
        if s.intensity.automatic_threshold {
            "automatic"
        } else {
            "given"
        },
        s.intensity.noise_std,
        s.tolerance,
        s.cover.object_points,
        s.cover.supports,
        s.cover.radius_min,
        s.cover.radius_max,
        s.tetrahedra,
        s.ridge_points,
        s.triangles,
        s.cleaning.dropped_triangles,
        s.cleaning.dropped_components,
        s.cleaning.holes_filled + s.material_holes,
        s.tunnels,
        s.components,
        if s.components == 1 { "" } else { "s" },
        s.euler_characteristic,
        s.stages.iter().map(|(_, t)| t.as_secs_f64()).sum::<f64>(),
    )
}
