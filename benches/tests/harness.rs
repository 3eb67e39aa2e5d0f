//! The harness binaries end to end, with stand-in peers: one that returns the ground truth
//! itself (it must score perfectly), one that fails (its row must say why) and a missing
//! sphcover binary (its row must say so), on a small analytic ground truth.

use std::path::{Path, PathBuf};
use std::process::Command;

use sphcover_core::DVec3;
use sphcover_core::io::{self, WriteOptions};
use sphcover_evaluation::ground_truth_meshes::icosphere;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sphcover-benches-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write_sphere(dir: &Path) -> PathBuf {
    let gt = dir.join("sphere.ply");
    io::write_mesh(
        &gt,
        &icosphere(DVec3::ZERO, 1.0, 4),
        &WriteOptions::default(),
    )
    .unwrap();
    gt
}

#[test]
fn recon_bench_scores_peers_and_reports_failures() {
    let dir = temp_dir("recon");
    let gt = write_sphere(&dir);
    let table = dir.join("table.md");
    let out = Command::new(env!("CARGO_BIN_EXE_recon-bench"))
        .args([
            "--sizes",
            "2k",
            "--cases",
            "clean,outliers1",
            "--samples",
            "5000",
            "--repeat",
            "2",
        ])
        .arg("--mesh")
        .arg(format!("sphere={}", gt.display()))
        .args(["--sphcover", "/nonexistent/sphcover"])
        .arg("--peer")
        .arg(format!(
            "perfect=sh -c 'cp \"$1\" \"$2\"' sh {} {{out}} {{in}}",
            gt.display()
        ))
        .arg("--peer")
        .arg("broken=sh -c 'echo starting >&2; echo boom >&2; exit 4' sh {in} {out}")
        .arg("--work-dir")
        .arg(&dir)
        .arg("--out")
        .arg(&table)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&table).unwrap();
    let rows: Vec<&str> = text.lines().filter(|l| l.starts_with("| sphere")).collect();
    assert_eq!(rows.len(), 6, "{text}");
    for case in ["clean", "outliers1"] {
        let row = |tool: &str| {
            rows.iter()
                .find(|r| r.contains(&format!("| {case} ")) && r.contains(&format!("| {tool} ")))
                .unwrap_or_else(|| panic!("no {case}/{tool} row in\n{text}"))
                .split('|')
                .map(str::trim)
                .collect::<Vec<_>>()
        };
        let perfect = row("perfect");
        // Columns: mesh case points tool wall cpu peak steal chamfer h99 nc f.25 f.5 f1 comp
        // wt invented uncovered slits status
        assert_eq!(perfect[9], "0.0000", "{perfect:?}");
        assert_eq!(perfect[11], "1.0000");
        assert_eq!(perfect[14], "1.0000");
        assert_eq!(perfect[15], "1");
        assert_eq!(perfect[16], "yes");
        // The ground truth itself, against 2000 random samples of it: only the rare gaps of
        // a random sample (about 2^-9 of the area, 0.2%) are farther than 3 spacings.
        let invented: f64 = perfect[17].parse().unwrap();
        assert!((0.0..1.0).contains(&invented), "{perfect:?}");
        // The truth leaves no surface sample out, only the outliers (1 in 101) that lie
        // farther than two spacings from it; no projector, so no slits.
        let uncovered: f64 = perfect[18].parse().unwrap();
        if case == "clean" {
            assert_eq!(uncovered, 0.0, "{perfect:?}");
        } else {
            assert!((0.5..=100.0 / 101.0).contains(&uncovered), "{perfect:?}");
        }
        assert_eq!(perfect[19], "–");
        assert_eq!(perfect[20], "ok");
        // Two runs: the median's wall time and the range of both.
        let (wall, range) = perfect[5].split_once(' ').expect("a range after the time");
        let wall: f64 = wall.parse().unwrap();
        let (lo, hi) = range
            .trim_matches(['(', ')'])
            .split_once('–')
            .expect("lo–hi");
        let (lo, hi): (f64, f64) = (lo.parse().unwrap(), hi.parse().unwrap());
        assert!(lo <= wall && wall <= hi, "{perfect:?}");
        // A run shorter than one tick of `/proc/stat` (10 ms) has no steal share: "–".
        if Path::new("/proc/stat").is_file() && perfect[8] != "–" {
            let steal: f64 = perfect[8].parse().unwrap();
            assert!((0.0..=100.0).contains(&steal), "{perfect:?}");
        }
        // A failing tool is not run again: its row has no range.
        let broken = row("broken");
        assert_eq!(broken[17], "–");
        assert_eq!(broken[18], "–");
        assert_eq!(broken[19], "–");
        assert!(broken[20].contains("failed (exit 4): boom"));
        assert!(!broken[5].contains('('), "{broken:?}");
        assert!(row("sphcover")[20].starts_with("not built"));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn recon_bench_refuses_bad_arguments() {
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_recon-bench"))
            .args(args)
            .output()
            .unwrap()
    };
    let o = run(&[
        "--cases",
        "nonsense",
        "--no-sphcover",
        "--peer",
        "p=x {in} {out}",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("unknown case `nonsense`"));
    let o = run(&["--sizes", "lots"]);
    assert!(!o.status.success());
    let o = run(&["--no-sphcover", "--peer", "p=tool-without-placeholders"]);
    assert!(!o.status.success());
}

#[test]
fn skeleton_bench_reports_a_missing_binary() {
    let dir = temp_dir("skeleton");
    let out = Command::new(env!("CARGO_BIN_EXE_skeleton-bench"))
        .args(["--sphcover", "/nonexistent/sphcover", "--work-dir"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(stdout.matches("not built").count(), 2, "{stdout}");
    assert!(stdout.contains("| t_junction-n000 | ridge"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn recon_score_scores_a_mesh_against_itself() {
    let dir = temp_dir("score");
    let gt = write_sphere(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_recon-score"))
        .arg(&gt)
        .arg(&gt)
        .args(["-n", "2000"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // Zero up to the rounding of a sample's projection onto its own triangle.
    assert!(v["chamfer_l1"].as_f64().unwrap() < 1e-9);
    assert_eq!(v["fscore@1"].as_f64(), Some(1.0));
    assert_eq!(v["watertight"].as_bool(), Some(true));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A stand-in `sphcover` that answers `skeleton CT -o OUT …` with the phantom's true sheet
/// (a flat 2 mm square): the table must show full coverage, nothing spurious and the
/// expected topology.
#[cfg(unix)]
#[test]
fn skeleton_bench_scores_a_sheet_against_the_phantom_truth() {
    use sphcover_core::io::{PlyEncoding, Precision};
    use sphcover_core::{PointCloud, TriMesh};
    use std::os::unix::fs::PermissionsExt;

    let dir = temp_dir("skeleton-truth");
    let phantom = dir.join("phantoms").join("plate");
    std::fs::create_dir_all(&phantom).unwrap();
    std::fs::write(phantom.join("ct_n000.nii.gz"), b"not read by the stand-in").unwrap();
    // Voxels of 0.1 mm: the square is 20 × 20 voxels.
    std::fs::write(
        phantom.join("meta.json"),
        r#"{"voxel_mm": 0.1, "expected_components": 1, "expected_euler_characteristic": 1, "gt_sheet_area_vox2": 400.0}"#,
    )
    .unwrap();
    let float_ply = WriteOptions {
        ply_encoding: PlyEncoding::BinaryLittleEndian,
        precision: Precision::F32,
        inputs: Vec::new(),
    };
    // True samples a quarter voxel apart, with their normals; the boundary is the square's
    // outline.
    let m = 81u32;
    let step = 2.0 / (m - 1) as f64;
    let samples: Vec<DVec3> = (0..m * m)
        .map(|k| DVec3::new((k % m) as f64 * step, (k / m) as f64 * step, 0.0))
        .collect();
    let sheet = PointCloud {
        normals: Some(vec![DVec3::Z; samples.len()]),
        ..PointCloud::from_positions(samples.clone())
    };
    io::write_point_cloud(&phantom.join("gt_sheet.ply"), &sheet, &float_ply).unwrap();
    let outline: Vec<DVec3> = samples
        .iter()
        .copied()
        .filter(|p| p.x == 0.0 || p.y == 0.0 || p.x >= 2.0 - 1e-9 || p.y >= 2.0 - 1e-9)
        .collect();
    io::write_point_cloud(
        &phantom.join("gt_boundary.ply"),
        &PointCloud::from_positions(outline),
        &float_ply,
    )
    .unwrap();
    // The same square as a 10 × 10 grid of quads: a disc, χ = 1.
    let n = 11u32;
    let vertices = (0..n * n)
        .map(|k| DVec3::new((k % n) as f64 * 0.2, (k / n) as f64 * 0.2, 0.0))
        .collect();
    let triangles = (0..n - 1)
        .flat_map(|j| (0..n - 1).map(move |i| (i, j)))
        .flat_map(|(i, j)| {
            let a = j * n + i;
            [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
        })
        .collect();
    io::write_mesh(
        &phantom.join("gt_sheet_mesh.ply"),
        &TriMesh::new(vertices, triangles),
        &WriteOptions::default(),
    )
    .unwrap();
    let fake = dir.join("fake-sphcover");
    std::fs::write(
        &fake,
        "#!/bin/sh\ncp \"$(dirname \"$2\")/gt_sheet_mesh.ply\" \"$4\"\n",
    )
    .unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();

    let out = Command::new(env!("CARGO_BIN_EXE_skeleton-bench"))
        .arg("--phantoms-dir")
        .arg(dir.join("phantoms"))
        .arg("--sphcover")
        .arg(&fake)
        .args(["--methods", "ridge", "--work-dir"])
        .arg(dir.join("work"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let row: Vec<&str> = stdout
        .lines()
        .find(|l| l.starts_with("| plate-n000"))
        .unwrap_or_else(|| panic!("no row in\n{stdout}"))
        .split('|')
        .map(str::trim)
        .collect();
    // Columns: phantom method wall cpu peak output coverage spurious spurious-off-rim
    // p95-off-rim components χ boundary-reach status
    assert_eq!(row[6], "200 triangles", "{stdout}");
    assert_eq!(row[7], "1.000", "{stdout}");
    assert_eq!(row[8], "0.000", "{stdout}");
    assert_eq!(row[9], "0.000", "{stdout}");
    assert_eq!(row[11], "1 (1)", "{stdout}");
    assert_eq!(row[12], "1 (1)", "{stdout}");
    assert_eq!(row[13], "0.00", "{stdout}");
    assert_eq!(row[14], "ok", "{stdout}");
    std::fs::remove_dir_all(&dir).unwrap();
}
