//! End-to-end tests of `sphcover skeleton`: the bundled CT phantom, the NMS baseline, and
//! every kind of bad input the command must refuse with exit code 2 and no output file.

mod support;

use std::path::Path;

use support::{fixture, run as sphcover, text};

/// A minimal NIfTI-1 file of `float32` values: `dims` (3 or 4 entries), voxel sizes, and an
/// optional sform (three rows of the voxel→world map).
fn write_nifti(
    path: &Path,
    dims: &[usize],
    voxel: [f32; 3],
    sform: Option<[[f32; 4]; 3]>,
    values: &[f32],
) {
    let mut b = vec![0u8; 352];
    b[0..4].copy_from_slice(&348i32.to_le_bytes());
    let mut dim = [1i16; 8];
    dim[0] = dims.len() as i16;
    for (k, &d) in dims.iter().enumerate() {
        dim[k + 1] = d as i16;
    }
    for (k, d) in dim.iter().enumerate() {
        b[40 + 2 * k..42 + 2 * k].copy_from_slice(&d.to_le_bytes());
    }
    b[70..72].copy_from_slice(&16i16.to_le_bytes());
    b[72..74].copy_from_slice(&32i16.to_le_bytes());
    let pixdim = [1.0f32, voxel[0], voxel[1], voxel[2], 1.0, 1.0, 1.0, 1.0];
    for (k, p) in pixdim.iter().enumerate() {
        b[76 + 4 * k..80 + 4 * k].copy_from_slice(&p.to_le_bytes());
    }
    b[108..112].copy_from_slice(&352f32.to_le_bytes());
    if let Some(rows) = sform {
        b[254..256].copy_from_slice(&1i16.to_le_bytes());
        for (i, row) in rows.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                b[280 + 16 * i + 4 * c..284 + 16 * i + 4 * c].copy_from_slice(&v.to_le_bytes());
            }
        }
    }
    b[344..348].copy_from_slice(b"n+1\0");
    for v in values {
        b.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, b).unwrap();
}

/// A 24³ slab of thickness 4 (HU: air −1000, material 2000) with a one-voxel linear rim.
fn slab_values(frames: usize) -> Vec<f32> {
    let n = 24;
    let mut v = Vec::new();
    for _ in 0..frames {
        for k in 0..n {
            for _ in 0..n * n {
                let inside = (2.5 - (k as f32 - 11.3).abs()).clamp(0.0, 1.0);
                v.push(-1000.0 + 3000.0 * inside);
            }
        }
    }
    v
}

#[test]
fn skeleton_of_the_t_junction_phantom_is_one_sheet() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("sheet.ply");
    let input = fixture("phantoms/t_junction_ct_n000.nii.gz");
    let out = sphcover(&[
        "skeleton",
        input.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
        "-v",
        "--ascii",
    ]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    for needle in [
        "object voxels",
        "supports",
        "tetrahedra",
        "ridge points",
        "triangles",
        "1 component,",
        // The true sheet's: the tunnels the junction leaves are closed.
        "Euler characteristic 1;",
        // -v times every stage, repairs included.
        "  cover ",
        "  rim trimming ",
        "  junction planes ",
    ] {
        assert!(err.contains(needle), "missing {needle:?} in {err}");
    }
    let ply = std::fs::read_to_string(&out_path).unwrap();
    let faces: usize = ply
        .lines()
        .find_map(|l| l.strip_prefix("element face "))
        .and_then(|n| n.trim().parse().ok())
        .unwrap();
    assert!(faces > 1000, "{faces} faces");
}

