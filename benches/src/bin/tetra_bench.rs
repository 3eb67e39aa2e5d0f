//! `tetra-bench`: `sphcover_tetra::RegularTriangulation` against CGAL's
//! `Regular_triangulation_3`, back to back on the same weighted points, with a check that both
//! give the same tetrahedra.
//!
//! ```text
//! cargo build --release -p sphcover-benches --bin tetra-bench
//! target/release/tetra-bench --sizes 20k                       # a quick check
//! target/release/tetra-bench --sizes 1m --sets random,octree --runs 3 --out tetra-1m.md
//! target/release/tetra-bench --sizes 1m --no-cgal --threads 1,2,4   # ours alone
//! ```
//!
//! For each set (`--sets`: `random`, uniform centres with weights up to
//! `(--random-radius × spacing)²`, about 0.2% of them hidden at the default 0.5; `octree`,
//! the graded octree cover of a torus of the `sphcover-tetra` benchmark, full of exact ties;
//! see `sphcover_benches::sphere_sets`) and size (`--sizes`), the spheres are written to the
//! work folder (default `target/tetra-bench`) and then:
//!
//! 1. CGAL: `benches/peers/cgal_regular.cpp`, compiled here with
//!    `g++ -O3 -DNDEBUG -std=c++17 -frounding-math … -lgmp -lmpfr` into the work folder when
//!    the binary is missing or older than the source (CGAL 5.5 headers: `apt-get install
//!    libcgal-dev`), builds the triangulation `--runs` times (kernel
//!    `Exact_predicates_inexact_constructions_kernel`, sequential), timing `insert` alone, and
//!    writes its finite cells as input indices;
//! 2. ours: `RegularTriangulation::new` with the default parameters, timed alone, `--runs`
//!    times in a rayon pool of each `--threads` size. The finite tetrahedra (sorted
//!    quadruples, sorted) are compared with CGAL's, and every slot of every run is
//!    fingerprinted (FNV-1a of `tet_slots()`, freed slots included): the slot order must be
//!    the same whatever the thread count;
//! 3. memory (unless `--no-memory`): this binary runs itself on the written set in a child
//!    process (hidden `--memory-child`) at the largest thread count, resets its peak
//!    resident memory once the set is read, triangulates, and reports the growth of the peak
//!    per sphere. CGAL's figure is its process's peak after the runs minus its peak once the
//!    input was read.
//!
//! The table gives the median wall time of the runs with their range and their median CPU
//! time; the header has the command line and the load average before and after, since a
//! shared machine's load changes the wall times (a sequential run whose CPU time is well
//! below its wall time waited for a core).

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Parser;
use sphcover_benches::cgal_peer::{CgalRun, cgal_peer_binary, run_cgal_peer};
use sphcover_benches::markdown_table::{MarkdownTable, fixed, format_count, parse_count};
use sphcover_benches::sphere_sets::{
    RANDOM_RADIUS, SphereSet, SphereSetKind, read_spheres, write_spheres,
};
use sphcover_benches::tet_lists::{canonical, differences, fnv1a};
use sphcover_benches::{command_line, release_dir, short_message};
use sphcover_core::this_process::{peak_resident_bytes, process_cpu_seconds, reset_peak_resident};
use sphcover_tetra::{RegularTriangulation, TriangulationParams};

