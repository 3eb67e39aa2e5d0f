//! End-to-end tests of the `sphcover` binary on the bundled fixtures.

use std::path::PathBuf;
use std::process::{Command, Output};

fn fixture(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(rel)
}

fn sphcover(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sphcover"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn info_reports_a_scan_with_normals() {
    let path = fixture("real/kitten.ply");
    let out = sphcover(&["info", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(stdout.contains("points        5210"), "{stdout}");
    assert!(
        stdout.contains("normals       yes: all unit length"),
        "{stdout}"
    );
    assert!(stdout.contains("non-finite    none"), "{stdout}");
}

#[test]
fn info_reports_zero_length_normals_of_a_raw_scan() {
    let path = fixture("real/hippo2.ply");
    let out = sphcover(&["info", "--json", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["points"], 4387);
    assert_eq!(v["normals"]["zero_length"], 2);
    assert!(v["format"].as_str().unwrap().contains("binary"));
}

#[test]
fn info_reports_a_closed_mesh() {
    let path = fixture("real/bunny_npm.off");
    let out = sphcover(&["info", "--json", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["points"], 1839);
    assert_eq!(v["triangles"], 3674);
    assert_eq!(v["mesh"]["closed"], true);
    assert_eq!(v["mesh"]["boundary_edges"], 0);
}

#[test]
fn info_on_a_malformed_file_names_it_and_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("broken.ply");
    std::fs::write(
        &bad,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 1\n",
    )
    .unwrap();
    let out = sphcover(&["info", bad.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert!(stderr.contains("broken.ply"), "{stderr}");
    assert!(stderr.contains("line"), "{stderr}");
}

#[test]
fn info_on_a_missing_file_exits_2() {
    let out = sphcover(&["info", "/nonexistent/dir/scan.ply"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("scan.ply"));
}

#[test]
fn info_keeps_going_past_a_bad_file_and_still_fails() {
    let good = fixture("real/bunny_npm.off");
    let out = sphcover(&["info", "nope.xyz", good.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stdout).contains("points        1839"));
}

#[test]
fn pending_subcommands_say_so_and_exit_1() {
    for sub in ["recon", "skeleton", "cover", "tetra"] {
        let out = sphcover(&[sub, "in.ply", "-o", "out.ply"]);
        assert_eq!(out.status.code(), Some(1), "{sub}");
        assert!(text(&out.stderr).contains("not available"), "{sub}");
    }
}

#[test]
fn bad_usage_exits_2() {
    assert_eq!(
        sphcover(&["--threads", "0", "info", "x.ply"]).status.code(),
        Some(2)
    );
    assert_eq!(sphcover(&["frobnicate"]).status.code(), Some(2));
    assert_eq!(sphcover(&["info"]).status.code(), Some(2));
    assert_eq!(sphcover(&["--help"]).status.code(), Some(0));
}

#[test]
fn output_does_not_depend_on_the_thread_count() {
    let path = fixture("real/kitten.ply");
    let one = sphcover(&["--threads", "1", "info", "--json", path.to_str().unwrap()]);
    let two = sphcover(&["--threads", "2", "info", "--json", path.to_str().unwrap()]);
    assert_eq!(one.stdout, two.stdout);
}