#[test]
fn nms_baseline_writes_points() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("nms.ply");
    let input = fixture("phantoms/t_junction_ct_n000.nii.gz");
    let out = sphcover(&[
        "skeleton",
        input.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
        "--method",
        "nms",
        "--sigma",
        "1.5",
        "--ascii",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let ply = std::fs::read_to_string(&out_path).unwrap();
    assert!(!ply.contains("element face"));
    assert!(text(&out.stderr).contains("ridge points"));
}

#[test]
fn the_same_seed_gives_the_same_sheet_whatever_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("phantoms/t_junction_ct_n000.nii.gz");
    let mut files = Vec::new();
    for threads in ["1", "2"] {
        let out_path = dir.path().join(format!("sheet{threads}.ply"));
        let out = sphcover(&[
            "skeleton",
            input.to_str().unwrap(),
            "-o",
            out_path.to_str().unwrap(),
            "--threads",
            threads,
            "--seed",
            "3",
        ]);
        assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
        files.push(std::fs::read(&out_path).unwrap());
    }
    assert_eq!(files[0], files[1]);
}

#[test]
fn bad_inputs_exit_2_without_writing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ok = d.join("slab.nii");
    write_nifti(&ok, &[24, 24, 24], [0.5; 3], None, &slab_values(1));
    let four_d = d.join("4d.nii");
    write_nifti(&four_d, &[24, 24, 24, 2], [0.5; 3], None, &slab_values(2));
    let aniso = d.join("aniso.nii");
    // 9:1, beyond what resampling takes.
    write_nifti(
        &aniso,
        &[24, 24, 24],
        [0.5, 0.5, 4.5],
        None,
        &slab_values(1),
    );
    let oblique = d.join("oblique.nii");
    let (c, s) = (
        0.5 * 30f32.to_radians().cos(),
        0.5 * 30f32.to_radians().sin(),
    );
    let rows = [[c, -s, 0.0, 0.0], [s, c, 0.0, 0.0], [0.0, 0.0, 0.5, 0.0]];
    write_nifti(
        &oblique,
        &[24, 24, 24],
        [0.5; 3],
        Some(rows),
        &slab_values(1),
    );
    let constant = d.join("constant.nii");
    write_nifti(&constant, &[8, 8, 8], [1.0; 3], None, &[5.0; 512]);
    let speck = d.join("speck.nii");
    let mut one = vec![0.0f32; 512];
    one[4 + 8 * (4 + 8 * 4)] = 100.0;
    write_nifti(&speck, &[8, 8, 8], [1.0; 3], None, &one);
    let points = fixture("sphere_2k.ply");

    let cases: Vec<(&Path, Vec<&str>, &str)> = vec![
        (&four_d, vec![], "4D volume with 2 frames"),
        (&aniso, vec![], "too anisotropic (more than 8:1)"),
        (&oblique, vec![], "oblique"),
        (&ok, vec!["--threshold", "1e6"], "selects no voxel"),
        (&ok, vec!["--threshold=-1e6"], "selects every voxel"),
        (&ok, vec!["--sigma", "0"], "--sigma"),
        (&constant, vec![], "constant"),
        (&speck, vec![], "empty result"),
        (&points, vec![], "expected a CT volume"),
    ];
    for (input, extra, message) in cases {
        let out_path = d.join("out.ply");
        let mut args = vec![
            "skeleton",
            input.to_str().unwrap(),
            "-o",
            out_path.to_str().unwrap(),
        ];
        args.extend(extra.iter());
        let out = sphcover(&args);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{input:?} {extra:?}: {err}");
        assert!(err.contains(message), "{input:?} {extra:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out_path.exists(), "{input:?} {extra:?} wrote a file");
    }
    // The well-formed slab itself works, with the NMS baseline too.
    for method in ["ridge", "nms"] {
        let out_path = d.join(format!("{method}.ply"));
        let out = sphcover(&[
            "skeleton",
            ok.to_str().unwrap(),
            "-o",
            out_path.to_str().unwrap(),
            "--method",
            method,
        ]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{method}: {}",
            text(&out.stderr)
        );
        assert!(out_path.exists());
    }
}

