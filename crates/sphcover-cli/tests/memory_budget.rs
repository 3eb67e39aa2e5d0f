//! `sphcover recon --max-memory`: the predicted peak is checked before the reconstruction; a
//! budget too small for any depth is refused up front (exit 2, the estimate in the message,
//! nothing written), one that a coarser grid fits gets that grid and says so. Once the cover's
//! graph is built the check is made again with its size, against the default limit too.

mod support;

use std::path::PathBuf;
use std::time::Duration;

use sphcover_core::random::XorShift64;
use sphcover_core::{DVec3, io};
use sphcover_recon::{COARSEST_BUDGET_DEPTH, RECON_MEMORY_MODEL};
use support::{
    fibonacci_sphere, files_in, fixture, recon_with_report, sphcover, sphcover_under_ulimit, text,
    write_points_ply,
};

const LIMIT: Duration = Duration::from_secs(120);
/// Points of the test scan; its default depth is 6 (the coarsest default).
const POINTS: usize = 600;

fn scan_dir() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scan.ply");
    let points = fibonacci_sphere(POINTS);
    write_points_ply(&scan, &points, Some(&points));
    (dir, scan)
}

fn recon(scan: &std::path::Path, extra: &[&str]) -> (std::process::Output, PathBuf, PathBuf) {
    let dir = scan.parent().unwrap();
    let out = dir.join("mesh.ply");
    let report = dir.join("report.json");
    (recon_with_report(scan, &out, &report, extra), out, report)
}

fn report(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn a_tiny_budget_is_refused_up_front_with_the_estimate() {
    let (dir, scan) = scan_dir();
    let (run, out, _) = recon(&scan, &["--max-memory", "10M"]);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--max-memory 10.0 MiB"), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "reconstructing {POINTS} points at depth 6 needs about"
        )),
        "{stderr}"
    );
    assert!(
        stderr.contains(&format!("even depth {COARSEST_BUDGET_DEPTH} needs about")),
        "{stderr}"
    );
    assert!(!out.exists());
    assert_eq!(files_in(dir.path()), ["scan.ply"]);
}

#[test]
fn a_budget_between_two_depths_chooses_the_coarser_and_says_so() {
    let (_dir, scan) = scan_dir();
    let model = RECON_MEMORY_MODEL;
    let budget = (model.peak_bytes(POINTS, 6) + model.peak_bytes(POINTS, 5)) / 2;
    let (run, out, report_path) = recon(&scan, &["--max-memory", &budget.to_string()]);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("depth 6 would need about"), "{stderr}");
    assert!(stderr.contains("using depth 5"), "{stderr}");
    assert!(out.exists());
    let report = report(&report_path);
    assert_eq!(report["depth"], 5);
    assert_eq!(report["memory"]["depth_lowered_from"], 6);
    assert_eq!(report["memory"]["budget_bytes"], budget);
    assert_eq!(
        report["memory"]["estimated_peak_bytes"],
        model.peak_bytes(POINTS, 5)
    );
}

#[test]
fn an_explicit_depth_over_budget_is_refused_with_the_depth_that_fits() {
    let (dir, scan) = scan_dir();
    let model = RECON_MEMORY_MODEL;
    let budget = (model.peak_bytes(POINTS, 8) + model.peak_bytes(POINTS, 7)) / 2;
    let (run, out, _) = recon(
        &scan,
        &["--depth", "8", "--max-memory", &budget.to_string()],
    );
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--depth 7 would fit"), "{stderr}");
    assert!(!out.exists());
    assert_eq!(files_in(dir.path()), ["scan.ply"]);
}

