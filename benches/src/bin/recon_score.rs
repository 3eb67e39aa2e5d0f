//! `recon-score REC GT`: scores one reconstructed mesh against a ground-truth mesh and prints
//! the scores as JSON (the same numbers `recon-bench` puts in its tables).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Parser;
use sphcover_core::io::{self, NonFinitePolicy, ReadOptions};
use sphcover_evaluation::recon_metrics::{ReconMetricsParams, score_reconstruction};

#[derive(Debug, Parser)]
#[command(
    name = "recon-score",
    about = "Score a reconstructed mesh against the ground truth"
)]
struct Args {
    /// The reconstruction.
    rec: PathBuf,
    /// The ground truth.
    gt: PathBuf,
    /// Samples per mesh.
    #[arg(short = 'n', long, default_value_t = 200_000)]
    samples: usize,
    /// Seed of the sampling.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> anyhow::Result<()> {
    let drop = ReadOptions {
        non_finite: NonFinitePolicy::Drop,
        ..ReadOptions::default()
    };
    let rec = io::read_mesh(&args.rec, &drop)
        .with_context(|| format!("reading {}", args.rec.display()))?;
    let gt = io::read_mesh(&args.gt, &ReadOptions::default())
        .with_context(|| format!("reading {}", args.gt.display()))?;
    let params = ReconMetricsParams {
        samples: args.samples,
        seed: args.seed,
        ..ReconMetricsParams::default()
    };
    let s = score_reconstruction(&rec, &gt, &params)?;
    let mut json = serde_json::json!({
        "rec": args.rec.display().to_string(),
        "gt": args.gt.display().to_string(),
        "samples": s.samples,
        "gt_bbox_diag": s.gt_diagonal,
        "vertices": s.topology.vertices,
        "triangles": s.topology.triangles,
        "components": s.topology.components,
        "largest_component_share": s.topology.largest_component_share,
        "boundary_edges": s.topology.boundary_edges,
        "nonmanifold_edges": s.topology.non_manifold_edges,
        "watertight": s.topology.watertight,
        "winding_consistent": s.topology.winding_consistent,
        "euler_characteristic": s.topology.euler_characteristic,
        "chamfer_l1": s.chamfer,
        "accuracy": s.accuracy,
        "completeness": s.completeness,
        "hausdorff": s.hausdorff,
        "hausdorff99": s.hausdorff99,
        "hausdorff99_rec_to_gt": s.hausdorff99_rec_to_gt,
        "hausdorff99_gt_to_rec": s.hausdorff99_gt_to_rec,
        "nc": s.normal_consistency,
        "nc_oriented": s.normal_consistency_oriented,
    });
    for f in &s.fscores {
        let tag = format!("{}", 100.0 * f.threshold);
        json[format!("precision@{tag}")] = f.precision.into();
        json[format!("recall@{tag}")] = f.recall.into();
        json[format!("fscore@{tag}")] = f.fscore.into();
    }
    let text = serde_json::to_string_pretty(&json)?;
    // A reader that stops early (`| head`) is not an error.
    match writeln!(std::io::stdout().lock(), "{text}") {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        written => Ok(written?),
    }
}