/// The plane of [`thick_slice_plate`]: unit normal (tilted 25° off the slices) and offset.
fn thick_slice_plane() -> ([f64; 3], f64) {
    let tilt = 25f64.to_radians();
    ([0.0, -tilt.sin(), tilt.cos()], 2.4)
}

/// A plate 3 thick on 48 x 48 x 12 voxels of 0.5 x 0.5 x 1.5, its faces blurred as a
/// scanner blurs them (0.8 pixel in-plane, 0.8 slice across the slices).
fn thick_slice_plate() -> Vec<f32> {
    let (n, c) = thick_slice_plane();
    let width = ((0.4 * n[1]).powi(2) + (1.2 * n[2]).powi(2)).sqrt();
    let mut v = Vec::new();
    for k in 0..12 {
        for j in 0..48 {
            for _ in 0..48 {
                let u = n[1] * 0.5 * j as f64 + n[2] * 1.5 * k as f64 - c;
                let inside = 0.5 * (((1.5 - u) / width).tanh() + ((1.5 + u) / width).tanh());
                v.push((-1000.0 + 3000.0 * inside) as f32);
            }
        }
    }
    v
}

/// Slices three times the pixels are resampled (said on a note line without -v), the sheet
/// is on the plate's mid-plane in world coordinates, the report records the grids, and the
/// memory prediction is the resampled grid's.
#[test]
fn thick_slices_are_resampled_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = d.join("thick.nii");
    write_nifti(
        &input,
        &[48, 48, 12],
        [0.5, 0.5, 1.5],
        None,
        &thick_slice_plate(),
    );
    let sheet = d.join("sheet.ply");
    let report = d.join("report.json");
    let out = sphcover(&[
        "skeleton",
        input.to_str().unwrap(),
        "-o",
        sheet.to_str().unwrap(),
        "--ascii",
        "--report",
        report.to_str().unwrap(),
    ]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let note = "note: {}: voxels of 0.500000 x 0.500000 x 1.500000 are more than 1.75:1 \
                anisotropic; resampled by 2 along voxel axis k (spacing 1.500000 -> 0.750000) \
                with cubic (Catmull-Rom) interpolation; 48 x 48 x 23 voxels\n";
    assert!(
        err.contains(&note.replace("{}", &input.display().to_string())),
        "{err}"
    );
    assert!(err.contains("1 component,"), "{err}");

    let ply = std::fs::read_to_string(&sheet).unwrap();
    let vertices: usize = ply
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .and_then(|n| n.trim().parse().ok())
        .unwrap();
    let body = ply.split("end_header\n").nth(1).unwrap();
    let (n, c) = thick_slice_plane();
    let off: Vec<f64> = body
        .lines()
        .take(vertices)
        .map(|l| {
            let x: Vec<f64> = l
                .split_whitespace()
                .take(3)
                .map(|v| v.parse().unwrap())
                .collect();
            (n[0] * x[0] + n[1] * x[1] + n[2] * x[2] - c).abs()
        })
        .collect();
    assert!(off.len() > 100);
    // In world coordinates on the mid-plane, though the slices are 1.5 apart.
    assert!(off.iter().all(|&d| d < 0.3), "{off:?}");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["resampled"]["factors"], serde_json::json!([1, 1, 2]));
    assert_eq!(
        json["resampled"]["input_dims"],
        serde_json::json!([48, 48, 12])
    );
    assert_eq!(json["resampled"]["dims"], serde_json::json!([48, 48, 23]));
    // Slices three times the pixels: the sheet across the plate is placed on their centroid.
    assert!(json["slice_centred_vertices"].as_u64().unwrap() > 0);
    // And the ridge test took the Hessian with the slice axis compressed.
    assert!(json["hessian_slice_stretch"].as_f64().unwrap() > 1.0);
    // And the rim test measured across the slices by the square root of its factor.
    let rim = json["rim_slice_stretch"].as_f64().unwrap();
    let hessian = json["hessian_slice_stretch"].as_f64().unwrap();
    assert!((rim - hessian.sqrt()).abs() < 1e-12, "{rim} {hessian}");

    let out = sphcover(&[
        "skeleton",
        input.to_str().unwrap(),
        "-o",
        d.join("never.ply").to_str().unwrap(),
        "--max-memory",
        "1M",
    ]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("extracting the sheet of 48 x 48 x 23 voxels (resampled from 48 x 48 x 12)"),
        "{err}"
    );
}

