//! `sphcover recon`: a surface mesh from scanned points (thesis §5), robust to noise,
//! outliers and wrong normals.

use std::path::Path;

use serde_json::json;
use sphcover_core::PointCloud;
use sphcover_core::StopRequest;
use sphcover_core::io::{self, CoverFileMeta, WriteOptions, format_byte_size};
use sphcover_recon::{
    BudgetFit, Method, NoiseOption, ONE_VIEW_NEAR, ReconError, ReconOptions, ReconParams,
    ReconStats, ScanFile, SequentialStreamedTiles, Tiling, ToleranceNote, TrimOption, UNSEEN_NEAR,
    UNSEEN_REACH, cover_over_budget_message, fit_memory_budget, reconstruct, reconstruct_streamed,
    reconstruct_tiled,
};

use crate::args::{ReconArgs, ReconMethodArg};
use crate::exit::BadInput;
use crate::memory_limit::MemoryLimit;
use crate::report::{Reporter, show_stage};

/// Runs `sphcover recon`.
pub fn run(args: &ReconArgs, reporter: &Reporter) -> anyhow::Result<()> {
    let mut params = params(args)?;
    if args.stream {
        return run_streamed(args, &params, reporter);
    }
    let stage = reporter.stage("read points");
    let limit = MemoryLimit::from_flag(args.max_memory);
    let mut cloud = io::read_point_cloud(&args.input, &args.read.read_options(&limit))
        .map_err(|e| limit.explain(e))?;
    stage.finish();
    if args.estimate_normals {
        cloud.normals = None;
    }
    let memory = match args.max_memory {
        Some(budget) => Some(fit_budget(&cloud, budget, &mut params, reporter)?),
        None => None,
    };
    // Checked again once the cover's graph is built, when its true size is known; without
    // --max-memory against the default limit, so that a cover far larger than usual stops
    // with the remedies instead of being killed when the machine runs out of memory.
    params.memory_budget = limit.bytes();

    let bar = reporter.stage_bar("reconstructing");
    let progress = |stage| show_stage(&bar, stage);
    let result = match args.tiles {
        Some(tiles) => {
            let tiling = Tiling {
                tiles,
                halo: args.halo.unwrap_or_else(|| Tiling::default_halo(tiles)),
            };
            reconstruct_tiled(&cloud, &params, &tiling, &progress)
        }
        None => reconstruct(&cloud, &params, &progress),
    };
    bar.finish_and_clear();
    let recon = result.map_err(|e| recon_error(args, Some(&limit), e))?;
    describe(&params, &recon.stats, reporter);

    let stage = reporter.stage("write");
    let options = WriteOptions {
        inputs: vec![args.input.clone()],
        ..WriteOptions::default()
    };
    io::write_mesh(&args.output, &recon.mesh, &options)?;
    if let Some(path) = &args.points_out {
        let points = PointCloud {
            positions: cloud.positions.clone(),
            normals: cloud.normals.clone(),
            confidence: Some(recon.confidence.clone()),
            values: Some(
                recon
                    .outliers
                    .iter()
                    .map(|&o| f64::from(u8::from(o)))
                    .collect(),
            ),
            colors: cloud.colors.clone(),
        };
        io::write_point_cloud(path, &points, &options)?;
    }
    if let Some(path) = &args.cover_out {
        let meta = CoverFileMeta {
            normalisation: recon.normalisation,
            notes: vec![format!(
                "sphcover recon --method {} of {}",
                params.method.name(),
                file_name(&args.input)
            )],
            ..CoverFileMeta::default()
        };
        io::write_cover(path, &recon.cover, &meta, &options)?;
    }
    write_report(args, &params, &recon.stats, memory.as_ref())?;
    stage.finish();
    conclude(args, &recon.stats, reporter);
    Ok(())
}

/// `recon --stream`: the scan read from its file tile by tile.
fn run_streamed(args: &ReconArgs, params: &ReconParams, reporter: &Reporter) -> anyhow::Result<()> {
    for (given, flag) in [
        (args.points_out.is_some(), "--points-out"),
        (args.cover_out.is_some(), "--cover-out"),
        (args.max_memory.is_some(), "--max-memory"),
    ] {
        if given {
            return Err(BadInput(format!(
                "{flag} needs the whole scan in memory, which --stream avoids: drop one of them"
            ))
            .into());
        }
    }
    let tiles = args.tiles.unwrap_or([1; 3]);
    let tiling = Tiling {
        tiles,
        halo: args.halo.unwrap_or_else(|| Tiling::default_halo(tiles)),
    };
    let scratch = scratch_directory(args);
    let source = ScanFile {
        options: args.read.read_options(&MemoryLimit::from_flag(None)),
        ignore_normals: args.estimate_normals,
        ..ScanFile::new(&args.input)
    };
    let bar = reporter.stage_bar("reconstructing");
    let progress = |stage| show_stage(&bar, stage);
    let stop = StopRequest::new();
    let result = reconstruct_streamed(
        &source,
        &SequentialStreamedTiles,
        params,
        &tiling,
        &scratch,
        &progress,
        &stop,
    );
    bar.finish_and_clear();
    let recon = result.map_err(|e| recon_error(args, None, e))?;
    describe(params, &recon.stats, reporter);
    let stage = reporter.stage("write");
    let options = WriteOptions {
        inputs: vec![args.input.clone()],
        ..WriteOptions::default()
    };
    io::write_mesh(&args.output, &recon.mesh, &options)?;
    write_report(args, params, &recon.stats, None)?;
    stage.finish();
    conclude(args, &recon.stats, reporter);
    Ok(())
}

