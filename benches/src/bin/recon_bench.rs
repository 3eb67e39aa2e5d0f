//! `recon-bench`: synthetic scans of ground-truth meshes, reconstructed by `sphcover recon`
//! and by peers, timed and scored side by side in one markdown table.
//!
//! ```text
//! cargo build --release -p sphcover-cli
//! cargo run --release -p sphcover-benches --bin recon-bench -- \
//!     --sizes 100k --cases clean,noise025,outliers1 \
//!     --peer "open3d=python3 benches/peers/open3d_poisson.py {in} {out} --depth 10" \
//!     --out table.md
//! ```

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use clap::Parser;
use sphcover_benches::command_template::{CommandTemplate, split_words};
use sphcover_benches::markdown_table::{MarkdownTable, fixed, format_count, parse_count};
use sphcover_benches::measured_run::{RunMeasurement, run_measured};
use sphcover_benches::{command_line, release_dir, short_message, workspace_root};
use sphcover_core::io::{self, NonFinitePolicy, PlyEncoding, Precision, ReadOptions, WriteOptions};
use sphcover_core::{DVec3, TriMesh};
use sphcover_evaluation::ground_truth_meshes::{icosphere, plates_before_wall, torus_mesh};
use sphcover_evaluation::invented_surface::{InputPoints, InventedSurface, InventedSurfaceParams};
use sphcover_evaluation::recon_metrics::{ReconMetrics, ReconMetricsParams, score_reconstruction};
use sphcover_evaluation::scan_blocks::generate_scan_in_blocks;
use sphcover_evaluation::scan_simulation::{ScanCase, ScanParams, generate_scan};
use sphcover_evaluation::shadow_slits::{ShadowSlits, shadow_slits};

/// The ground truth used when no `--mesh` is given (relative to the workspace root).
const DEFAULT_MESH: &str = "bunny=fixtures/real/bunny00.off";

#[derive(Debug, Parser)]
#[command(
    name = "recon-bench",
    about = "Reconstruct synthetic scans with sphcover and peers; print time, memory and accuracy as a markdown table"
)]
struct Args {
    /// Point counts of the scans (k and M suffixes allowed).
    #[arg(long, value_delimiter = ',', default_value = "100k")]
    sizes: Vec<String>,
    /// Scan cases (default: the standard ones): clean, noise025, noise050, outliers1,
    /// outliers5, holes, gradient, normals30, normals60, scanner, combined,
    /// combined-no-outliers, combined030, all; and, only when named, single-view (one camera
    /// with a projector: the shadows of a raw range scan).
    #[arg(long, value_delimiter = ',')]
    cases: Vec<String>,
    /// Ground-truth mesh as NAME=PATH, or `sphere`, `torus` or `plates` (plates before a
    /// wall) for an analytic shape (repeatable); default `bunny=fixtures/real/bunny00.off`.
    #[arg(long = "mesh")]
    meshes: Vec<String>,
    /// The sphcover binary (default: the release build in the cargo target directory).
    #[arg(long)]
    sphcover: Option<PathBuf>,
    /// Extra arguments for `sphcover recon`, as one string.
    #[arg(long, default_value = "")]
    sphcover_args: String,
    /// Do not run sphcover (peers only).
    #[arg(long)]
    no_sphcover: bool,
    /// A peer as NAME=COMMAND with {in} and {out} placeholders (repeatable).
    #[arg(long = "peer")]
    peers: Vec<String>,
    /// Also write the table (with the command line) to this file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Where scans and outputs go (default: `recon-bench` next to the release directory).
    #[arg(long)]
    work_dir: Option<PathBuf>,
    /// Samples per mesh for the scores.
    #[arg(long, default_value_t = 200_000)]
    samples: usize,
    /// Seed of the scans and of the scoring.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Time limit per tool run, in seconds.
    #[arg(long, default_value_t = 1800.0)]
    timeout: f64,
    /// Runs of each tool per scan: the table gives the run of median wall time, with the
    /// range of all (the machine's speed drifts, so one run says little).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    repeat: u32,
    /// Camera positions of the virtual scanner, in the cases that use it (default 6).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    views: Option<u32>,
    /// Range noise of the virtual scanner, as a fraction of the diagonal (default 0.001;
    /// 0.0005 in single-view).
    #[arg(long)]
    range_noise: Option<f64>,
    /// Distance from each camera of the virtual scanner to its projector, in diagonals
    /// (default 0: no projector, no shadows; 0.15 in single-view).
    #[arg(long)]
    baseline: Option<f64>,
    /// Uniform outliers as a fraction of the surface points, in place of each case's own.
    #[arg(long)]
    outliers: Option<f64>,
    /// Generate each scan a block of 2^20 points at a time and write it as it goes
    /// (`scan_blocks`: memory holds one block, for scans larger than memory), instead of
    /// whole. Same distribution, other points than the whole generation for the same seed;
    /// the file is named `…-blocks.ply`. Not for the scanner cases.
    #[arg(long)]
    stream_scans: bool,
}