#[test]
fn a_generous_budget_changes_nothing() {
    let (_dir, scan) = scan_dir();
    let (run, out, report_path) = recon(&scan, &[]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let plain = std::fs::read(&out).unwrap();
    assert_eq!(report(&report_path)["memory"], serde_json::Value::Null);
    let (run, out, report_path) = recon(&scan, &["--max-memory", "64G"]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    assert_eq!(std::fs::read(&out).unwrap(), plain);
    let report = report(&report_path);
    assert_eq!(
        report["memory"]["depth_lowered_from"],
        serde_json::Value::Null
    );
    assert_eq!(report["depth"], 6);
}

#[test]
fn a_malformed_budget_is_bad_usage() {
    let (dir, scan) = scan_dir();
    for size in ["2X", "G", "lots"] {
        let (run, out, _) = recon(&scan, &["--max-memory", size]);
        let stderr = text(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{size}: {stderr}");
        assert!(stderr.contains("--max-memory"), "{size}: {stderr}");
        assert!(!out.exists());
    }
    assert_eq!(files_in(dir.path()), ["scan.ply"]);
}

#[test]
fn the_graph_cut_method_is_outside_the_model() {
    let (_dir, scan) = scan_dir();
    let (run, out, _) = recon(&scan, &["--method", "graphcut", "--max-memory", "64G"]);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("not the graph-cut method"), "{stderr}");
    assert!(!out.exists());
}

/// `sphcover skeleton --max-memory`: the bundled T-junction phantom (under 10 MiB predicted)
/// is refused under a 1 MiB budget and runs under 1 GiB.
#[test]
fn skeleton_refuses_a_budget_below_its_estimate_and_runs_within_one_above() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("phantoms/t_junction_ct_n000.nii.gz");
    let out = dir.path().join("sheet.ply");
    let args = |budget: &'static str| {
        vec![
            "skeleton".to_owned(),
            input.to_str().unwrap().to_owned(),
            "-o".to_owned(),
            out.to_str().unwrap().to_owned(),
            "--max-memory".to_owned(),
            budget.to_owned(),
        ]
    };
    let refused: Vec<String> = args("1M");
    let refused: Vec<&str> = refused.iter().map(String::as_str).collect();
    let run = sphcover(&refused, LIMIT);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--max-memory 1.0 MiB"), "{stderr}");
    assert!(stderr.contains("voxels needs about"), "{stderr}");
    assert!(files_in(dir.path()).is_empty());

    let accepted: Vec<String> = args("1G");
    let accepted: Vec<&str> = accepted.iter().map(String::as_str).collect();
    let run = sphcover(&accepted, LIMIT);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    assert!(out.exists());
}

/// `count` samples spread uniformly by area over the closed, outward-wound mesh `path`, with
/// the normals of their triangles.
fn surface_samples(path: &std::path::Path, count: usize) -> (Vec<DVec3>, Vec<DVec3>) {
    let mesh = io::read_mesh(path, &io::ReadOptions::default()).unwrap();
    let corners = |t: &[u32; 3]| t.map(|v| mesh.vertices[v as usize]);
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = corners(t);
        total += 0.5 * (b - a).cross(c - a).length();
        cumulative.push(total);
    }
    let mut rng = XorShift64::new(7);
    (0..count)
        .map(|_| {
            let pick = rng.uniform() * total;
            let t = cumulative
                .partition_point(|&c| c < pick)
                .min(cumulative.len() - 1);
            let [a, b, c] = corners(&mesh.triangles[t]);
            let (mut u, mut v) = (rng.uniform(), rng.uniform());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            (
                a + u * (b - a) + v * (c - a),
                (b - a).cross(c - a).normalize(),
            )
        })
        .unzip()
}

#[test]
fn a_cover_refined_to_its_sampling_stops_at_the_memory_limit_with_the_remedies() {
    // 100K samples of the thin-walled housing: its cover has about three times the usual
    // graph (the model predicts some 430 MiB). Under a 586 MiB address space the default
    // limit is 60% of it, 352 MiB, and the run stops once the graph is built.
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("housing.ply");
    let (points, normals) = surface_samples(&fixture("thin_walled_housing.ply"), 100_000);
    write_points_ply(&scan, &points, Some(&normals));
    let out = dir.path().join("mesh.ply");
    let args = [
        "recon",
        scan.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--threads",
        "2",
    ];
    let run = sphcover_under_ulimit(600_000, &args, LIMIT);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("memory limit 351.6 MiB: the cover has")
            && stderr.contains("--tiles 2 or more")
            && stderr.contains("--eps")
            && stderr.contains("address-space limit (ulimit -v); --max-memory sets it"),
        "{stderr}"
    );
    assert!(!out.exists());
    assert_eq!(files_in(dir.path()), ["housing.ply"]);
}