/// Where `recon --stream` writes its tile files: `--scratch`, else the output's directory.
pub fn scratch_directory(args: &ReconArgs) -> std::path::PathBuf {
    match &args.scratch {
        Some(dir) => dir.clone(),
        None => match args.output.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        },
    }
}

/// A reconstruction's error for people: bad input (exit 2) named by the input file. A cover
/// over the memory `limit` says where the limit came from.
fn recon_error(args: &ReconArgs, limit: Option<&MemoryLimit>, e: ReconError) -> anyhow::Error {
    let input = args.input.display();
    let budget = if args.max_memory.is_some() {
        "--max-memory"
    } else {
        "memory limit"
    };
    if let Some(message) = cover_over_budget_message(&e, budget, "--tiles", "--eps") {
        let origin = match limit {
            Some(limit) if args.max_memory.is_none() => format!(" (the limit: {})", limit.origin()),
            _ => String::new(),
        };
        return anyhow::Error::from(BadInput(format!("{input}: {message}{origin}")));
    }
    if e.is_bad_input() {
        let hint = if matches!(e, ReconError::Flat) {
            " (without --trim off)"
        } else {
            ""
        };
        anyhow::Error::from(BadInput(format!("{input}: {e}{hint}")))
    } else {
        anyhow::Error::from(e).context(format!("{input}"))
    }
}

/// Stage times and measurements with `-v`, and the note or warning on the tolerance.
fn describe(params: &ReconParams, stats: &ReconStats, reporter: &Reporter) {
    for (name, time) in &stats.stages {
        reporter.detail(&format!("  {name:<24} {:>9.3} s", time.as_secs_f64()));
    }
    details(stats, reporter);
    match ToleranceNote::of(params, stats) {
        Some(note @ ToleranceNote::Raised { .. }) => {
            reporter.note(&note.message("--eps", "--noise"))
        }
        Some(note) => reporter.warn(&note.message("--eps", "--noise")),
        None => {}
    }
}

/// The report file, when asked for.
fn write_report(
    args: &ReconArgs,
    params: &ReconParams,
    stats: &ReconStats,
    memory: Option<&BudgetFit>,
) -> anyhow::Result<()> {
    if let Some(path) = &args.report {
        let text = serde_json::to_string_pretty(&report_json(args, params, stats, memory))?;
        io::write_atomic(path, std::slice::from_ref(&args.input), |w| {
            w.write_all(text.as_bytes())
        })?;
    }
    Ok(())
}

/// Notes and warnings on the surface, and the summary line.
fn conclude(args: &ReconArgs, s: &ReconStats, reporter: &Reporter) {
    if s.unseen_area_fraction > 0.0 && s.scan.one_view {
        reporter.note(&format!(
            "left out {:.1}% of the surface, where the scanner did not see the object (farther than {} sample spacing from every sample); \
             the scan is one view (its normals face one side), so gaps in it are not closed either; --trim off keeps a closed surface",
            100.0 * s.unseen_area_fraction,
            ONE_VIEW_NEAR,
        ));
    } else if s.unseen_area_fraction > 0.0 {
        reporter.note(&format!(
            "left out {:.1}% of the surface, where the scanner did not see the object (farther than {} sample spacings from every sample, over more than {:.0}% of the diagonal); \
             smaller holes are closed; --trim off keeps a closed surface",
            100.0 * s.unseen_area_fraction,
            UNSEEN_NEAR,
            100.0 * UNSEEN_REACH
        ));
    }
    let untrimmed = matches!(args.trim.as_deref(), None | Some("off"));
    if !s.watertight && untrimmed {
        if s.object_component_open && s.unseen_area_fraction == 0.0 {
            reporter.warn(
                "the surface is open: the scan does not enclose the object everywhere (one view, a LiDAR tile, an open base), \
                 so away from the samples the surface is extrapolated; --trim drops what lies farther than 3 sample spacings from every sample",
            );
        } else if !s.object_component_open && s.open_components > 0 {
            let sheets = match s.open_components {
                1 => "1 other component is an open sheet".to_owned(),
                n => format!("{n} other components are open sheets"),
            };
            reporter.warn(&format!(
                "the object's surface is closed, but {sheets} apart from it, most often surface around stray samples or outliers; components under 1% of the largest one's area are dropped"
            ));
        }
    }
    reporter.summary(&format!(
        "{} points{}{}: {} supports, {} inconsistent; {} triangles, {} component{}, {}; {:.2} s -> {}",
        s.points,
        if s.normals_estimated {
            " (normals estimated)"
        } else {
            ""
        },
        if s.outliers > 0 {
            format!(", {} outliers", s.outliers)
        } else {
            String::new()
        },
        s.supports,
        s.inconsistent_supports,
        s.triangles,
        s.components,
        if s.components == 1 { "" } else { "s" },
        if s.watertight { "watertight" } else { "open" },
        s.stages.iter().map(|(_, t)| t.as_secs_f64()).sum::<f64>(),
        args.output.display()
    ));
}