/// The scan parameters of `case` with the command line's overrides, and the suffix that
/// names the overrides in file names and tables (empty without any).
fn scan_params(case: ScanCase, size: usize, args: &Args) -> (ScanParams, String) {
    let mut params = case.params(size, args.seed);
    let mut suffix = String::new();
    if let Some(scanner) = params.scanner.as_mut() {
        if let Some(views) = args.views {
            scanner.views = views as usize;
            suffix += &format!("-views{views}");
        }
        if let Some(noise) = args.range_noise {
            scanner.range_noise = noise;
            suffix += &format!("-range{noise}");
        }
        if let Some(baseline) = args.baseline {
            scanner.projector_baseline = baseline;
            suffix += &format!("-baseline{baseline}");
        }
    }
    if let Some(outliers) = args.outliers {
        params.outliers = outliers;
        suffix += &format!("-outliers{outliers}");
    }
    (params, suffix)
}

/// Builds the command line of a tool for an input and an output path.
type CommandBuilder = Box<dyn Fn(&Path, &Path) -> Vec<String>>;

/// One tool to run on every scan.
struct Tool {
    name: String,
    command: CommandBuilder,
    /// Why it cannot run at all, if so.
    unavailable: Option<String>,
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
    let sizes: Vec<usize> = args
        .sizes
        .iter()
        .map(|s| parse_count(s).with_context(|| format!("bad size `{s}` (e.g. 100k, 362k, 1M)")))
        .collect::<anyhow::Result<_>>()?;
    let cases: Vec<ScanCase> = if args.cases.is_empty() {
        ScanCase::ALL.to_vec()
    } else {
        args.cases
            .iter()
            .map(|c| {
                ScanCase::from_name(c).with_context(|| {
                    let names: Vec<_> = ScanCase::ALL
                        .iter()
                        .chain(&ScanCase::EXTRA)
                        .map(|c| c.name())
                        .collect();
                    format!("unknown case `{c}`; known: {}", names.join(", "))
                })
            })
            .collect::<anyhow::Result<_>>()?
    };
    let mesh_specs = if args.meshes.is_empty() {
        vec![DEFAULT_MESH.to_string()]
    } else {
        args.meshes.clone()
    };
    let mut meshes = Vec::new();
    for spec in &mesh_specs {
        let Some((name, path)) = spec.split_once('=') else {
            let mesh = builtin_mesh(spec).with_context(|| {
                format!("--mesh wants NAME=PATH or one of sphere, torus, plates; got `{spec}`")
            })?;
            meshes.push((
                spec.clone(),
                PathBuf::from(format!("(analytic {spec})")),
                mesh,
            ));
            continue;
        };
        let path = resolve(&root, Path::new(path));
        let mesh = io::read_mesh(&path, &ReadOptions::default())
            .with_context(|| format!("reading ground truth {}", path.display()))?;
        meshes.push((name.to_string(), path, mesh));
    }

