//! `skeleton-bench`: skeletal sheets of CT phantoms by `sphcover skeleton` with the ridge
//! method and with the non-maximum-suppression baseline, timed and scored side by side.
//!
//! ```text
//! cargo build --release -p sphcover-cli
//! cargo run --release -p sphcover-benches --bin skeleton-bench -- \
//!     --phantoms-dir path/to/phantoms --methods ridge,nms --out skeleton.md
//! ```
//!
//! A phantom is a CT volume (`.nii.gz`). When the folder of the volume holds the phantom
//! generator's `meta.json` (voxel size, expected components and Euler characteristic) and
//! `gt_sheet_mesh.ply` (the true mid-surface), the table compares the output with them:
//! two-sided Chamfer distance, 99th-percentile Hausdorff distance and F-score at one voxel,
//! all in voxels, from the same point-to-surface scoring as `recon-bench`. Sheet-specific
//! scores (boundary and junction-curve distances) belong to the skeleton's own metrics.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::Parser;
use sphcover_benches::command_template::split_words;
use sphcover_benches::markdown_table::{MarkdownTable, fixed};
use sphcover_benches::measured_run::{RunOutcome, run_measured};
use sphcover_benches::{command_line, release_dir, short_message, workspace_root};
use sphcover_core::MeshTopology;
use sphcover_core::io::{self, NonFinitePolicy, ReadOptions};
use sphcover_fixtures::recon_metrics::{ReconMetricsParams, score_reconstruction};

/// The phantom used when none is given (relative to the workspace root).
const DEFAULT_PHANTOM: &str = "t_junction-n000=fixtures/phantoms/t_junction_ct_n000.nii.gz";

#[derive(Debug, Parser)]
#[command(
    name = "skeleton-bench",
    about = "Extract skeletal sheets of CT phantoms with sphcover's methods; print time, memory and accuracy as a markdown table"
)]
struct Args {
    /// A CT phantom as NAME=PATH (repeatable).
    #[arg(long = "phantom")]
    phantoms: Vec<String>,
    /// A folder of phantom folders, each holding `ct_n*.nii.gz` (and optionally `meta.json`,
    /// `gt_sheet_mesh.ply`); every CT file found is a phantom.
    #[arg(long)]
    phantoms_dir: Option<PathBuf>,
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
    /// Where outputs go (default: `skeleton-bench` next to the release directory).
    #[arg(long)]
    work_dir: Option<PathBuf>,
    /// Samples per mesh for the distances.
    #[arg(long, default_value_t = 100_000)]
    samples: usize,
    /// Time limit per run, in seconds.
    #[arg(long, default_value_t = 1800.0)]
    timeout: f64,
}

/// What the phantom generator says about one phantom.
#[derive(Debug, Default)]
struct PhantomTruth {
    voxel_mm: Option<f64>,
    components: Option<u64>,
    euler: Option<i64>,
    sheet_mesh: Option<PathBuf>,
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
    let root = workspace_root();
    let mut phantoms: Vec<(String, PathBuf)> = Vec::new();
    for spec in &args.phantoms {
        let (name, path) = spec
            .split_once('=')
            .with_context(|| format!("--phantom wants NAME=PATH, got `{spec}`"))?;
        phantoms.push((name.to_string(), resolve(&root, Path::new(path))));
    }
    if let Some(dir) = &args.phantoms_dir {
        phantoms.extend(find_phantoms(&resolve(&root, dir))?);
    }
    if phantoms.is_empty() {
        let (name, path) = DEFAULT_PHANTOM.split_once('=').unwrap_or(("", ""));
        phantoms.push((name.to_string(), root.join(path)));
    }
    if args.methods.is_empty() {
        bail!("no --methods");
    }
    let exe = args
        .sphcover
        .clone()
        .map_or_else(|| release_dir().join("sphcover"), |p| resolve(&root, &p));
    let extra = split_words(&args.sphcover_args).context("unbalanced quote in --sphcover-args")?;
    let work = args
        .work_dir
        .clone()
        .unwrap_or_else(|| release_dir().with_file_name("skeleton-bench"));
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    let work = std::path::absolute(&work)?;
    let timeout = Duration::from_secs_f64(args.timeout.max(0.0));

