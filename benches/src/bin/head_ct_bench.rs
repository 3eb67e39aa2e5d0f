//! `head-ct-bench`: the skeletal sheet of a generated clinical head CT
//! (`sphcover_evaluation::head_ct_phantom`) by `sphcover skeleton` with default parameters,
//! with the non-maximum-suppression baseline beside it, timed and scored with
//! `sphcover_evaluation::head_sheet_metrics`.
//!
//! ```text
//! cargo build --release -p sphcover-cli
//! cargo run --release -p sphcover-benches --bin head-ct-bench -- --slice-ratios 3,5
//! ```
//!
//! The head is rendered on the clinical grid (1.5 mm slices on 0.957 mm pixels) and, for
//! each `--slice-ratios` value, on slices that many pixels thick; each rendering is written
//! as int16 NIfTI into the work folder and each method runs on it.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::Parser;
use sphcover_benches::command_template::split_words;
use sphcover_benches::markdown_table::{MarkdownTable, fixed};
use sphcover_benches::measured_run::run_measured;
use sphcover_benches::{command_line, release_dir, short_message, workspace_root};
use sphcover_core::TriMesh;
use sphcover_core::io::{self, NonFinitePolicy, ReadOptions};
use sphcover_evaluation::head_ct_phantom::{HeadCt, HeadCtParams, head_ct_phantom};
use sphcover_evaluation::head_sheet_metrics::{
    COVERED, HeadSheetMetrics, ON_BONE, THIN_VAULT, score_head_points, score_head_sheet,
};

/// Columns of the table.
const COLUMNS: usize = 15;

#[derive(Debug, Parser)]
#[command(
    name = "head-ct-bench",
    about = "Skeletal sheets of a generated clinical head CT by sphcover's methods; print time, memory and scores as a markdown table"
)]
struct Args {
    /// Slice spacing over in-plane voxel size of further renderings (e.g. 3,5); the clinical
    /// 1.5 mm slices on 0.957 mm pixels are always rendered.
    #[arg(long, value_delimiter = ',')]
    slice_ratios: Vec<f64>,
    /// The small test phantom (112 × 124 × 54) instead of the clinical size.
    #[arg(long)]
    small: bool,
    /// Seed of the scanner noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Methods of `sphcover skeleton --method`.
    #[arg(long, value_delimiter = ',', default_value = "ridge,nms")]
    methods: Vec<String>,
    /// The sphcover binary (default: the release build in the cargo target directory).
    #[arg(long)]
    sphcover: Option<PathBuf>,
    /// Extra arguments for `sphcover skeleton`, as one string.
    #[arg(long, default_value = "")]
    sphcover_args: String,
    /// Also write the table (with the command line) to this file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Where the phantoms and outputs go (default: `head-ct-bench` next to the release
    /// directory).
    #[arg(long)]
    work_dir: Option<PathBuf>,
    /// Time limit per run, in seconds.
    #[arg(long, default_value_t = 1800.0)]
    timeout: f64,
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
    if args.methods.is_empty() {
        bail!("no --methods");
    }
    let root = workspace_root();
    let exe = args
        .sphcover
        .clone()
        .unwrap_or_else(|| release_dir().join("sphcover"));
    if !exe.is_file() {
        bail!(
            "{} is not built (cargo build --release -p sphcover-cli)",
            exe.display()
        );
    }
    let extra = split_words(&args.sphcover_args).context("unbalanced quote in --sphcover-args")?;
    let work = args
        .work_dir
        .clone()
        .unwrap_or_else(|| release_dir().with_file_name("head-ct-bench"));
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    let work = std::path::absolute(&work)?;
    let timeout = Duration::from_secs_f64(args.timeout.max(0.0));