    let mut tools = Vec::new();
    if !args.no_sphcover {
        let exe = args
            .sphcover
            .clone()
            .map_or_else(|| release_dir().join("sphcover"), |p| resolve(&root, &p));
        let extra =
            split_words(&args.sphcover_args).context("unbalanced quote in --sphcover-args")?;
        let unavailable = (!exe.is_file()).then(|| {
            format!(
                "not built: {} (cargo build --release -p sphcover-cli)",
                exe.display()
            )
        });
        tools.push(Tool {
            name: "sphcover".into(),
            command: Box::new(move |i: &Path, o: &Path| {
                let mut v = vec![
                    exe.display().to_string(),
                    "recon".into(),
                    i.display().to_string(),
                    "-o".into(),
                    o.display().to_string(),
                ];
                v.extend(extra.iter().cloned());
                v
            }),
            unavailable,
        });
    }
    for spec in &args.peers {
        let t = CommandTemplate::parse(spec)?;
        tools.push(Tool {
            name: t.name.clone(),
            command: Box::new(move |i: &Path, o: &Path| t.expand(i, o)),
            unavailable: None,
        });
    }
    if tools.is_empty() {
        bail!("nothing to run: --no-sphcover and no --peer");
    }

    let work = args
        .work_dir
        .clone()
        .unwrap_or_else(|| release_dir().with_file_name("recon-bench"));
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    // Tools run in the workspace root: hand them absolute paths.
    let work = std::path::absolute(&work)?;
    let timeout = Duration::from_secs_f64(args.timeout.max(0.0));
    let score_params = ReconMetricsParams {
        samples: args.samples,
        seed: args.seed,
        ..ReconMetricsParams::default()
    };
    let invented_params = InventedSurfaceParams {
        samples: args.samples,
        seed: args.seed,
        ..InventedSurfaceParams::default()
    };

    let mut table = MarkdownTable::new([
        "mesh",
        "case",
        "points",
        "tool",
        "wall s",
        "CPU s",
        "peak MiB",
        "steal %",
        "Chamfer %",
        "H99 %",
        "NC",
        "F@0.25%",
        "F@0.5%",
        "F@1%",
        "comp.",
        "watertight",
        "invented %",
        "uncovered %",
        "slits bridged",
        "status",
    ]);
    for (mesh_name, _, gt) in &meshes {
        for &size in &sizes {
            for &case in &cases {
                let t0 = Instant::now();
                let (params, mut suffix) = scan_params(case, size, &args);
                if args.stream_scans {
                    suffix.push_str("-blocks");
                }
                let stem = format!("{mesh_name}-{}{suffix}-{}", case.name(), format_count(size));
                let input = work.join(format!("{stem}.ply"));
                // The scan's points, to measure invented surface against (not kept for a scan
                // generated a block at a time, which may not fit in memory).
                let mut input_points = None;
                let points = if args.stream_scans {
                    write_scan_in_blocks(gt, &params, &input)?
                } else {
                    let scan = generate_scan(gt, &params)
                        .with_context(|| format!("generating {} of {mesh_name}", case.name()))?;
                    let wopts = WriteOptions {
                        ply_encoding: PlyEncoding::BinaryLittleEndian,
                        precision: Precision::F32,
                        inputs: Vec::new(),
                    };
                    io::write_point_cloud(&input, &scan.cloud, &wopts)
                        .with_context(|| format!("writing {}", input.display()))?;
                    // As written: the file holds `f32` coordinates.
                    let written: Vec<DVec3> = scan
                        .cloud
                        .positions
                        .iter()
                        .map(|p| p.as_vec3().as_dvec3())
                        .collect();
                    input_points =
                        Some(InputPoints::new(&written).map_err(|e| format!("scan points: {e}")));
                    scan.cloud.len()
                };
                eprintln!(
                    "[{stem}] {points} points generated in {:.2} s",
                    t0.elapsed().as_secs_f64()
                );
                for tool in &tools {
                    let output = work.join(format!("{stem}.{}.ply", tool.name));
                    let row = run_tool(
                        tool,
                        &input,
                        &output,
                        gt,
                        &score_params,
                        input_points.as_ref().map(|p| (p, &invented_params)),
                        has_shadows(&params).then_some(&params),
                        &root,
                        timeout,
                        args.repeat,
                    );
                    let case_name = format!("{}{suffix}", case.name());
                    let cells = row_cells(mesh_name, &case_name, points, &tool.name, &row);
                    eprintln!("  {}", cells.join(" | "));
                    table.push(cells);
                }
            }
        }
    }

