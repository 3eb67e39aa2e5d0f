//! The CGAL peer of `tetra-bench`: `peers/cgal_regular.cpp` (CGAL's sequential
//! `Regular_triangulation_3` with exact predicates), compiled on demand and run on a sphere
//! file of [`crate::sphere_sets::write_spheres`].
//!
//! The program's protocol is described at the top of its source: it takes the sphere file,
//! an output path for its finite cells (little-endian `u32` quadruples of input indices,
//! each sorted) and a number of runs, and prints `key value` lines (`time` and `cpu` per run,
//! `hidden`, `vertices`, `finite_cells`, `input_peak_bytes`, `peak_bytes`).

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, bail};

use crate::tet_lists::{canonical, read_tets};
use crate::workspace_root;

/// The peer's source, relative to the workspace root.
pub const CGAL_SOURCE: &str = "benches/peers/cgal_regular.cpp";
/// How the peer is compiled: `-frounding-math` as CGAL's own CMake setup adds for GCC (its
/// interval filters need the rounding mode honoured).
pub const CXX_FLAGS: [&str; 4] = ["-O3", "-DNDEBUG", "-std=c++17", "-frounding-math"];
/// What the peer links: CGAL's exact number types.
pub const CXX_LIBS: [&str; 2] = ["-lgmp", "-lmpfr"];

/// What one call of the peer reported.
#[derive(Clone, Debug, PartialEq)]
pub struct CgalRun {
    /// Wall seconds of `insert` per run.
    pub times: Vec<f64>,
    /// CPU seconds of `insert` per run (the process's user and system time).
    pub cpu_times: Vec<f64>,
    /// Input points that are not vertices.
    pub hidden: usize,
    /// Growth of the process's peak resident memory from after reading the input to after
    /// the runs, per sphere.
    pub bytes_per_sphere: Option<f64>,
    /// The finite cells of the last run, canonical ([`canonical`]).
    pub tets: Vec<[u32; 4]>,
}

/// The peer's binary `cgal_regular` in `work`, compiled with `g++` ([`CXX_FLAGS`],
/// [`CXX_LIBS`]) when it is missing or older than its source. Errors say what to install
/// (`apt-get install libcgal-dev`) or to pass `--no-cgal`.
pub fn cgal_peer_binary(work: &Path) -> anyhow::Result<PathBuf> {
    let source = workspace_root().join(CGAL_SOURCE);
    let exe = work.join("cgal_regular");
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let source_time =
        modified(&source).with_context(|| format!("{} is missing", source.display()))?;
    if modified(&exe).is_some_and(|t| t >= source_time) {
        return Ok(exe);
    }
    eprintln!("compiling {} (about 10 s)", source.display());
    let partial = work.join(format!("cgal_regular.partial-{}", std::process::id()));
    let output = Command::new("g++")
        .args(CXX_FLAGS)
        .arg(&source)
        .arg("-o")
        .arg(&partial)
        .args(CXX_LIBS)
        .output();
    let output = match output {
        Ok(o) => o,
        Err(e) => bail!(
            "cannot run g++ ({e}): the CGAL peer needs a C++ compiler and CGAL \
             (apt-get install g++ libcgal-dev), or run ours alone with --no-cgal"
        ),
    };
    if !output.status.success() {
        let _ = std::fs::remove_file(&partial);
        let stderr = String::from_utf8_lossy(&output.stderr);
        let lines: Vec<&str> = stderr.lines().collect();
        let tail = lines[lines.len().saturating_sub(8)..].join("\n");
        if stderr.contains("CGAL/") && stderr.contains("No such file") {
            bail!(
                "CGAL's headers are not installed: apt-get install libcgal-dev \
                 (CGAL 5.5, with GMP and MPFR), or run ours alone with --no-cgal"
            );
        }
        if stderr.contains("-lgmp") || stderr.contains("-lmpfr") {
            bail!(
                "GMP or MPFR is missing: apt-get install libcgal-dev (it pulls libgmp-dev and \
                 libmpfr-dev), or run ours alone with --no-cgal\n{tail}"
            );
        }
        bail!("compiling {} failed:\n{tail}", source.display());
    }
    std::fs::rename(&partial, &exe).with_context(|| format!("moving to {}", exe.display()))?;
    Ok(exe)
}

/// Runs the peer `exe` `runs` times on the `n` spheres of `spheres`, its cells going to
/// `tets_file`; a failure comes back as the message for the table.
pub fn run_cgal_peer(
    exe: &Path,
    spheres: &Path,
    tets_file: &Path,
    runs: usize,
    n: usize,
) -> Result<CgalRun, String> {
    let _ = std::fs::remove_file(tets_file);
    let output = Command::new(exe)
        .arg(spheres)
        .arg(tets_file)
        .arg(runs.to_string())
        .output()
        .map_err(|e| format!("not started: {e}"))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let last = stderr
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("");
        return Err(format!("failed ({}): {last}", output.status));
    }
    let values = |key: &str| -> Vec<f64> {
        stdout
            .lines()
            .filter_map(|l| l.strip_prefix(key)?.strip_prefix(' ')?.trim().parse().ok())
            .collect()
    };
    let one = |key: &str| values(key).first().copied();
    let times = values("time");
    let cpu_times = values("cpu");
    if times.len() != runs || cpu_times.len() != runs {
        return Err(format!("{} times for {runs} runs", times.len()));
    }
    let hidden = one("hidden").ok_or("no hidden count")? as usize;
    let bytes_per_sphere = one("peak_bytes")
        .zip(one("input_peak_bytes"))
        .filter(|(p, _)| *p > 0.0)
        .map(|(p, i)| (p - i) / n.max(1) as f64);
    let tets = read_tets(tets_file).map_err(|e| format!("reading its cells: {e}"))?;
    Ok(CgalRun {
        times,
        cpu_times,
        hidden,
        bytes_per_sphere,
        tets: canonical(tets),
    })
}
