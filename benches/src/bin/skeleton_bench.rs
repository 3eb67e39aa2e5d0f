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
//! generator's ground truth (`meta.json`, `gt_sheet.ply`, `gt_boundary.ply`, optionally
//! `gt_junction.ply`), the output is scored with `sphcover_evaluation::sheet_metrics` at τ = 1
//! voxel: coverage of the true sheet, spurious fraction (everywhere and away from the
//! rounded rims), the 95th-percentile distance away from the rims, components and Euler
//! characteristic against the expected ones, and how close the output comes to the true
//! boundary. Without a ground truth only cost and topology are shown. The ridge method
//! writes a triangle mesh, the NMS baseline a point set; both are scored.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::Parser;
use sphcover_benches::command_template::split_words;
use sphcover_benches::markdown_table::{MarkdownTable, fixed};
use sphcover_benches::measured_run::run_measured;
use sphcover_benches::{command_line, release_dir, short_message, workspace_root};
use sphcover_core::io::{self, NonFinitePolicy, ReadOptions};
use sphcover_core::{MeshTopology, TriMesh};
use sphcover_evaluation::sheet_metrics::{read_ground_truth, score_mesh, score_points};
use sphcover_evaluation::thin_phantoms::GroundTruthSheet;

/// Columns of the table.
const COLUMNS: usize = 14;

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
    /// A folder of phantom folders, each holding `ct_n*.nii.gz` (and optionally the ground
    /// truth: `meta.json`, `gt_sheet.ply`, `gt_boundary.ply`, `gt_junction.ply`); every CT file
    /// found is a phantom.
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
        "output",
        "coverage",
        "spurious",
        "spurious off rim",
        "p95 off rim vox",
        "comp. (true)",
        "χ (true)",
        "boundary reach vox",
        "status",
    ]);
    for (name, ct) in &phantoms {
        let truth = ct.parent().and_then(|dir| read_ground_truth(dir).ok());
        for method in &args.methods {
            let output = work.join(format!("{name}.{method}.ply"));
            let mut cells = vec![name.clone(), method.clone()];
            if !exe.is_file() {
                cells.extend(std::iter::repeat_n("–".to_string(), COLUMNS - 3));
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
            let status = match run.outcome.failure(timeout) {
                Some(why) => why,
                None if output.is_file() => score_output(&output, truth.as_ref(), &mut cells),
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
            "Command: `{}`\n\nScores of `sphcover_evaluation::sheet_metrics` at τ = 1 voxel \
             (distances in voxels; \"off rim\" = away from the rounded rims of the plates); \
             χ = Euler characteristic; true values from each phantom's `meta.json`.\n\n{rendered}",
            command_line()
        );
        std::fs::write(out, text).with_context(|| format!("writing {}", out.display()))?;
    }
    Ok(())
}

/// Reads the output (a mesh, or a point set from the NMS baseline), appends its size and
/// scores to `cells`, and returns the status.
fn score_output(
    output: &Path,
    truth: Option<&GroundTruthSheet>,
    cells: &mut Vec<String>,
) -> String {
    let opts = ReadOptions {
        non_finite: NonFinitePolicy::Drop,
        ..ReadOptions::default()
    };
    let geometry = match io::read_geometry(output, &opts) {
        Ok(g) => g,
        Err(e) => return format!("unreadable output: {e}"),
    };
    let is_mesh = !geometry.triangles.is_empty();
    let mesh = TriMesh::new(geometry.points.positions, geometry.triangles);
    cells.push(if is_mesh {
        format!("{} triangles", mesh.triangles.len())
    } else {
        format!("{} points", mesh.vertices.len())
    });
    let Some(truth) = truth else {
        let topo = MeshTopology::of(&mesh);
        cells.extend(std::iter::repeat_n("–".to_string(), 4));
        if is_mesh {
            cells.push(topo.components.to_string());
            cells.push(topo.euler_characteristic().to_string());
        }
        return "ok (no ground truth next to the CT file)".to_string();
    };
    let m = if is_mesh {
        score_mesh(&mesh, truth, 1.0)
    } else {
        score_points(&mesh.vertices, truth, 1.0)
    };
    cells.extend([
        format!("{:.3}", m.coverage),
        format!("{:.3}", m.spurious),
        format!("{:.3}", m.spurious_interior),
        format!("{:.2}", m.distance_interior_p95),
        format!("{} ({})", m.components, truth.components),
        format!(
            "{} ({})",
            m.euler_characteristic
                .map_or_else(|| "–".to_string(), |e| e.to_string()),
            truth.euler_characteristic
        ),
        format!("{:.2}", m.boundary_reach_mean),
    ]);
    "ok".to_string()
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

/// `p` relative to the workspace root unless absolute or present from here.
fn resolve(root: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() || p.exists() {
        p.to_path_buf()
    } else {
        root.join(p)
    }
}