    let mut table = MarkdownTable::new([
        "grid",
        "method",
        "wall s",
        "CPU s",
        "peak MiB",
        "output",
        "on bone",
        "vault covered",
        "vault comp.",
        "holes > 20 mm (largest)",
        "holder covered",
        "holder apart",
        "holder holes (largest)",
        "comp.",
        "status",
    ]);
    let base = if args.small {
        HeadCtParams::small()
    } else {
        HeadCtParams::clinical()
    };
    let grids =
        std::iter::once(base).chain(args.slice_ratios.iter().map(|&r| base.with_slice_ratio(r)));
    for params in grids {
        let params = HeadCtParams {
            seed: args.seed,
            ..params
        };
        let [nx, ny, nz] = params.dims;
        let grid = format!("{nx}×{ny}×{nz}, {:.2} mm slices", params.slice);
        eprintln!("rendering {grid}");
        let ct = head_ct_phantom(&params);
        let input = work.join(format!("head_ct_{nx}x{ny}x{nz}.nii"));
        ct.write_nifti(&input)
            .with_context(|| format!("writing {}", input.display()))?;
        for method in &args.methods {
            let output = work.join(format!("head_ct_{nx}x{ny}x{nz}.{method}.ply"));
            let _ = std::fs::remove_file(&output);
            let mut argv = vec![
                exe.display().to_string(),
                "skeleton".into(),
                input.display().to_string(),
                "-o".into(),
                output.display().to_string(),
                "--method".into(),
                method.clone(),
            ];
            argv.extend(extra.iter().cloned());
            let run = run_measured(&argv, &root, timeout);
            let mut cells = vec![
                grid.clone(),
                method.clone(),
                fixed(Some(run.wall_seconds), 1),
                fixed(run.cpu_seconds, 1),
                fixed(run.peak_mib, 0),
            ];
            let status = match run.outcome.failure(timeout) {
                Some(why) => why,
                None if output.is_file() => score_output(&output, &ct, &mut cells),
                None => "exited 0 but wrote no output".to_string(),
            };
            cells.resize(COLUMNS - 1, "–".to_string());
            cells.push(short_message(&status, 120));
            eprintln!("  {}", cells.join(" | "));
            table.push(cells);
        }
    }
    let rendered = table.render();
    println!("{rendered}");
    if let Some(out) = &args.out {
        let text = format!(
            "Command: `{}`\n\nScores of `sphcover_evaluation::head_sheet_metrics` (voxel = in-plane \
             voxel): on bone = share of the output within {ON_BONE} voxels of bone or holder; vault \
             covered = share of the vault's bone voxels (bone ≤ {THIN_VAULT} voxels thick) within \
             {COVERED} voxels of the output; holes = boundary loops of the vault's sheet away from \
             the skull base and other bone; holder holes = boundary loops of the holder's sheet \
             but its outline.\n\n{rendered}",
            command_line()
        );
        std::fs::write(out, text).with_context(|| format!("writing {}", out.display()))?;
    }
    Ok(())
}

/// Reads the output (a mesh, or the baseline's point set), appends its size and scores to
/// `cells`, and returns the status.
fn score_output(output: &std::path::Path, ct: &HeadCt, cells: &mut Vec<String>) -> String {
    let opts = ReadOptions {
        non_finite: NonFinitePolicy::Drop,
        ..ReadOptions::default()
    };
    let geometry = match io::read_geometry(output, &opts) {
        Ok(g) => g,
        Err(e) => return format!("unreadable output: {e}"),
    };
    if geometry.triangles.is_empty() {
        let points = geometry.points.positions;
        cells.push(format!("{} points", points.len()));
        let m = score_head_points(&points, ct);
        cells.extend([
            format!("{:.3}", m.on_bone),
            format!("{:.3}", m.vault_covered),
            "–".into(),
            "–".into(),
            format!("{:.3}", m.holder_covered),
        ]);
        return "ok".to_string();
    }
    let mesh = TriMesh::new(geometry.points.positions, geometry.triangles);
    cells.push(format!("{} triangles", mesh.triangles.len()));
    let m: HeadSheetMetrics = score_head_sheet(&mesh, ct);
    let big_holes = m.vault_holes.iter().filter(|&&p| p > 20.0).count();
    cells.extend([
        format!("{:.3}", m.on_bone),
        format!("{:.3}", m.vault_covered),
        m.vault_components.to_string(),
        format!("{big_holes} ({:.0} mm)", m.largest_hole()),
        format!("{:.3}", m.holder_covered),
        if m.holder_separate { "yes" } else { "no" }.to_string(),
        format!(
            "{} ({:.0} mm)",
            m.holder_holes.len(),
            m.holder_holes.first().copied().unwrap_or(0.0)
        ),
        m.components.to_string(),
    ]);
    format!(
        "ok; {:.1}% of triangles share no edge",
        100.0 * m.isolated_triangles
    )
}