    let rendered = table.render();
    println!("{rendered}");
    if let Some(out) = &args.out {
        let gt_list: Vec<String> = meshes
            .iter()
            .map(|(n, p, m)| {
                format!(
                    "{n} = {} ({} vertices, {} triangles)",
                    p.display(),
                    m.vertices.len(),
                    m.triangles.len()
                )
            })
            .collect();
        let text = format!(
            "Command: `{}`\n\nGround truth: {}. Scores on {} area-uniform samples per mesh; \
             lengths in % of the ground truth's bounding-box diagonal; NC = normal \
             consistency; comp. = connected components; invented = % of the output's area \
             farther than 3 median sample spacings of the scan from every scan point; uncovered \
             = % of the scan's points (50,000 of them at most) farther than 2 spacings from \
             the output; slits \
             bridged = shadow slits of the scan's camera rows, 1–2 and 3–5 rays wide, that the \
             output joins across, of all such rows, and in brackets the bridges that are not \
             the truth's (where it leaves the slit open, or farther than 2 rays from it) and \
             the rows whose end samples the output does not come within 3 rays of (scans \
             with a projector).\n\n{rendered}",
            command_line(),
            gt_list.join("; "),
            args.samples
        );
        std::fs::write(out, text).with_context(|| format!("writing {}", out.display()))?;
    }
    Ok(())
}

/// What one tool did on one scan.
struct ToolResult {
    /// The run of median wall time (or the first that failed).
    run: Option<RunMeasurement>,
    /// The shortest and longest wall time, when the tool ran more than once.
    wall_range: Option<(f64, f64)>,
    scores: Result<ReconMetrics, String>,
    /// Invented surface against the scan's points, when they were at hand.
    invented: Option<Result<InventedSurface, String>>,
    /// The scan's shadow slits and which the output bridges (scans with a projector).
    slits: Option<Result<ShadowSlits, String>>,
}

/// A bridge across a shadow slit farther than this from the truth, in rays of the camera's
/// grid (about sample spacings), is made up; nearer, it follows a face the shadow fell on
/// (the scan's range noise is under a spacing).
const OFF_TRUTH_RAYS: f64 = 2.0;

/// Whether the scan `params` describe has the shadows of a projector.
fn has_shadows(params: &ScanParams) -> bool {
    params.scanner.is_some_and(|s| s.projector_baseline > 0.0)
}

/// Generates the scan `params` describe a block at a time ([`generate_scan_in_blocks`]) into
/// a binary PLY of `float` positions and normals at `path`, as `write_point_cloud` writes
/// whole scans; returns the number of points.
fn write_scan_in_blocks(gt: &TriMesh, params: &ScanParams, path: &Path) -> anyhow::Result<usize> {
    const BLOCK: usize = 1 << 20;
    let surface = params.count;
    let per_block = |n: usize| n + (params.outliers * n as f64).round() as usize;
    let total = (surface / BLOCK) * per_block(BLOCK) + per_block(surface % BLOCK);
    let header = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {total}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nend_header\n"
    );
    io::write_atomic(path, &[], |w| {
        w.write_all(header.as_bytes())?;
        let mut bytes = Vec::new();
        let written = generate_scan_in_blocks(gt, params, BLOCK, |block| {
            bytes.clear();
            let normals = block.normals.as_deref().unwrap_or_default();
            for (p, n) in block.positions.iter().zip(normals) {
                for v in p.to_array().into_iter().chain(n.to_array()) {
                    bytes.extend_from_slice(&(v as f32).to_le_bytes());
                }
            }
            w.write_all(&bytes)
        })
        .map_err(|e| std::io::Error::other(e.to_string()))??;
        if written != total {
            return Err(std::io::Error::other(format!(
                "{written} points generated, {total} declared"
            )));
        }
        Ok(())
    })
    .with_context(|| format!("writing {}", path.display()))?;
    Ok(total)
}