/// Checks the predicted peak of the run against `budget` before any heavy work (the points
/// are read: their count decides the default depth and the per-point cost). Over budget, a
/// coarser depth that fits replaces the default one, with a warning; a refusal is bad usage
/// with the estimate (nothing is written).
fn fit_budget(
    cloud: &PointCloud,
    budget: u64,
    params: &mut ReconParams,
    reporter: &Reporter,
) -> anyhow::Result<BudgetFit> {
    let fit = fit_memory_budget(cloud, params, budget)
        .map_err(|e| BadInput(e.message("--max-memory", "--depth")))?;
    match fit.lowering_message("--max-memory") {
        Some(warning) => {
            reporter.warn(&warning);
            params.depth = Some(fit.depth);
        }
        None => reporter.detail(&format!(
            "  memory: predicted peak {} at depth {}, within --max-memory {}",
            format_byte_size(fit.estimate),
            fit.depth,
            format_byte_size(budget)
        )),
    }
    Ok(fit)
}

/// The library's parameters for the command line's options; an option out of range is bad
/// input named by its flag.
fn params(args: &ReconArgs) -> anyhow::Result<ReconParams> {
    if args.tiles.is_some() {
        if args.method == ReconMethodArg::Graphcut {
            return Err(
                BadInput(format!("--tiles: {}", ReconError::NotTileable("graphcut"))).into(),
            );
        }
        if let Some(halo) = args.halo
            && !(0.0..=1.0).contains(&halo)
        {
            return Err(BadInput(format!(
                "--halo {halo} must lie in [0, 1] (a share of the longest bounding-box edge)"
            ))
            .into());
        }
    }
    let trim = match args.trim.as_deref() {
        None => TrimOption::Unseen,
        Some("off") => TrimOption::Off,
        Some("auto") => TrimOption::Auto,
        Some(text) => match text.parse::<f64>() {
            Ok(d) if d.is_finite() && d > 0.0 => TrimOption::Distance(d),
            _ => {
                return Err(BadInput(format!(
                    "--trim {text} must be a positive number, off, or no value (3 sample spacings)"
                ))
                .into());
            }
        },
    };
    let noise = match args.noise.as_deref() {
        None => None,
        Some("auto") => Some(NoiseOption::Auto),
        Some("off") => Some(NoiseOption::Off),
        Some(text) => match text.parse::<f64>() {
            Ok(v) => Some(NoiseOption::Value(v)),
            Err(_) => {
                return Err(BadInput(format!(
                    "--noise {text} must be auto, off or a non-negative number"
                ))
                .into());
            }
        },
    };
    let options = ReconOptions {
        method: match args.method {
            ReconMethodArg::Integrated => Method::Integrated,
            ReconMethodArg::Graphcut => Method::GraphCut,
            ReconMethodArg::Diffusion => Method::Diffusion,
            ReconMethodArg::Pu => Method::PartitionOfUnity,
        },
        eps: args.eps,
        noise,
        k: args.k,
        trim,
        depth: args.depth,
        normal_fit: args.normal_fit,
        position_fit: args.position_fit,
        normal_neighbours: args.normal_neighbours,
        refine: !args.no_refine,
        fill_pinholes: !args.keep_pinholes,
        seed: args.seed,
    };
    options.params().map_err(|e| {
        BadInput(format!(
            "--{} {} must be {}",
            e.option.replace('_', "-"),
            e.value,
            e.requirement
        ))
        .into()
    })
}

