//! Output paths and bounded options are checked before any work: each case below names an
//! input that does not exist, so a run that started reading would report that instead.

mod support;

use std::time::Duration;

use support::{files_in, sphcover_in, text};

const LIMIT: Duration = Duration::from_secs(60);

#[test]
fn bad_outputs_are_refused_before_the_input_is_read() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    std::fs::create_dir(dir.path().join("sub.png")).unwrap();
    std::fs::write(dir.path().join("file"), b"").unwrap();
    // (arguments, exit code, what the message says)
    let cases: &[(&[&str], i32, &str)] = &[
        (
            &["recon", "in.ply", "-o", "out.nii"],
            2,
            "must end in .ply, .obj, .off, .stl, .vtp, .vtu",
        ),
        (
            &["recon", "in.ply", "-o", "out"],
            2,
            "must end in .ply, .obj, .off, .stl, .vtp, .vtu",
        ),
        (
            &["recon", "in.ply", "-o", "m.ply", "--report", "r.txt"],
            2,
            "--report must end in .json",
        ),
        (
            &["recon", "in.ply", "-o", "m.ply", "--points-out", "p.xyz"],
            2,
            "--points-out must end in .ply",
        ),
        (
            &["recon", "in.ply", "-o", "m.ply", "--cover-out", "m.ply"],
            2,
            "named as two outputs",
        ),
        (
            &[
                "recon",
                "in.ply",
                "-o",
                "sub.ply",
                "--cover-out",
                "./sub/../sub.ply",
            ],
            2,
            "named as two outputs",
        ),
        (
            &["recon", "in.ply", "-o", "missing/m.ply"],
            1,
            "missing does not exist",
        ),
        (
            &["recon", "in.ply", "-o", "file/m.ply"],
            1,
            "file is not a directory",
        ),
        (
            &["recon", "in.ply", "-o", "/proc/m.ply"],
            1,
            "cannot write in /proc",
        ),
        (
            &["skeleton", "in.nii", "-o", "sheet.xyz"],
            2,
            "must end in .ply, .obj, .off, .stl, .vtp, .vtu",
        ),
        (
            &["skeleton", "in.nii", "--method", "nms", "-o", "pts.stl"],
            2,
            "must end in .ply, .xyz, .vtp",
        ),
        (
            &["cover", "in.ply", "-o", "cover.nii"],
            2,
            "the cover output (-o) must end in .ply",
        ),
        (
            &["tetra", "in.sph", "-o", "mesh.ply"],
            2,
            "must end in .vtk, .vtu, .txt, .tets",
        ),
        (
            &["render", "in.ply", "-o", "view.jpg"],
            2,
            "must end in .png",
        ),
        (&["render", "in.ply", "-o", "sub.png"], 2, "is a directory"),
    ];
    for &(args, code, message) in cases {
        let run = sphcover_in(Some(dir.path()), args, LIMIT);
        let stderr = text(&run.stderr);
        assert_eq!(
            run.status.code(),
            Some(code),
            "{}: {stderr}",
            args.join(" ")
        );
        assert!(stderr.contains(message), "{}: {stderr}", args.join(" "));
        assert!(
            !stderr.contains("in.ply:"),
            "{}: read the input first: {stderr}",
            args.join(" ")
        );
    }
    assert_eq!(files_in(dir.path()), ["file", "sub", "sub.png"]);
}

#[test]
fn bounded_options_are_refused_or_reduced() {
    let dir = tempfile::tempdir().unwrap();
    let run = sphcover_in(
        Some(dir.path()),
        &[
            "recon",
            "in.ply",
            "-o",
            "m.ply",
            "--normal-neighbours",
            "100000",
        ],
        LIMIT,
    );
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--normal-neighbours 100000 must be in 3..=500"),
        "{stderr}"
    );

    // Far more threads than cores: reduced with a warning, not thousands started.
    let run = sphcover_in(
        Some(dir.path()),
        &["--threads", "100000", "info", "missing.ply"],
        LIMIT,
    );
    let stderr = text(&run.stderr);
    assert!(
        stderr.contains("--threads 100000 is more than 4 per logical core"),
        "{stderr}"
    );
    assert!(stderr.contains("missing.ply"), "{stderr}");
}
