//! End-to-end tests of the `sphcover` binary on the bundled fixtures.

mod support;

use support::{fixture, run as sphcover, text};

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

#[test]
fn info_reports_a_ct_volume() {
    let path = fixture("phantoms/t_junction_ct_n000.nii.gz");
    let out = sphcover(&["info", "--json", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["dims"], serde_json::json!([80, 72, 56]));
    assert_eq!(v["datatype"], "int16");
    assert!((v["voxel_size"][0].as_f64().unwrap() - 0.1).abs() < 1e-6);
}

#[test]
fn tetra_reproduces_the_reference_dual_complex() {
    let input = fixture("tetra/random_3k.spheres.txt");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("random.tets");
    let run = sphcover(&[
        "tetra",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--shrink",
        "1",
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let expected = std::fs::read(fixture("tetra/random_3k.tets.txt")).unwrap();
    assert!(std::fs::read(&out).unwrap() == expected);
}

#[test]
fn tetra_on_a_sphere_grid_writes_vtk_and_reports_the_topology() {
    let input = fixture("grid_spheres.sph");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("grid.vtk");
    let run = sphcover(&[
        "tetra",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let stderr = text(&run.stderr);
    // 4 × 4 × 4 cubes, each split into 6 tetrahedra; the union of balls is contractible.
    assert!(stderr.contains("384 tetrahedra"), "{stderr}");
    assert!(stderr.contains("Euler characteristic 1"), "{stderr}");
    assert!(std::fs::read(&out).unwrap().starts_with(b"# vtk DataFile"));
}

#[test]
fn tetra_refuses_to_overwrite_its_input_and_bad_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("s.txt");
    std::fs::write(&input, "0 0 0 1\n1 0 0 1\n0 1 0 1\n0 0 1 1\n").unwrap();
    let run = sphcover(&[
        "tetra",
        input.to_str().unwrap(),
        "-o",
        input.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    assert!(text(&run.stderr).contains("overwrite"));
    assert_eq!(
        std::fs::read_to_string(&input).unwrap(),
        "0 0 0 1\n1 0 0 1\n0 1 0 1\n0 0 1 1\n"
    );
    let kitten = fixture("real/kitten.ply");
    let out = dir.path().join("k.vtk");
    let run = sphcover(&[
        "tetra",
        kitten.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    assert!(text(&run.stderr).contains("radii"));
    assert!(!out.exists());
}

#[test]
fn non_finite_spheres_are_refused_unless_dropped_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("s.sph");
    std::fs::write(&input, "0 0 0 1\n1 0 0 1\nnan 0 0 1\n0 1 0 1\n0 0 1 1\n").unwrap();
    let out = dir.path().join("s.tets");
    let refused = sphcover(&[
        "tetra",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(refused.status.code(), Some(2));
    let stderr = text(&refused.stderr);
    assert!(
        stderr.contains("s.sph") && stderr.contains("line 3"),
        "{stderr}"
    );
    assert!(!out.exists());
    let dropped = sphcover(&[
        "tetra",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--drop-non-finite",
    ]);
    assert_eq!(dropped.status.code(), Some(0), "{}", text(&dropped.stderr));
    assert!(text(&dropped.stderr).contains("dropped 1 spheres"));
    assert!(out.exists());
}

#[test]
fn cover_of_oriented_points_is_read_back_and_independent_of_threads() {
    let input = fixture("sphere_2k.ply");
    let dir = tempfile::tempdir().unwrap();
    let one = dir.path().join("one.ply");
    let two = dir.path().join("two.ply");
    for (threads, out) in [("1", &one), ("2", &two)] {
        let run = sphcover(&[
            "--threads",
            threads,
            "cover",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--eps",
            "0.005",
            "--seed",
            "3",
        ]);
        assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
        assert!(text(&run.stderr).contains("supports"));
    }
    assert!(std::fs::read(&one).unwrap() == std::fs::read(&two).unwrap());
    let (cover, meta) = sphcover_core::io::read_cover(&one).unwrap();
    assert!(cover.len() > 10);
    // The samples of a sphere of radius 0.5 span a box whose longest edge is just under 1.
    assert!((meta.normalisation.scale - 1.0).abs() < 1e-2, "{meta:?}");
}

#[test]
fn cover_of_a_ct_volume_and_its_tetrahedral_mesh() {
    let input = fixture("phantoms/t_junction_ct_n000.nii.gz");
    let dir = tempfile::tempdir().unwrap();
    let cover = dir.path().join("t.cover.ply");
    let run = sphcover(&[
        "cover",
        input.to_str().unwrap(),
        "-o",
        cover.to_str().unwrap(),
        "--threshold",
        "500",
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    assert!(
        text(&run.stderr).contains("0 over ε"),
        "{}",
        text(&run.stderr)
    );
    let mesh = dir.path().join("t.vtk");
    let run = sphcover(&[
        "tetra",
        cover.to_str().unwrap(),
        "-o",
        mesh.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
}

#[test]
fn cover_centre_order_and_elimination_trade_supports_for_build_time() {
    let input = fixture("phantoms/t_junction_ct_n000.nii.gz");
    let dir = tempfile::tempdir().unwrap();
    let supports = |extra: &[&str]| {
        let out = dir.path().join("c.ply");
        let mut args = vec![
            "cover",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(&["--threshold", "500"]);
        args.extend_from_slice(extra);
        let run = sphcover(&args);
        assert_eq!(
            run.status.code(),
            Some(0),
            "{extra:?}: {}",
            text(&run.stderr)
        );
        sphcover_core::io::read_cover(&out).unwrap().0.len()
    };
    let thesis = supports(&["--elimination", "off"]);
    let default = supports(&[]);
    let greedy = supports(&["--centre-order", "greedy", "--elimination", "centres"]);
    assert!(
        greedy < default && default < thesis,
        "{greedy} / {default} / {thesis}"
    );
    // On oriented points the volume options are refused.
    let out = dir.path().join("s.ply");
    let points = fixture("sphere_2k.ply");
    let run = sphcover(&[
        "cover",
        points.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--centre-order",
        "greedy",
    ]);
    assert_eq!(run.status.code(), Some(2));
    assert!(
        text(&run.stderr).contains("--centre-order"),
        "{}",
        text(&run.stderr)
    );
    assert!(!out.exists());
}

#[test]
fn cover_refuses_points_without_normals_and_empty_thresholds() {
    let dir = tempfile::tempdir().unwrap();
    let bare = dir.path().join("bare.xyz");
    std::fs::write(&bare, "0 0 0\n1 0 0\n0 1 0\n0 0 1\n").unwrap();
    let out = dir.path().join("c.ply");
    let run = sphcover(&["cover", bare.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2));
    assert!(text(&run.stderr).contains("normals"));
    let ct = fixture("phantoms/t_junction_ct_n000.nii.gz");
    let run = sphcover(&[
        "cover",
        ct.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--threshold",
        "100000",
    ]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    assert!(!out.exists());
}