/// With `-v`: the stage counts.
fn details(s: &ReconStats, reporter: &Reporter) {
    reporter.detail(&format!(
        "  scan: spacing {:.2e}, noise {:.2e}, {} isolated samples{}; cover tolerance ε = {:.2e}",
        s.scan.spacing,
        s.scan.noise,
        s.scan.isolated_count,
        if s.scan.one_view {
            ", one view (normals face one side)"
        } else {
            ""
        },
        s.eps
    ));
    reporter.detail(&format!(
        "  cover: {} supports ({} over ε, largest error {:.2e}); graph mean degree {:.1}{}",
        s.supports,
        s.cover.supports_over_eps,
        s.cover.max_error,
        s.graph_mean_degree,
        s.predicted_peak_bytes.map_or(String::new(), |b| format!(
            "; predicted peak {}",
            format_byte_size(b)
        ))
    ));
    for t in &s.tiles {
        reporter.detail(&format!(
            "  tile {:?}: {} samples in its box, {} with the halo, {} supports, share of time {:.3} s",
            t.position,
            t.own_samples,
            t.samples,
            t.supports,
            t.time.as_secs_f64()
        ));
    }
    if s.cut.is_some() || s.inconsistent_supports > 0 {
        let kept = match s.confirmed_supports {
            0 => String::new(),
            n => format!(", {n} of them kept (their samples fit them)"),
        };
        reporter.detail(&format!(
            "  graph cut: {} supports inconsistent{kept}",
            s.inconsistent_supports
        ));
    }
    if let Some(d) = &s.diffusion {
        reporter.detail(&format!(
            "  diffusion: {} rounds, CG iterations {:?}, {} supports fitted",
            d.rounds, d.cg_iterations, d.fitted_supports
        ));
    }
    if let Some(p) = &s.polygonise {
        reporter.detail(&format!(
            "  polygonise: depth {}, step {:.3e}, {} cells visited, {} evaluations, {} pinholes filled; search {:.3} s (evaluations {:.3} s), extraction {:.3} s",
            s.depth,
            p.step,
            p.cells_visited,
            p.grid_evaluations,
            p.pinholes_filled,
            p.search_time.as_secs_f64(),
            p.evaluation_time.as_secs_f64(),
            p.extraction_time.as_secs_f64()
        ));
    }
    if let Some(r) = &s.refinement {
        reporter.detail(&format!(
            "  refine: {} vertices moved (mean {:.2e}, longest {:.2e}), {} out of reach, {} unfitted",
            r.moved, r.mean_move, r.longest_move, r.out_of_reach, r.unfitted
        ));
    }
    reporter.detail(&format!(
        "  result: {} vertices, {} triangles, {} components ({} dropped), Euler characteristic {}",
        s.vertices, s.triangles, s.components, s.dropped_components, s.euler_characteristic
    ));
}

fn report_json(
    args: &ReconArgs,
    params: &ReconParams,
    s: &ReconStats,
    memory: Option<&BudgetFit>,
) -> serde_json::Value {
    json!({
        "memory": memory.map(|m| json!({
            "budget_bytes": m.budget,
            "estimated_peak_bytes": m.estimate,
            "depth_lowered_from": m.lowered_from.map(|(depth, _)| depth),
        })),
        "input": args.input.display().to_string(),
        "output": args.output.display().to_string(),
        "method": s.method.name(),
        "points": s.points,
        "non_finite_points": s.non_finite_points,
        "normals_estimated": s.normals_estimated,
        "outliers": s.outliers,
        "supports": s.supports,
        "supports_over_eps": s.cover.supports_over_eps,
        "graph_mean_degree": s.graph_mean_degree,
        "predicted_peak_bytes": s.predicted_peak_bytes,
        "inconsistent_supports": s.inconsistent_supports,
        "confirmed_supports": s.confirmed_supports,
        "unseen_area_fraction": s.unseen_area_fraction,
        "one_view": s.scan.one_view,
        "tiles": s.tiles.iter().map(|t| json!({
            "position": t.position,
            "own_samples": t.own_samples,
            "samples": t.samples,
            "supports": t.supports,
            "seconds": t.time.as_secs_f64(),
        })).collect::<Vec<_>>(),
        "depth": s.depth,
        "eps_requested": params.cover.eps,
        "eps": s.eps,
        "noise": s.scan.noise,
        "noise_floor": s.noise_floor,
        "vertices": s.vertices,
        "triangles": s.triangles,
        "components": s.components,
        "dropped_components": s.dropped_components,
        "refined_vertices": s.refinement.as_ref().map(|r| r.moved),
        "watertight": s.watertight,
        "open_components": s.open_components,
        "object_component_open": s.object_component_open,
        "euler_characteristic": s.euler_characteristic,
        "stages_seconds": s.stages.iter().map(|(n, t)| json!({"stage": n, "seconds": t.as_secs_f64()})).collect::<Vec<_>>(),
        "total_seconds": s.stages.iter().map(|(_, t)| t.as_secs_f64()).sum::<f64>(),
    })
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}