/// Runs `tool` on `input` `repeat` times (stopping at a failure) and scores the output,
/// against the ground truth, given the scan's points for invented surface, and given the
/// parameters of a scan with shadows for the slits it bridges.
fn run_tool(
    tool: &Tool,
    input: &Path,
    output: &Path,
    gt: &TriMesh,
    params: &ReconMetricsParams,
    invented: Option<(&Result<InputPoints, String>, &InventedSurfaceParams)>,
    shadowed_scan: Option<&ScanParams>,
    cwd: &Path,
    timeout: Duration,
    repeat: u32,
) -> ToolResult {
    if let Some(why) = &tool.unavailable {
        return ToolResult {
            run: None,
            wall_range: None,
            scores: Err(why.clone()),
            invented: None,
            slits: None,
        };
    }
    let mut runs = Vec::new();
    for _ in 0..repeat {
        // A stale output of an earlier run must not be scored as this run's.
        let _ = std::fs::remove_file(output);
        let run = run_measured(&(tool.command)(input, output), cwd, timeout);
        let failed = !run.succeeded();
        runs.push(run);
        if failed {
            break;
        }
    }
    let wall_range = (runs.len() > 1).then(|| {
        runs.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
            (lo.min(r.wall_seconds), hi.max(r.wall_seconds))
        })
    });
    let run = median_or_failed(runs);
    let (scores, invented, slits) = match run.outcome.failure(timeout) {
        Some(why) => (Err(why), None, None),
        None if !output.is_file() => (Err("exited 0 but wrote no output".into()), None, None),
        None => {
            let opts = ReadOptions {
                non_finite: NonFinitePolicy::Drop,
                ..ReadOptions::default()
            };
            match io::read_mesh(output, &opts) {
                Err(e) => (Err(format!("unreadable output: {e}")), None, None),
                Ok(rec) => (
                    score_reconstruction(&rec, gt, params).map_err(|e| e.to_string()),
                    invented.map(|(points, p)| {
                        let points = points.as_ref().map_err(Clone::clone)?;
                        points.score(&rec, p).map_err(|e| e.to_string())
                    }),
                    shadowed_scan
                        .map(|scan| shadow_slits(gt, scan, &rec).map_err(|e| e.to_string())),
                ),
            }
        }
    };
    ToolResult {
        run: Some(run),
        wall_range,
        scores,
        invented,
        slits,
    }
}

/// The failed run if one failed (the last), else the run of median wall time (the slower
/// of the middle two for an even count).
fn median_or_failed(mut runs: Vec<RunMeasurement>) -> RunMeasurement {
    if runs.last().is_some_and(|r| !r.succeeded()) {
        return runs.pop().expect("a last run");
    }
    runs.sort_by(|a, b| a.wall_seconds.total_cmp(&b.wall_seconds));
    let middle = runs.len() / 2;
    runs.swap_remove(middle)
}

fn row_cells(mesh: &str, case: &str, points: usize, tool: &str, r: &ToolResult) -> Vec<String> {
    let mut cells = vec![
        mesh.to_string(),
        case.to_string(),
        points.to_string(),
        tool.to_string(),
        wall_cell(r),
        fixed(r.run.as_ref().and_then(|m| m.cpu_seconds), 2),
        fixed(r.run.as_ref().and_then(|m| m.peak_mib), 0),
        fixed(r.run.as_ref().and_then(|m| m.steal_percent), 0),
    ];
    match &r.scores {
        Ok(s) => cells.extend([
            format!("{:.4}", s.chamfer),
            format!("{:.4}", s.hausdorff99),
            format!("{:.4}", s.normal_consistency),
            fixed(s.fscore_at(0.0025), 4),
            fixed(s.fscore_at(0.005), 4),
            fixed(s.fscore_at(0.01), 4),
            s.topology.components.to_string(),
            if s.topology.watertight { "yes" } else { "no" }.to_string(),
            input_score_cell(r, |s| s.invented_fraction),
            input_score_cell(r, |s| s.uncovered_fraction),
            slits_cell(r),
            "ok".to_string(),
        ]),
        Err(e) => {
            cells.extend(std::iter::repeat_n("–".to_string(), 11));
            cells.push(short_message(e, 120));
        }
    }
    cells
}