#[derive(Debug, Parser)]
#[command(
    name = "tetra-bench",
    about = "Time sphcover's regular triangulation against CGAL's Regular_triangulation_3 on the same spheres, check both give the same tetrahedra, print a markdown table"
)]
struct Args {
    /// Numbers of spheres (`20k`, `1m`, …; the octree cover has about that many).
    #[arg(long, value_delimiter = ',', default_value = "20k,100k,1m")]
    sizes: Vec<String>,
    /// Sphere sets: `random`, `octree`.
    #[arg(long, value_delimiter = ',', default_value = "random,octree")]
    sets: Vec<String>,
    /// Seed of the `random` set.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Largest radius of the `random` set's spheres, in mean spacings `N^(-1/3)`: weights are
    /// uniform in `[0, (F·s)²]`. Larger values hide more points.
    #[arg(long, value_name = "F", default_value_t = RANDOM_RADIUS)]
    random_radius: f64,
    /// Constructions per tool, set and thread count; the table gives the median time.
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Rayon pool sizes our triangulation runs in.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// Run ours alone (no compiler or CGAL needed).
    #[arg(long)]
    no_cgal: bool,
    /// Skip the child process that measures our peak memory.
    #[arg(long)]
    no_memory: bool,
    /// Also write the table (with the command line) to this file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Where the sets, CGAL's binary and its output go (default: `tetra-bench` next to the
    /// release directory).
    #[arg(long)]
    work_dir: Option<PathBuf>,
    /// Internal: triangulate this sphere file once on `--threads` threads and print the peak
    /// memory it took.
    #[arg(long, hide = true)]
    memory_child: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = match &args.memory_child {
        Some(file) => memory_child(file, args.threads.first().copied().unwrap_or(1)),
        None => run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Our runs at one thread count.
#[derive(Debug)]
struct OurRuns {
    threads: usize,
    /// Wall seconds per run.
    times: Vec<f64>,
    /// CPU seconds per run (all threads of this process).
    cpu_times: Vec<f64>,
    /// FNV-1a of the slots, per run.
    slot_prints: Vec<u64>,
    /// Tetrahedra only in ours and only in CGAL's (or in the first thread count's, without
    /// CGAL).
    diff: Option<(usize, usize)>,
}

/// One row of the table.
#[derive(Debug)]
struct Row {
    set: &'static str,
    spheres: usize,
    hidden: usize,
    finite_tets: usize,
    cgal: Option<Result<CgalRun, String>>,
    ours: Vec<OurRuns>,
    memory: Option<Result<f64, String>>,
}

fn run(args: &Args) -> anyhow::Result<()> {
    if args.runs == 0 {
        bail!("--runs must be at least 1");
    }
    if args.threads.is_empty() || args.threads.contains(&0) {
        bail!("--threads needs positive pool sizes");
    }
    if !(args.random_radius.is_finite() && args.random_radius >= 0.0) {
        bail!("--random-radius must be finite and non-negative");
    }
    let kinds = args
        .sets
        .iter()
        .map(|s| {
            SphereSetKind::from_name(s)
                .with_context(|| format!("unknown set {s:?} (random, octree)"))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let sizes = args
        .sizes
        .iter()
        .map(|s| parse_count(s).with_context(|| format!("bad size {s:?} (e.g. 20k, 1m)")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let work = args
        .work_dir
        .clone()
        .unwrap_or_else(|| release_dir().with_file_name("tetra-bench"));
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    let work = std::path::absolute(&work)?;
    let cgal = if args.no_cgal {
        None
    } else {
        Some(cgal_peer_binary(&work)?)
    };
    let load_before = load_average();

    let mut rows = Vec::new();
    let mut notes = Vec::new();
    for &kind in &kinds {
        for &n in &sizes {
            let start = Instant::now();
            let set = kind.generate(n, args.seed, args.random_radius);
            eprintln!(
                "{} {}: {} spheres ({}) in {:.1} s",
                kind.name(),
                format_count(n),
                set.len(),
                set.description,
                start.elapsed().as_secs_f64()
            );
            notes.push(format!(
                "{} {}: {}",
                kind.name(),
                set.len(),
                set.description
            ));
            let stem = match kind {
                SphereSetKind::Random => {
                    format!("random-{n}-seed{}-r{}", args.seed, args.random_radius)
                }
                SphereSetKind::Octree => format!("octree-{n}"),
            };
            let spheres_file = work.join(format!("{stem}.spheres.bin"));
            write_spheres(&spheres_file, &set)
                .with_context(|| format!("writing {}", spheres_file.display()))?;
            let row = measure(
                kind,
                &set,
                &spheres_file,
                &work.join(format!("{stem}.cgal-tets.bin")),
                cgal.as_deref(),
                args,
            )?;
            eprintln!("  {}", row_cells(&row, &args.threads).join(" | "));
            rows.push(row);
        }
    }

    let mut header = vec![
        "set".to_string(),
        "spheres".into(),
        "hidden".into(),
        "finite tets".into(),
        "CGAL s".into(),
    ];
    header.extend(args.threads.iter().map(|t| format!("ours s, {t} thr")));
    header.extend(
        args.threads
            .iter()
            .map(|t| format!("ours/CGAL wall (CPU), {t} thr")),
    );
    header.extend([
        "same tets as CGAL".to_string(),
        "slot order identical".into(),
        format!(
            "ours B/sphere ({} thr)",
            args.threads.iter().max().unwrap_or(&1)
        ),
        "CGAL B/sphere".into(),
    ]);
    let mut table = MarkdownTable::new(header);
    for row in &rows {
        table.push(row_cells(row, &args.threads));
    }
    let runs: Vec<String> = rows.iter().map(runs_line).collect();
    let fingerprints: Vec<String> = rows
        .iter()
        .map(|r| {
            let prints: Vec<String> = r
                .ours
                .iter()
                .map(|o| format!("{} thr {}", o.threads, hex_list(&o.slot_prints)))
                .collect();
            format!("- {} {}: {}", r.set, r.spheres, prints.join("; "))
        })
        .collect();
    let text = format!(
        "Command: `{}`\n\nLoad average before: {}; after: {} ({} cores).\n\n{}\n\
         Times: median wall seconds (and range) of {} constructions, then their median CPU \
         seconds (all threads), the construction alone (CGAL: \
         `insert` of the range with input indices, spatial sort included; ours: \
         `RegularTriangulation::new`). Hidden: points that are not vertices. Same tets: the \
         finite tetrahedra as sets of input indices, at every thread count. Slot order \
         identical: FNV-1a of `tet_slots()` equal over every run and thread count. B/sphere: \
         growth of the peak resident memory during the construction, per sphere (ours in a \
         child process; CGAL's over its runs, with its copies of the input inside `insert` \
         and the hidden points its cells keep).\n\nSets:\n{}\n\nEvery run, wall s / CPU s (CPU \
         well below wall: the run waited for a core):\n{}\n\nSlot fingerprints:\n{}\n",
        command_line(),
        load_before,
        load_average(),
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        table.render(),
        args.runs,
        notes
            .iter()
            .map(|n| format!("- {n}"))
            .collect::<Vec<_>>()
            .join("\n"),
        runs.join("\n"),
        fingerprints.join("\n"),
    );
    println!("{text}");
    if let Some(out) = &args.out {
        std::fs::write(out, &text).with_context(|| format!("writing {}", out.display()))?;
    }
    Ok(())
}

/// CGAL's runs, then ours at each thread count, then our memory, on one set.
fn measure(
    kind: SphereSetKind,
    set: &SphereSet,
    spheres_file: &Path,
    cgal_tets_file: &Path,
    cgal: Option<&Path>,
    args: &Args,
) -> anyhow::Result<Row> {
    let n = set.len();
    let cgal = cgal.map(|exe| {
        eprintln!("  CGAL, {} runs", args.runs);
        run_cgal_peer(exe, spheres_file, cgal_tets_file, args.runs, n)
    });
    let reference = match &cgal {
        Some(Ok(c)) => Some(&c.tets),
        _ => None,
    };
    let params = TriangulationParams::default();
    let mut ours = Vec::new();
    let mut first_tets: Option<Vec<[u32; 4]>> = None;
    let (mut hidden, mut finite_tets) = (0, 0);
    for &threads in &args.threads {
        eprintln!("  ours, {threads} threads, {} runs", args.runs);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .context("building the thread pool")?;
        let mut times = Vec::new();
        let mut cpu_times = Vec::new();
        let mut slot_prints = Vec::new();
        let mut last = None;
        for _ in 0..args.runs {
            // The previous triangulation is freed outside the timed span.
            drop(last.take());
            let cpu = process_cpu_seconds();
            let start = Instant::now();
            let tri = pool
                .install(|| RegularTriangulation::new(&set.points, &set.weights, &params))
                .context("our triangulation")?;
            times.push(start.elapsed().as_secs_f64());
            cpu_times.push(
                process_cpu_seconds()
                    .zip(cpu)
                    .map_or(f64::NAN, |(b, a)| b - a),
            );
            slot_prints.push(fnv1a(tri.tet_slots()));
            last = Some(tri);
        }
        let tri = last.expect("at least one run");
        let stats = tri.stats();
        (hidden, finite_tets) = (stats.hidden + stats.duplicates, stats.finite_tets);
        let tets: Vec<[u32; 4]> = tri.finite_tets().map(|t| tri.tet(t)).collect();
        drop(tri);
        let tets = canonical(tets);
        let diff = match (reference, &first_tets) {
            (Some(r), _) | (None, Some(r)) => Some(differences(&tets, r)),
            (None, None) => None,
        };
        if first_tets.is_none() && reference.is_none() {
            first_tets = Some(tets);
        }
        ours.push(OurRuns {
            threads,
            times,
            cpu_times,
            slot_prints,
            diff,
        });
    }
    let memory = (!args.no_memory).then(|| {
        let threads = args.threads.iter().copied().max().unwrap_or(1);
        eprintln!("  ours, peak memory on {threads} threads");
        memory_of_ours(spheres_file, threads)
    });
    Ok(Row {
        set: kind.name(),
        spheres: n,
        hidden,
        finite_tets,
        cgal,
        ours,
        memory,
    })
}

fn row_cells(row: &Row, threads: &[usize]) -> Vec<String> {
    let cgal = row.cgal.as_ref().and_then(|c| c.as_ref().ok());
    let cgal_median = cgal.map(|c| (median(&c.times), median(&c.cpu_times)));
    let hidden = match cgal {
        Some(c) if c.hidden != row.hidden => format!("{} (CGAL {})", row.hidden, c.hidden),
        _ => row.hidden.to_string(),
    };
    let mut cells = vec![
        row.set.to_string(),
        row.spheres.to_string(),
        hidden,
        row.finite_tets.to_string(),
        match &row.cgal {
            None => "–".into(),
            Some(Ok(c)) => time_cell(&c.times, &c.cpu_times),
            Some(Err(e)) => short_message(e, 60),
        },
    ];
    let ours_median = |t: usize| {
        row.ours
            .iter()
            .find(|o| o.threads == t)
            .map(|o| (median(&o.times), median(&o.cpu_times)))
    };
    cells.extend(threads.iter().map(|&t| {
        row.ours
            .iter()
            .find(|o| o.threads == t)
            .map_or_else(|| "–".into(), |o| time_cell(&o.times, &o.cpu_times))
    }));
    cells.extend(
        threads
            .iter()
            .map(|&t| match ours_median(t).zip(cgal_median) {
                Some((o, c)) => format!("{:.2} (CPU {:.2})", o.0 / c.0, o.1 / c.1),
                None => "–".into(),
            }),
    );
    cells.push(same_tets_cell(row, cgal.is_some()));
    let prints: Vec<u64> = row
        .ours
        .iter()
        .flat_map(|o| o.slot_prints.iter().copied())
        .collect();
    cells.push(
        if prints.windows(2).all(|w| w[0] == w[1]) {
            "yes"
        } else {
            "no"
        }
        .to_string(),
    );
    cells.push(match &row.memory {
        None => "–".into(),
        Some(Ok(b)) => format!("{b:.0}"),
        Some(Err(e)) => short_message(e, 60),
    });
    cells.push(fixed(cgal.and_then(|c| c.bytes_per_sphere), 0));
    cells
}

/// `yes`, or per thread count the tetrahedra only in ours and only in CGAL's; without CGAL,
/// whether every thread count gave the tetrahedra of the first.
fn same_tets_cell(row: &Row, with_cgal: bool) -> String {
    let differing: Vec<String> = row
        .ours
        .iter()
        .filter_map(|o| match o.diff {
            Some((a, b)) if (a, b) != (0, 0) => Some(if with_cgal {
                format!("{} thr: {a} only ours, {b} only CGAL", o.threads)
            } else {
                format!(
                    "{} thr: {a} / {b} differ from {} thr",
                    o.threads, row.ours[0].threads
                )
            }),
            _ => None,
        })
        .collect();
    match (with_cgal, differing.is_empty()) {
        (false, true) => "– (no CGAL)".into(),
        (true, true) => "yes".into(),
        (_, false) => format!("no: {}", differing.join("; ")),
    }
}

/// Every run of a row as `wall/CPU`, CGAL's then ours per thread count.
fn runs_line(row: &Row) -> String {
    let pairs = |wall: &[f64], cpu: &[f64]| {
        wall.iter()
            .zip(cpu)
            .map(|(w, c)| format!("{w:.2}/{c:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut parts = Vec::new();
    if let Some(Ok(c)) = &row.cgal {
        parts.push(format!("CGAL {}", pairs(&c.times, &c.cpu_times)));
    }
    for o in &row.ours {
        parts.push(format!(
            "ours {} thr {}",
            o.threads,
            pairs(&o.times, &o.cpu_times)
        ));
    }
    format!("- {} {}: {}", row.set, row.spheres, parts.join("; "))
}

/// The median wall time, with the range of all runs in parentheses when there are several,
/// then the median CPU time.
fn time_cell(times: &[f64], cpu_times: &[f64]) -> String {
    let m = median(times);
    let cpu = median(cpu_times);
    if times.len() < 2 {
        return format!("{m:.2}, CPU {cpu:.2}");
    }
    let lo = times.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = times.iter().copied().fold(0.0, f64::max);
    format!("{m:.2} ({lo:.2}–{hi:.2}), CPU {cpu:.2}")
}

fn median(xs: &[f64]) -> f64 {
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

fn hex_list(prints: &[u64]) -> String {
    let mut distinct: Vec<u64> = prints.to_vec();
    distinct.dedup();
    distinct
        .iter()
        .map(|p| format!("{p:016x}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `/proc/loadavg`'s three load averages, or `unknown`.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg").map_or_else(
        |_| "unknown".into(),
        |s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "),
    )
}

/// Our peak memory per sphere, measured in a child process on the written set.
fn memory_of_ours(spheres: &Path, threads: usize) -> Result<f64, String> {
    let exe = std::env::current_exe().map_err(|e| format!("no own binary: {e}"))?;
    let output = Command::new(exe)
        .arg("--memory-child")
        .arg(spheres)
        .arg("--threads")
        .arg(threads.to_string())
        .output()
        .map_err(|e| format!("not started: {e}"))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        return Err(format!("failed: {}", stderr.trim()));
    }
    stdout
        .lines()
        .find_map(|l| l.strip_prefix("bytes_per_sphere ")?.trim().parse().ok())
        .ok_or_else(|| "no figure".to_string())
}

/// The child of [`memory_of_ours`]: reads the set, resets the peak, triangulates once and
/// prints the peak's growth.
fn memory_child(spheres: &Path, threads: usize) -> anyhow::Result<()> {
    let set = read_spheres(spheres).with_context(|| format!("reading {}", spheres.display()))?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("building the thread pool")?;
    // Warm the pool's threads up so their stacks count as before.
    pool.install(|| rayon::join(|| (), || ()));
    let reset = reset_peak_resident();
    let before = peak_resident_bytes().context("no /proc/self/status")?;
    let tri = pool
        .install(|| {
            RegularTriangulation::new(&set.points, &set.weights, &TriangulationParams::default())
        })
        .context("our triangulation")?;
    let after = peak_resident_bytes().context("no /proc/self/status")?;
    println!("finite_tets {}", tri.stats().finite_tets);
    println!("peak_reset {reset}");
    println!("before_bytes {before}");
    println!("peak_bytes {after}");
    println!(
        "bytes_per_sphere {:.1}",
        after.saturating_sub(before) as f64 / set.len().max(1) as f64
    );
    Ok(())
}
