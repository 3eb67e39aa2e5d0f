//! `sphcover cover SAMPLES.ply --value-property NAME`: the volume cover of scattered samples
//! with values, its round trip, and its bad input.

mod support;

use std::path::Path;

use glam::DVec3;
use support::{run as sphcover, text, write_jittered_samples};

/// Writes an ascii PLY of jittered samples of a blurred ball with the value in `density`
/// (and `nan` at sample `nan_at`, when given).
fn write_samples(path: &Path, nan_at: Option<usize>) {
    let n = 12;
    let centre = DVec3::splat(0.5 * (n as f64 - 1.0));
    write_jittered_samples(path, [n; 3], 0x2545_f491_4f6c_dd1d, |p, sample| {
        if nan_at == Some(sample) {
            f64::NAN
        } else {
            1000.0 / (1.0 + ((p.distance(centre) - 4.0) / 1.2).exp())
        }
    });
}

#[test]
fn scattered_samples_give_a_volume_cover_read_back_and_independent_of_threads() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("samples.ply");
    write_samples(&input, None);
    let outs = [dir.path().join("one.ply"), dir.path().join("two.ply")];
    for (threads, out) in ["1", "2"].iter().zip(&outs) {
        let run = sphcover(&[
            "--threads",
            threads,
            "cover",
            input.to_str().unwrap(),
            "--value-property",
            "density",
            "--threshold",
            "500",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
        assert!(
            text(&run.stderr).contains("0 over ε"),
            "{}",
            text(&run.stderr)
        );
    }
    assert!(std::fs::read(&outs[0]).unwrap() == std::fs::read(&outs[1]).unwrap());
    let (cover, _) = sphcover_core::io::read_cover(&outs[0]).unwrap();
    assert!(
        cover.len() > 1 && cover.len() < 12 * 12 * 12 / 4,
        "{}",
        cover.len()
    );
}

#[test]
fn scattered_samples_bad_input_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("samples.ply");
    write_samples(&input, None);
    let out = dir.path().join("c.ply");
    let cover = |input: &Path, property: &str, extra: &[&str]| {
        let mut args = vec![
            "cover",
            input.to_str().unwrap(),
            "--value-property",
            property,
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        sphcover(&args)
    };
    let run = cover(&input, "intensity", &[]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    assert!(text(&run.stderr).contains("no scalar vertex property named `intensity`"));
    let run = cover(&input, "density", &["--threshold", "5000"]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    assert!(
        text(&run.stderr).contains("selects no voxel"),
        "{}",
        text(&run.stderr)
    );
    let constant = dir.path().join("constant.ply");
    std::fs::write(
        &constant,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nproperty float density\nend_header\n0 0 0 4\n1 0 0 4\n0 1 0 4\n",
    )
    .unwrap();
    let run = cover(&constant, "density", &[]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    assert!(
        text(&run.stderr).contains("constant"),
        "{}",
        text(&run.stderr)
    );
    let nan = dir.path().join("nan.ply");
    write_samples(&nan, Some(17));
    let run = cover(&nan, "density", &[]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    assert!(
        text(&run.stderr).contains("nan.ply: vertex 17: `density` is not finite (1 sample"),
        "{}",
        text(&run.stderr)
    );
    assert!(!out.exists());
}