#[test]
fn the_report_file_holds_the_stage_counts() {
    let dir = tempfile::tempdir().unwrap();
    let sheet = dir.path().join("sheet.ply");
    let report = dir.path().join("report.json");
    let input = fixture("phantoms/t_junction_ct_n000.nii.gz");
    let out = sphcover(&[
        "skeleton",
        input.to_str().unwrap(),
        "-o",
        sheet.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["components"], 1);
    assert!(json["triangles"].as_u64().unwrap() > 1000);
    assert!(json["supports"].as_u64().unwrap() > 100);
    let stages: Vec<&str> = json["stages_seconds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    let default = sphcover_skeleton::SkeletonParams::default();
    assert_eq!(stages, sphcover_skeleton::stage_names(&default));
    assert!(json["tunnels_closed"].is_u64());
    assert!(json["perforations_cut"].is_u64());
    assert!(json["flap_triangles_collapsed"].is_u64());
    assert!(json["resampled"].is_null());
    assert_eq!(json["slice_centred_vertices"], 0);
    assert_eq!(json["off_plate_triangles_collapsed"], 0);
    assert!(json["hessian_slice_stretch"].is_null());
    assert!(json["rim_slice_stretch"].is_null());
}

/// Voxels holding NaN or an infinity are refused by every command that processes a volume,
/// naming the first one; with `--drop-non-finite` they become background, so a slab whose
/// air holds them gives the sheet of the clean slab byte for byte. `info` counts them.
#[test]
fn non_finite_voxels_are_refused_or_with_the_flag_become_background() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let clean = d.join("clean.nii");
    write_nifti(&clean, &[24, 24, 24], [0.5; 3], None, &slab_values(1));
    let mut values = slab_values(1);
    // In the air (k = 0 and k = 23), below and above the slab; (7, 1, 0) comes first.
    let at = |i: usize, j: usize, k: usize| i + 24 * (j + 24 * k);
    values[at(5, 6, 0)] = f32::NAN;
    values[at(7, 1, 0)] = f32::INFINITY;
    values[at(3, 3, 23)] = f32::NEG_INFINITY;
    let holed = d.join("holed.nii");
    write_nifti(&holed, &[24, 24, 24], [0.5; 3], None, &values);
    let all_nan = d.join("all_nan.nii");
    write_nifti(&all_nan, &[8, 8, 8], [1.0; 3], None, &[f32::NAN; 512]);

    let path = |p: &Path| p.to_str().unwrap().to_owned();
    let out = d.join("out.ply");
    let refusals: [Vec<String>; 4] = [
        vec!["skeleton".into(), path(&holed), "-o".into(), path(&out)],
        vec![
            "skeleton".into(),
            path(&holed),
            "-o".into(),
            path(&out),
            "--method".into(),
            "nms".into(),
        ],
        vec!["cover".into(), path(&holed), "-o".into(), path(&out)],
        vec![
            "skeleton".into(),
            path(&all_nan),
            "-o".into(),
            path(&out),
            "--drop-non-finite".into(),
        ],
    ];
    for args in &refusals {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let run = sphcover(&args);
        let err = text(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote a file");
        if args[1].ends_with("holed.nii") {
            assert!(
                err.contains(
                    "holed.nii: voxel (7, 1, 0) is not finite (3 voxels hold NaN or an infinity); --drop-non-finite makes them background"
                ),
                "{err}"
            );
            assert!(err.contains("--drop-non-finite"), "{err}");
        } else {
            assert!(
                err.contains("512 voxels hold NaN or an infinity: every voxel"),
                "{err}"
            );
        }
    }

    for method in ["ridge", "nms"] {
        let sheet = |input: &Path, name: &str, extra: &[&str]| {
            let output = d.join(format!("{name}-{method}.ply"));
            let mut args = vec![
                "skeleton",
                input.to_str().unwrap(),
                "-o",
                output.to_str().unwrap(),
                "--method",
                method,
            ];
            args.extend_from_slice(extra);
            let run = sphcover(&args);
            assert_eq!(
                run.status.code(),
                Some(0),
                "{args:?}: {}",
                text(&run.stderr)
            );
            (std::fs::read(&output).unwrap(), text(&run.stderr))
        };
        let (expected, _) = sheet(&clean, "clean", &[]);
        let (dropped, warning) = sheet(&holed, "dropped", &["--drop-non-finite"]);
        assert!(expected == dropped, "{method}: the sheets differ");
        assert!(
            warning.contains("3 voxels holding NaN or an infinity set to the lowest finite value"),
            "{warning}"
        );
    }

    let info = sphcover(&["info", holed.to_str().unwrap(), "--json"]);
    assert_eq!(info.status.code(), Some(0), "{}", text(&info.stderr));
    assert!(
        text(&info.stdout).contains("\"non_finite_voxels\": 3"),
        "{}",
        text(&info.stdout)
    );
}

/// A 40³ CT in HU of 1 mm voxels: a ball of soft tissue (+40, radius 16) in air, holding a
/// bone shell (+1200, radii 11–13).
fn head_values() -> Vec<f32> {
    let n = 40;
    let mut v = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r = [i, j, k]
                    .iter()
                    .map(|&c| (c as f32 - 19.5).powi(2))
                    .sum::<f32>()
                    .sqrt();
                v.push(if (11.0..=13.0).contains(&r) {
                    1200.0
                } else if r <= 16.0 {
                    40.0
                } else {
                    -1000.0
                });
            }
        }
    }
    v
}