    let mut table = MarkdownTable::new([
        "phantom",
        "method",
        "wall s",
        "CPU s",
        "peak MiB",
        "triangles",
        "comp. (expected)",
        "χ (expected)",
        "Chamfer vox",
        "H99 vox",
        "F@1 vox",
        "status",
    ]);
    for (name, ct) in &phantoms {
        let truth = phantom_truth(ct);
        for method in &args.methods {
            let output = work.join(format!("{name}.{method}.ply"));
            let mut cells = vec![name.clone(), method.clone()];
            if !exe.is_file() {
                cells.extend(std::iter::repeat_n("–".to_string(), 9));
                cells.push(format!(
                    "not built: {} (cargo build --release -p sphcover-cli)",
                    exe.display()
                ));
                table.push(cells);
                continue;
            }
            let _ = std::fs::remove_file(&output);
            let mut argv = vec![
                exe.display().to_string(),
                "skeleton".into(),
                ct.display().to_string(),
                "-o".into(),
                output.display().to_string(),
                "--method".into(),
                method.clone(),
            ];
            argv.extend(extra.iter().cloned());
            let run = run_measured(&argv, &root, timeout);
            cells.extend([
                fixed(Some(run.wall_seconds), 2),
                fixed(run.cpu_seconds, 2),
                fixed(run.peak_mib, 0),
            ]);
            let status = match &run.outcome {
                RunOutcome::Success if output.is_file() => {
                    score_sheet(&output, &truth, args.samples, &mut cells)
                }
                RunOutcome::Success => "exited 0 but wrote no output".to_string(),
                RunOutcome::Failed { code, message } => format!(
                    "failed ({}): {message}",
                    code.map_or_else(|| "signal".to_string(), |c| format!("exit {c}"))
                ),
                RunOutcome::TimedOut => format!("timed out after {} s", timeout.as_secs()),
                RunOutcome::NotStarted(m) => format!("not started: {m}"),
            };
            cells.resize(11, "–".to_string());
            cells.push(short_message(&status, 120));
            eprintln!("  {}", cells.join(" | "));
            table.push(cells);
        }
    }
    let rendered = table.render();
    println!("{rendered}");
    if let Some(out) = &args.out {
        let text = format!(
            "Command: `{}`\n\nDistances to the true mid-surface in voxels; χ = Euler \
             characteristic; expected values from each phantom's `meta.json`.\n\n{rendered}",
            command_line()
        );
        std::fs::write(out, text).with_context(|| format!("writing {}", out.display()))?;
    }
    Ok(())
}

/// Reads the output sheet, appends triangles, components, χ and the distances to `cells`,
/// and returns the status.
fn score_sheet(
    output: &Path,
    truth: &PhantomTruth,
    samples: usize,
    cells: &mut Vec<String>,
) -> String {
    let opts = ReadOptions {
        non_finite: NonFinitePolicy::Drop,
    };
    let sheet = match io::read_mesh(output, &opts) {
        Ok(m) => m,
        Err(e) => return format!("unreadable output: {e}"),
    };
    let topo = MeshTopology::of(&sheet);
    let with_expected = |got: String, expected: Option<String>| match expected {
        Some(e) => format!("{got} ({e})"),
        None => got,
    };
    cells.push(sheet.triangles.len().to_string());
    cells.push(with_expected(
        topo.components.to_string(),
        truth.components.map(|c| c.to_string()),
    ));
    cells.push(with_expected(
        topo.euler_characteristic().to_string(),
        truth.euler.map(|c| c.to_string()),
    ));
    let (Some(gt_path), Some(voxel)) = (&truth.sheet_mesh, truth.voxel_mm) else {
        return "ok (no ground-truth sheet next to the CT file)".to_string();
    };
    let gt = match io::read_mesh(gt_path, &ReadOptions::default()) {
        Ok(m) => m,
        Err(e) => return format!("ground truth unreadable: {e}"),
    };
    let diag = gt.bounding_box().diagonal();
    let params = ReconMetricsParams {
        samples,
        seed: 0,
        thresholds: vec![voxel / diag],
    };
    match score_reconstruction(&sheet, &gt, &params) {
        Ok(s) => {
            let to_vox = |pct: f64| pct / 100.0 * s.gt_diagonal / voxel;
            cells.push(format!("{:.3}", to_vox(s.chamfer)));
            cells.push(format!("{:.3}", to_vox(s.hausdorff99)));
            cells.push(fixed(s.fscores.first().map(|f| f.fscore), 4));
            "ok".to_string()
        }
        Err(e) => e.to_string(),
    }
}

/// Every `ct_n*.nii.gz` in the sub-folders of `dir`, named `FOLDER-nXXX`, in name order.
fn find_phantoms(dir: &Path) -> anyhow::Result<Vec<(String, PathBuf)>> {
    let mut found = Vec::new();
    let entries = std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))?;
    for entry in entries.flatten() {
        let folder = entry.path();
        let Ok(files) = std::fs::read_dir(&folder) else {
            continue;
        };
        for f in files.flatten() {
            let file_name = f.file_name().to_string_lossy().to_string();
            if let Some(level) = file_name
                .strip_prefix("ct_")
                .and_then(|s| s.strip_suffix(".nii.gz"))
            {
                let name = format!("{}-{level}", entry.file_name().to_string_lossy());
                found.push((name, f.path()));
            }
        }
    }
    found.sort();
    Ok(found)
}

/// What `meta.json` and `gt_sheet_mesh.ply` next to `ct` say, when they exist.
fn phantom_truth(ct: &Path) -> PhantomTruth {
    let Some(dir) = ct.parent() else {
        return PhantomTruth::default();
    };
    let meta: Option<serde_json::Value> = std::fs::read_to_string(dir.join("meta.json"))
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok());
    let sheet = dir.join("gt_sheet_mesh.ply");
    PhantomTruth {
        voxel_mm: meta.as_ref().and_then(|m| m["voxel_mm"].as_f64()),
        components: meta
            .as_ref()
            .and_then(|m| m["expected_components"].as_u64()),
        euler: meta
            .as_ref()
            .and_then(|m| m["expected_euler_characteristic"].as_i64()),
        sheet_mesh: sheet.is_file().then_some(sheet),
    }
}

/// `p` relative to the workspace root unless absolute or present from here.
fn resolve(root: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() || p.exists() {
        p.to_path_buf()
    } else {
        root.join(p)
    }
}