/// A share from the scores against the scan's points (`share` of them), in %, when they
/// were measured.
fn input_score_cell(r: &ToolResult, share: impl Fn(&InventedSurface) -> f64) -> String {
    fixed(
        r.invented
            .as_ref()
            .and_then(|s| s.as_ref().ok())
            .map(|s| 100.0 * share(s)),
        2,
    )
}

/// The shadow-slit rows 1–2 and 3–5 rays wide that the output bridges, of all such rows, and
/// in brackets how many of those bridges are not the truth's ([`OFF_TRUTH_RAYS`]) and how
/// many rows lack the output's surface at an end, when they were measured.
fn slits_cell(r: &ToolResult) -> String {
    match &r.slits {
        Some(Ok(slits)) => {
            let cell = |lo: usize, hi: usize| {
                let (rows, bridged) = slits.bridged_within(lo, hi);
                let made_up = slits.bridged_off_truth(lo, hi, OFF_TRUTH_RAYS);
                let unheld = slits.unheld_within(lo, hi);
                format!("{bridged}/{rows} ({made_up}, {unheld})")
            };
            format!("{}, {}", cell(1, 2), cell(3, 5))
        }
        Some(Err(e)) => short_message(e, 60),
        None => "–".to_string(),
    }
}

/// The wall time of the reported run, with the range over all runs when there were several.
fn wall_cell(r: &ToolResult) -> String {
    let wall = fixed(r.run.as_ref().map(|m| m.wall_seconds), 2);
    match r.wall_range {
        Some((lo, hi)) => format!("{wall} ({lo:.2}–{hi:.2})"),
        None => wall,
    }
}

/// The analytic ground truths: a sphere of radius 0.5 (81,920 triangles) and a torus of
/// radii 0.35 and 0.15 (65,536 triangles), fine enough that their facets are far below the
/// errors measured; and plates floating before a wall, whose single view has shadow slits
/// the truth leaves open ([`plates_before_wall`]).
fn builtin_mesh(name: &str) -> Option<TriMesh> {
    match name {
        "sphere" => Some(icosphere(DVec3::ZERO, 0.5, 6)),
        "torus" => Some(torus_mesh(0.35, 0.15, 256, 128)),
        "plates" => Some(plates_before_wall()),
        _ => None,
    }
}

/// `p` relative to the workspace root unless absolute or present from here, so the harness
/// runs from anywhere.
fn resolve(root: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() || p.exists() {
        p.to_path_buf()
    } else {
        root.join(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_change_the_scanner_cases_and_name_themselves() {
        let args = Args::parse_from([
            "recon-bench",
            "--views",
            "12",
            "--range-noise",
            "0.0001",
            "--baseline",
            "0.1",
            "--outliers",
            "0.05",
        ]);
        let (scanner, suffix) = scan_params(ScanCase::Scanner, 1000, &args);
        let camera = scanner.scanner.expect("the scanner case scans");
        assert_eq!((camera.views, camera.range_noise), (12, 0.0001));
        assert_eq!(camera.projector_baseline, 0.1);
        assert_eq!(scanner.outliers, 0.05);
        assert_eq!(suffix, "-views12-range0.0001-baseline0.1-outliers0.05");
        // Without a scanner, only the outliers change.
        let (clean, suffix) = scan_params(ScanCase::Clean, 1000, &args);
        assert!(clean.scanner.is_none());
        assert_eq!(suffix, "-outliers0.05");
        let defaults = Args::parse_from(["recon-bench"]);
        assert_eq!(
            scan_params(ScanCase::Scanner, 1000, &defaults),
            (ScanCase::Scanner.params(1000, 0), String::new())
        );
        let (single, _) = scan_params(ScanCase::SingleView, 1000, &defaults);
        assert_eq!(single.scanner.expect("a scan").projector_baseline, 0.15);
    }
}