#[test]
fn a_ct_in_hounsfield_units_takes_its_thin_material() {
    let dir = tempfile::tempdir().unwrap();
    let ct = dir.path().join("head.nii");
    write_nifti(&ct, &[40, 40, 40], [1.0; 3], None, &head_values());
    let out_path = dir.path().join("sheet.ply");
    let out = sphcover(&[
        "skeleton",
        ct.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
    ]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.contains("note: CT in Hounsfield units (air -1000, soft tissue +40): bone is the thin material, above 230 HU"),
        "{err}"
    );
    assert!(
        err.contains("choose another with --material or --threshold"),
        "{err}"
    );
    // The shell's sheet: every vertex near the middle radius 12.
    let sheet = sphcover_core::io::read_mesh(&out_path, &Default::default()).unwrap();
    assert!(!sheet.triangles.is_empty());
    for v in &sheet.vertices {
        let r = (*v - sphcover_core::DVec3::splat(19.5)).length();
        assert!((r - 12.0).abs() < 1.0, "{r}");
    }
    // Without materials the threshold splits air from the body: the whole ball, thick.
    let out = sphcover(&[
        "skeleton",
        ct.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
        "--material",
        "off",
    ]);
    let err = text(&out.stderr);
    assert!(!err.contains("note: CT"), "{err}");
    assert!(err.contains("threshold -"), "{err}");
    // A material needs a CT: the phantom of air and one material has no soft tissue.
    let out = sphcover(&[
        "skeleton",
        fixture("phantoms/t_junction_ct_n000.nii.gz")
            .to_str()
            .unwrap(),
        "-o",
        out_path.to_str().unwrap(),
        "--material",
        "bone",
    ]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--material bone needs a CT in Hounsfield units"),
        "{err}"
    );
}
