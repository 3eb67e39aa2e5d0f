//! `sphcover skeleton SAMPLES.ply --value-property NAME`: the sheet of scattered samples
//! with values, independent of the thread count, and its bad input.

mod support;

use std::path::Path;

use support::{files_in, run as sphcover, text, write_jittered_samples};

/// Writes an ascii PLY of jittered samples of a plate 4 units thick (z = 6 … 10), faces
/// blurred over about one unit, HU-like values in `density` (all `constant` when given).
fn write_plate_samples(path: &Path, constant: Option<f64>) {
    write_jittered_samples(path, [20, 20, 16], 0x9e37_79b9_7f4a_7c15, |p, _| {
        let inside = 2.0 - (p.z - 8.0).abs();
        constant.unwrap_or(-1000.0 + 1500.0 * (1.0 + (inside / 0.8).tanh()))
    });
}

#[test]
fn scattered_samples_give_one_mid_plane_sheet_whatever_the_threads() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("samples.ply");
    write_plate_samples(&input, None);
    let outs = [dir.path().join("one.ply"), dir.path().join("two.ply")];
    for (threads, out) in ["1", "2"].iter().zip(&outs) {
        let run = sphcover(&[
            "--threads",
            threads,
            "skeleton",
            input.to_str().unwrap(),
            "--value-property",
            "density",
            "-o",
            out.to_str().unwrap(),
        ]);
        let stderr = text(&run.stderr);
        assert_eq!(run.status.code(), Some(0), "{stderr}");
        assert!(stderr.contains("1 component,"), "{stderr}");
        assert!(stderr.contains("(automatic)"), "{stderr}");
    }
    assert!(std::fs::read(&outs[0]).unwrap() == std::fs::read(&outs[1]).unwrap());
    let sheet = sphcover_core::io::read_mesh(&outs[0], &Default::default()).unwrap();
    assert!(sheet.triangles.len() > 100, "{}", sheet.triangles.len());
    assert!(sheet.vertices.iter().all(|v| (v.z - 8.0).abs() < 0.5));
}

#[test]
fn scattered_sample_bad_input_is_refused_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("samples.ply");
    write_plate_samples(&input, None);
    let flat = dir.path().join("flat.ply");
    write_plate_samples(&flat, Some(5.0));
    let out = dir.path().join("sheet.ply");
    let out_arg = out.to_str().unwrap();
    let cases: [(&Path, &[&str], &str); 5] = [
        (
            &input,
            &["--value-property", "intensity"],
            "no scalar vertex property named `intensity`",
        ),
        (
            &input,
            &["--value-property", "density", "--method", "nms"],
            "works on a voxel grid",
        ),
        (
            &input,
            &["--value-property", "density", "--threshold", "1e6"],
            "selects no voxel",
        ),
        (&flat, &["--value-property", "density"], "constant"),
        (
            &input,
            &[],
            "name their value property with --value-property",
        ),
    ];
    for (path, extra, message) in cases {
        let mut args = vec!["skeleton", path.to_str().unwrap(), "-o", out_arg];
        args.extend_from_slice(extra);
        let run = sphcover(&args);
        let stderr = text(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(message), "{extra:?}: {stderr}");
        assert!(!out.exists(), "{extra:?}");
    }
    let mut names = files_in(dir.path());
    names.sort();
    assert_eq!(names, ["flat.ply", "samples.ply"]);
}

/// A sample whose value is NaN or infinite is refused as a vertex with such a coordinate is,
/// naming it; `--drop-non-finite` drops it with a warning.
#[test]
fn non_finite_sample_values_are_refused_or_dropped_with_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let nan_at = [17usize, 4000];
    let holed = dir.path().join("holed.ply");
    write_jittered_samples(&holed, [20, 20, 16], 7, |p, n| {
        if nan_at.contains(&n) {
            f64::NAN
        } else {
            -1000.0 + 1500.0 * (1.0 + ((2.0 - (p.z - 8.0).abs()) / 0.8).tanh())
        }
    });
    let out = dir.path().join("sheet.ply");
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            holed.to_str().unwrap().to_owned(),
            "-o".to_owned(),
            out.to_str().unwrap().to_owned(),
            "--value-property".to_owned(),
            "density".to_owned(),
        ];
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let mut refused = vec!["skeleton".to_owned()];
    refused.extend(args(&[]));
    let refused: Vec<&str> = refused.iter().map(String::as_str).collect();
    let run = sphcover(&refused);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("holed.ply: vertex 17: `density` is not finite (2 samples with a NaN or infinite value); --drop-non-finite drops them"),
        "{stderr}"
    );
    assert!(!out.exists());
    let mut dropped = vec!["skeleton".to_owned()];
    dropped.extend(args(&["--drop-non-finite"]));
    let dropped: Vec<&str> = dropped.iter().map(String::as_str).collect();
    let run = sphcover(&dropped);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("dropped 2 samples whose `density` is NaN or infinite"),
        "{stderr}"
    );
    assert!(out.exists());
}
