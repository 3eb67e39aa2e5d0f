//! End-to-end tests of `sphcover recon` on the bundled scans.

mod support;

use sphcover_core::io::{self, ReadOptions};
use sphcover_core::{DVec3, MeshTopology, TriMesh};
use support::{fixture, recon_with_report, run as sphcover, text};

fn summary(t: &MeshTopology) -> String {
    format!(
        "{} components, {} boundary / {} non-manifold / {} inconsistent edges, χ = {}",
        t.components,
        t.boundary_edges,
        t.non_manifold_edges,
        t.inconsistent_edges,
        t.euler_characteristic()
    )
}

#[test]
fn kitten_scan_gives_one_closed_surface_and_every_optional_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("kitten_mesh.ply");
    let points = dir.path().join("points.ply");
    let cover = dir.path().join("cover.ply");
    let report = dir.path().join("report.json");
    let input = fixture("real/kitten.ply");
    let run = sphcover(&[
        "recon",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--points-out",
        points.to_str().unwrap(),
        "--cover-out",
        cover.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));

    let mesh = io::read_mesh(&out, &ReadOptions::default()).unwrap();
    let topology = MeshTopology::of(&mesh);
    // The kitten is a closed surface with one handle (its tail meets its body).
    assert!(
        topology.is_closed_oriented_manifold(),
        "{}",
        summary(&topology)
    );
    assert_eq!(topology.components, 1);
    assert_eq!(topology.euler_characteristic(), 0);

    // The surface passes close to the scan: every sample within two grid steps (the default
    // depth for 5,210 points is 6, a step of 1/64 of the box) of a mesh vertex.
    let scan = io::read_point_cloud(&input, &ReadOptions::default()).unwrap();
    let index = sphcover_core::PointIndex::new(&mesh.vertices).unwrap();
    let mut nearest = Vec::new();
    let worst = scan
        .positions
        .iter()
        .map(|&p| {
            index.nearest_k(p, 1, &mut nearest);
            (mesh.vertices[nearest[0] as usize] - p).length()
        })
        .fold(0.0, f64::max);
    assert!(
        worst < 2.0 / 64.0 * scan.bounding_box().longest_edge(),
        "{worst}"
    );

    let labelled = io::read_point_cloud(&points, &ReadOptions::default()).unwrap();
    assert_eq!(labelled.len(), scan.len());
    assert!(labelled.confidence.is_some() && labelled.values.is_some());
    let (read_cover, _meta) = io::read_cover(&cover).unwrap();
    assert!(!read_cover.is_empty());

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["method"], "integrated");
    assert_eq!(json["points"], 5210);
    assert_eq!(json["components"], 1);
    assert_eq!(json["watertight"], true);
    assert_eq!(
        json["triangles"].as_u64().unwrap(),
        mesh.triangles.len() as u64
    );
}

#[test]
fn every_method_reconstructs_the_bundled_sphere() {
    let dir = tempfile::tempdir().unwrap();
    // The plain partition of unity has no defence against noise, nor the diffusion alone
    // against outliers (the noisy sample has 2%): they get the clean sample.
    for (method, sample) in [
        ("integrated", "sphere_noisy_2k.ply"),
        ("diffusion", "sphere_2k.ply"),
        ("graphcut", "sphere_noisy_2k.ply"),
        ("pu", "sphere_2k.ply"),
    ] {
        let input = fixture(sample);
        let out = dir.path().join(format!("{method}.ply"));
        let run = sphcover(&[
            "recon",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--method",
            method,
        ]);
        assert_eq!(
            run.status.code(),
            Some(0),
            "{method}: {}",
            text(&run.stderr)
        );
        let mesh = io::read_mesh(&out, &ReadOptions::default()).unwrap();
        let topology = MeshTopology::of(&mesh);
        assert_eq!(topology.components, 1, "{method}: {}", summary(&topology));
        assert!(topology.is_watertight(), "{method}: {}", summary(&topology));
    }
}

#[test]
fn unoriented_points_are_oriented_and_said_so() {
    let dir = tempfile::tempdir().unwrap();
    let xyz = dir.path().join("torus.xyz");
    let torus = io::read_point_cloud(&fixture("torus_3k.xyz"), &ReadOptions::default()).unwrap();
    let bare = sphcover_core::PointCloud::from_positions(torus.positions.clone());
    io::write_point_cloud(&xyz, &bare, &io::WriteOptions::default()).unwrap();
    let out = dir.path().join("torus.ply");
    let run = sphcover(&["recon", xyz.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    assert!(text(&run.stderr).contains("normals estimated"));
    let topology = MeshTopology::of(&io::read_mesh(&out, &ReadOptions::default()).unwrap());
    assert_eq!(
        (topology.components, topology.euler_characteristic()),
        (1, 0)
    );
    assert!(topology.is_closed_oriented_manifold());
}

#[test]
fn bad_parameters_and_inputs_exit_2_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.ply");
    let kitten = fixture("real/kitten.ply");
    let k = kitten.to_str().unwrap();
    let o = out.to_str().unwrap();
    for args in [
        vec!["recon", k, "-o", o, "--eps", "0"],
        vec!["recon", k, "-o", o, "--trim", "-1"],
        vec!["recon", k, "-o", o, "--depth", "30"],
        vec!["recon", k, "-o", o, "--k", "nan"],
        vec!["recon", "missing.ply", "-o", o],
        vec!["recon", k, "-o", k],
    ] {
        let run = sphcover(&args);
        assert_eq!(
            run.status.code(),
            Some(2),
            "{args:?}: {}",
            text(&run.stderr)
        );
        assert!(!out.exists(), "{args:?}");
    }
    let three = dir.path().join("three.xyz");
    std::fs::write(&three, "0 0 0\n1 0 0\n0 1 0\n").unwrap();
    let run = sphcover(&["recon", three.to_str().unwrap(), "-o", o]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    assert!(
        text(&run.stderr).contains("three.xyz"),
        "{}",
        text(&run.stderr)
    );
    assert!(!out.exists());
}

/// The colour the test paints at `p` in a box from `lo` spanning `extent`: red along x,
/// green along y, blue along z, 8-bit.
fn paint(p: DVec3, lo: DVec3, extent: DVec3) -> [u8; 3] {
    ((p - lo) / extent)
        .to_array()
        .map(|t| (t.clamp(0.0, 1.0) * 255.0).round() as u8)
}

#[test]
fn colours_survive_las_to_recon_to_ply() {
    // The bundled LiDAR tile declares RGB but its colours are all black: paint them here,
    // as 16-bit values the way the specification scales 8-bit colours (c · 257).
    let input = fixture("real/urban.las");
    let mut las = std::fs::read(&input).unwrap();
    let cloud = io::read_point_cloud(&input, &ReadOptions::default()).unwrap();
    assert_eq!(cloud.colors, None, "black colours are no colours");
    let bbox = cloud.bounding_box();
    let (lo, extent) = (bbox.min, bbox.max - bbox.min);
    let offset = u32::from_le_bytes(las[96..100].try_into().unwrap()) as usize;
    let length = usize::from(u16::from_le_bytes([las[105], las[106]]));
    assert_eq!(las[104], 3, "point format 3: RGB at byte 28 of a record");
    let painted: Vec<[u8; 3]> = cloud
        .positions
        .iter()
        .map(|&p| paint(p, lo, extent))
        .collect();
    for (i, rgb) in painted.iter().enumerate() {
        let at = offset + i * length + 28;
        for (k, &c) in rgb.iter().enumerate() {
            las[at + 2 * k..at + 2 * k + 2].copy_from_slice(&(u16::from(c) * 257).to_le_bytes());
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let coloured = dir.path().join("urban_rgb.las");
    std::fs::write(&coloured, &las).unwrap();
    let mesh_path = dir.path().join("urban_mesh.ply");
    let points_path = dir.path().join("urban_points.ply");
    let run = sphcover(&[
        "recon",
        coloured.to_str().unwrap(),
        "-o",
        mesh_path.to_str().unwrap(),
        "--points-out",
        points_path.to_str().unwrap(),
        "--trim",
        "-v",
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    assert!(
        text(&run.stderr).contains("colours"),
        "{}",
        text(&run.stderr)
    );

    let points = io::read_point_cloud(&points_path, &ReadOptions::default()).unwrap();
    assert_eq!(points.colors.as_ref(), Some(&painted));

    // Every vertex carries the colour of a sample near it: one of the painted colours, and
    // close to the paint at the vertex itself. The trimmed surface stays within 3 sample
    // spacings (about 1.6 m) of the samples, a few units of the ramps (255 over 33–92 m);
    // the tail is the barely sampled walls, where the nearest sample is metres away in z.
    let mesh = io::read_mesh(&mesh_path, &ReadOptions::default()).unwrap();
    let colors = mesh.colors.as_ref().expect("the mesh has colours");
    assert_eq!(colors.len(), mesh.vertices.len());
    let palette: std::collections::HashSet<[u8; 3]> = painted.iter().copied().collect();
    assert!(colors.iter().all(|c| palette.contains(c)));
    let mut errors: Vec<u8> = mesh
        .vertices
        .iter()
        .zip(colors)
        .map(|(&v, c)| {
            let want = paint(v, lo, extent);
            (0..3).map(|k| want[k].abs_diff(c[k])).max().unwrap()
        })
        .collect();
    errors.sort_unstable();
    let median = errors[errors.len() / 2];
    let p99 = errors[errors.len() * 99 / 100];
    assert!(
        median <= 4 && p99 <= 30,
        "median {median}, 99th percentile {p99}"
    );

    // What a viewer reads: uchar red green blue beside the confidence as quality.
    let header = std::fs::read(&mesh_path).unwrap();
    let header = text(&header[..header.windows(10).position(|w| w == b"end_header").unwrap()]);
    for line in [
        "property uchar red",
        "property uchar green",
        "property uchar blue",
    ] {
        assert!(header.contains(line), "{header}");
    }
    assert!(header.contains("quality"), "{header}");
}

#[test]
fn a_given_eps_is_used_as_given_and_every_override_says_why() {
    let scan = fixture("sphere_noisy_2k.ply");
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(format!("{name}.ply"));
        let report = dir.path().join(format!("{name}.json"));
        let result = recon_with_report(&scan, &out, &report, extra);
        assert_eq!(result.status.code(), Some(0), "{}", text(&result.stderr));
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
        let eps = report["eps"].as_f64().unwrap();
        (text(&result.stderr), eps, std::fs::read(&out).unwrap())
    };

    // By default the noise raises ε, and the run says so once, with the measured noise.
    let (stderr, auto_eps, auto_mesh) = run("auto", &[]);
    assert!(auto_eps > 4.0 * 2.5e-3, "{auto_eps}");
    assert_eq!(
        stderr
            .matches("note: cover tolerance raised from 2.500e-3")
            .count(),
        1
    );
    assert!(stderr.contains("measured noise"), "{stderr}");

    // A given ε is obeyed, with a warning that it lies below the noise floor, and it
    // changes the surface.
    let (stderr, eps, small) = run("small", &["--eps", "0.004"]);
    assert_eq!(eps, 0.004);
    assert!(
        stderr.contains("warning: --eps 4.000e-3 is below"),
        "{stderr}"
    );
    let (_, eps, larger) = run("larger", &["--eps", "0.008"]);
    assert_eq!(eps, 0.008);
    assert_ne!(small, larger);
    assert_ne!(small, auto_mesh);

    // --noise auto applies the floor to a given ε; off keeps the default ε; a value is the
    // noise to keep to.
    let (stderr, eps, _) = run("given_auto", &["--eps", "0.004", "--noise", "auto"]);
    assert_eq!(eps, auto_eps);
    assert!(stderr.contains("raised from 4.000e-3"), "{stderr}");
    let (stderr, eps, _) = run("off", &["--noise", "off"]);
    assert_eq!(eps, 2.5e-3);
    assert!(
        stderr.contains("warning: --eps 2.500e-3 is below"),
        "{stderr}"
    );
    let (stderr, eps, _) = run("value", &["--noise", "0.002"]);
    assert_eq!(eps, 0.008);
    assert!(stderr.contains("given noise 2.000e-3"), "{stderr}");

    for bad in ["loud", "-1"] {
        let out = dir.path().join("bad.ply");
        let result = sphcover(&[
            "recon",
            scan.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--noise",
            bad,
        ]);
        assert_eq!(result.status.code(), Some(2), "{bad}");
        assert!(
            text(&result.stderr).contains("--noise"),
            "{}",
            text(&result.stderr)
        );
        assert!(!out.exists());
    }
}

#[test]
fn boundaries_of_a_trimmed_surface_share_their_vertices() {
    // The hippo scan is open underneath; trimming leaves boundaries, and where a boundary
    // pinched a vertex the surface used to keep two copies of it at one position.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hippo_trimmed.ply");
    let input = fixture("real/hippo2.ply");
    let run = sphcover(&[
        "recon",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--trim",
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let mesh = io::read_mesh(&out, &ReadOptions::default()).unwrap();
    let mut positions: Vec<[u64; 3]> = mesh
        .vertices
        .iter()
        .map(|v| v.to_array().map(f64::to_bits))
        .collect();
    positions.sort_unstable();
    positions.dedup();
    assert_eq!(positions.len(), mesh.vertices.len(), "coincident vertices");
    let topology = MeshTopology::of(&mesh);
    assert!(topology.is_manifold(), "{}", summary(&topology));
    assert_eq!(topology.non_manifold_vertices, 0, "{}", summary(&topology));
    assert!(topology.boundary_edges > 0, "{}", summary(&topology));
}

#[test]
fn an_open_sheet_beside_a_closed_object_is_not_blamed_on_the_scan() {
    // A closed sphere of samples, and apart from it a small flat patch of stray samples that
    // the reconstruction meshes as an open sheet.
    let sphere = support::fibonacci_sphere(3000);
    let mut points: Vec<DVec3> = sphere.iter().map(|&n| 0.4 * n).collect();
    let mut normals = sphere.clone();
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..200 {
        let r = 0.06 * ((i as f64 + 0.5) / 200.0).sqrt();
        let a = golden * i as f64;
        points.push(DVec3::new(0.9 + r * a.cos(), r * a.sin(), 0.0));
        normals.push(DVec3::Z);
    }
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("sphere_and_patch.ply");
    support::write_points_ply(&scan, &points, Some(&normals));
    let out = dir.path().join("mesh.ply");
    let run = sphcover(&["recon", scan.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let stderr = text(&run.stderr);
    assert!(
        stderr.contains("the object's surface is closed, but 1 other component is an open sheet"),
        "{stderr}"
    );
    assert!(!stderr.contains("does not enclose the object"), "{stderr}");
    let topology = MeshTopology::of(&io::read_mesh(&out, &ReadOptions::default()).unwrap());
    assert_eq!(topology.components, 2);
    assert_eq!(topology.open_component.iter().filter(|&&o| o).count(), 1);
}

#[test]
fn a_single_view_is_not_wrapped_in_invented_surface_by_default() {
    // A raw range scan seen from one side: by default the side the scanner never saw is left
    // out (most of the surface `--trim off` extrapolates), with a note saying so.
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("real/hippo2.ply");
    let area = |mesh: &TriMesh| -> f64 {
        mesh.triangles
            .iter()
            .map(|t| sphcover_core::triangle_area(mesh, t))
            .sum()
    };
    let run_with = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "recon",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let run = sphcover(&args);
        assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
        let mesh = io::read_mesh(&out, &ReadOptions::default()).unwrap();
        (text(&run.stderr), mesh)
    };
    let (note, open) = run_with("default.ply", &[]);
    let (_, closed) = run_with("closed.ply", &["--trim", "off"]);
    assert!(
        note.contains("left out") && note.contains("--trim off"),
        "{note}"
    );
    assert!(!note.contains("the surface is open"), "{note}");
    assert!(MeshTopology::of(&open).boundary_edges > 0);
    let kept = area(&open) / area(&closed);
    assert!(
        kept < 0.35,
        "the default keeps {kept:.2} of the closed surface's area"
    );
}

#[test]
fn tiled_kitten_is_one_closed_surface_beside_the_single_run() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("real/kitten.ply");
    let single = dir.path().join("single.ply");
    let tiled = dir.path().join("tiled.ply");
    let report = dir.path().join("report.json");
    let run = sphcover(&[
        "recon",
        input.to_str().unwrap(),
        "-o",
        single.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let run = recon_with_report(&input, &tiled, &report, &["--tiles", "2,2,1", "-v"]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let stderr = text(&run.stderr);
    assert_eq!(stderr.matches("  tile [").count(), 4, "{stderr}");

    let single = io::read_mesh(&single, &ReadOptions::default()).unwrap();
    let mesh = io::read_mesh(&tiled, &ReadOptions::default()).unwrap();
    let topology = MeshTopology::of(&mesh);
    assert!(
        topology.is_closed_oriented_manifold(),
        "{}",
        summary(&topology)
    );
    assert_eq!(
        (topology.components, topology.euler_characteristic()),
        (1, 0)
    );
    // Every vertex of the tiled surface lies within one grid step (1/64 of the box at the
    // kitten's depth 6) of the single run's surface.
    let index = sphcover_core::PointIndex::new(&single.vertices).unwrap();
    let step = sphcover_core::Aabb::from_points(&single.vertices).longest_edge() / 64.0;
    let mut nearest = Vec::new();
    for &v in &mesh.vertices {
        index.nearest_k_with_distances(v, 1, &mut nearest);
        assert!(nearest[0].0.sqrt() < step, "{v:?}: {}", nearest[0].0.sqrt());
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["tiles"].as_array().map(Vec::len), Some(4));
}

#[test]
fn streamed_hippo_is_the_tiled_surface_and_leaves_no_tile_files() {
    // A partial scan: most of the surface is left out where the scanner did not see it, by
    // the trimming, which a streamed run measures tile by tile.
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("real/hippo2.ply");
    let tiled = dir.path().join("tiled.ply");
    let streamed = dir.path().join("streamed.ply");
    let report = dir.path().join("report.json");
    let scratch = dir.path().join("scratch");
    let run = sphcover(&[
        "recon",
        input.to_str().unwrap(),
        "--tiles",
        "2",
        "-o",
        tiled.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let run = recon_with_report(
        &input,
        &streamed,
        &report,
        &[
            "--tiles",
            "2",
            "--stream",
            "--scratch",
            scratch.to_str().unwrap(),
            "-v",
        ],
    );
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let stderr = text(&run.stderr);
    assert_eq!(stderr.matches("  tile [").count(), 8, "{stderr}");
    for stage in ["tile files", "scan statistics", "trim", "clean and refine"] {
        assert!(stderr.contains(stage), "{stage}: {stderr}");
    }
    assert!(stderr.contains("left out"), "{stderr}");
    let tiled = io::read_mesh(&tiled, &ReadOptions::default()).unwrap();
    let mesh = io::read_mesh(&streamed, &ReadOptions::default()).unwrap();
    let (ours, theirs) = (MeshTopology::of(&mesh), MeshTopology::of(&tiled));
    assert_eq!(
        (ours.components, ours.euler_characteristic()),
        (theirs.components, theirs.euler_characteristic()),
        "{}",
        summary(&ours)
    );
    assert_eq!(ours.non_manifold_edges, 0);
    let area = |m: &TriMesh| -> f64 {
        m.triangles
            .iter()
            .map(|t| sphcover_core::triangle_area(m, t))
            .sum()
    };
    let ratio = area(&mesh) / area(&tiled);
    assert!((ratio - 1.0).abs() < 0.05, "area ratio {ratio}");
    // Within two grid steps (1/64 of the box at depth 6): the scan statistics are measured
    // tile by tile (noise 1.06e-3 against 1.02e-3 here), so ε and the trimmed rim differ a
    // little.
    let step = sphcover_core::Aabb::from_points(&tiled.vertices).longest_edge() / 32.0;
    let index = sphcover_core::PointIndex::new(&tiled.vertices).unwrap();
    let mut nearest = Vec::new();
    for &v in &mesh.vertices {
        index.nearest_k_with_distances(v, 1, &mut nearest);
        assert!(nearest[0].0.sqrt() < step, "{v:?}: {}", nearest[0].0.sqrt());
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["tiles"].as_array().map(Vec::len), Some(8));
    // A single range scan: its normals face one side, measured tile by tile as well.
    assert_eq!(report["one_view"], serde_json::Value::Bool(true));
    assert!(stderr.contains("the scan is one view"), "{stderr}");
    // The scratch directory is left as it was found: empty.
    assert_eq!(std::fs::read_dir(&scratch).unwrap().count(), 0);
}

#[test]
fn streaming_refuses_what_needs_the_whole_scan_and_estimates_missing_normals() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.ply");
    let hippo = fixture("real/hippo2.ply");
    // The same points without normals.
    let bare = dir.path().join("bare.ply");
    let mut cloud = io::read_point_cloud(&hippo, &ReadOptions::default()).unwrap();
    cloud.normals = None;
    io::write_point_cloud(&bare, &cloud, &io::WriteOptions::default()).unwrap();
    let (hippo, bare, output) = (
        hippo.to_str().unwrap(),
        bare.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    let points_out = dir.path().join("points.ply");
    for (input, extra, says) in [
        (hippo, &["--stream"][..], "--tiles"),
        (hippo, &["--tiles", "2", "--scratch", "x"][..], "--stream"),
        (
            hippo,
            &[
                "--tiles",
                "2",
                "--stream",
                "--points-out",
                points_out.to_str().unwrap(),
            ][..],
            "--points-out needs the whole scan",
        ),
    ] {
        let mut args = vec!["recon", input, "-o", output];
        args.extend(extra);
        let run = sphcover(&args);
        let stderr = text(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(says), "{extra:?}: {stderr}");
        assert!(!out.exists() && !points_out.exists());
    }
    // A scan without normals is streamed too: they are estimated tile by tile.
    let run = sphcover(&[
        "recon", bare, "-o", output, "--tiles", "2", "--stream", "-v",
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    assert!(
        text(&run.stderr).contains("normals estimated"),
        "{}",
        text(&run.stderr)
    );
    std::fs::remove_file(&out).unwrap();
    // No tile directory was left beside the output.
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .filter(|n| n.to_string_lossy().starts_with(".sphcover-tiles"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn bad_tilings_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("real/kitten.ply");
    let out = dir.path().join("out.ply");
    let (input, output) = (input.to_str().unwrap(), out.to_str().unwrap());
    for (extra, says) in [
        (&["--tiles", "0"][..], "at least one tile"),
        (&["--tiles", "2,2"][..], "NX,NY,NZ"),
        (&["--halo", "0.2"][..], "--tiles"),
        (&["--tiles", "2", "--halo", "2"][..], "halo"),
        (
            &["--tiles", "2", "--method", "graphcut"][..],
            "cannot be tiled",
        ),
    ] {
        let mut args = vec!["recon", input, "-o", output];
        args.extend(extra);
        let run = sphcover(&args);
        assert_eq!(
            run.status.code(),
            Some(2),
            "{extra:?}: {}",
            text(&run.stderr)
        );
        assert!(
            text(&run.stderr).contains(says),
            "{extra:?}: {}",
            text(&run.stderr)
        );
        assert!(!out.exists());
    }
}

#[test]
fn keep_pinholes_turns_the_pinhole_fill_off() {
    // CGAL's second hippo scan has one tunnel a grid vertex wide (filled by default; the
    // region is trimmed away afterwards as unseen, so both outputs are the same here).
    let scan = fixture("real/hippo2.ply");
    let dir = tempfile::tempdir().unwrap();
    let filled = |extra: &[&str]| {
        let out = dir.path().join("out.ply");
        let mut args = vec![
            "-v",
            "recon",
            scan.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let result = sphcover(&args);
        assert_eq!(result.status.code(), Some(0), "{}", text(&result.stderr));
        let stderr = text(&result.stderr);
        stderr
            .lines()
            .find(|l| l.contains("polygonise:"))
            .unwrap_or_else(|| panic!("no polygonise line in {stderr}"))
            .to_owned()
    };
    assert!(filled(&[]).contains(", 1 pinholes filled;"));
    assert!(filled(&["--keep-pinholes"]).contains(", 0 pinholes filled;"));
}
