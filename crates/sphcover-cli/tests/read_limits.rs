//! The memory limit of the commands' readers (`src/memory_limit.rs`): decompression bombs
//! (small gzip volumes whose headers declare gigabytes, over streams of zeros that really
//! inflate to them) are refused from their headers by `info`, `skeleton` and `cover` with
//! exit 2 and a message naming the file, its sizes and the limit, instead of dying in a
//! failed allocation. The default limit is a share of the memory the process may use, so the
//! tests lower it with `ulimit -v` as a user capping a run does.
#![cfg(target_os = "linux")]

mod support;

use std::path::Path;
use std::time::Duration;

use support::{files_in, sphcover, sphcover_under_ulimit, text, write_bombs};

/// Far above what refusing from a header takes; a bomb that is read instead takes longer.
const LIMIT: Duration = Duration::from_secs(60);
/// A 2 GiB address space: a default reader limit of 1.2 GiB.
const ULIMIT_KIB: u64 = 2 << 20;

/// The command lines of `info`, `skeleton` and `cover` on `input`, writing into `dir`.
fn commands(input: &Path, dir: &Path) -> Vec<Vec<String>> {
    let input = input.to_str().unwrap().to_owned();
    let out = dir.join("out.ply").to_str().unwrap().to_owned();
    vec![
        vec!["info".into(), input.clone()],
        vec!["skeleton".into(), input.clone(), "-o".into(), out.clone()],
        vec!["cover".into(), input, "-o".into(), out],
    ]
}

#[test]
fn bombs_are_refused_from_the_header_by_info_skeleton_and_cover() {
    let dir = tempfile::tempdir().unwrap();
    let bombs = write_bombs(dir.path());
    for bomb in &bombs {
        let name = bomb.file_name().unwrap().to_str().unwrap();
        for args in commands(bomb, dir.path()) {
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let run = sphcover_under_ulimit(ULIMIT_KIB, &args, LIMIT);
            let stderr = text(&run.stderr);
            assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
            assert!(stderr.contains(name), "{args:?}: {stderr}");
            assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
            if args[0] == "skeleton" {
                // The pipeline's own model, from the header, refuses first.
                assert!(stderr.contains("extracting the sheet of"), "{stderr}");
                assert!(
                    stderr.contains("pass --max-memory to try anyway"),
                    "{stderr}"
                );
            } else {
                assert!(stderr.contains(": declares "), "{args:?}: {stderr}");
                assert!(
                    stderr.contains("in memory, above the memory limit"),
                    "{args:?}: {stderr}"
                );
                assert!(stderr.contains("(60% of "), "{args:?}: {stderr}");
            }
        }
    }
    let message = {
        let args = ["info", bombs[0].to_str().unwrap()];
        text(&sphcover_under_ulimit(ULIMIT_KIB, &args, LIMIT).stderr)
    };
    assert!(
        message.contains(&format!(
            "{}: declares 1024 x 1024 x 512 voxels of int16 (1.0 GiB decoded, held as float32): 2.0 GiB in memory, above the memory limit",
            bombs[0].display()
        )),
        "{message}"
    );
    // Nothing written besides the bombs.
    assert_eq!(
        files_in(dir.path()),
        ["bomb_1g.nii.gz", "bomb_2g.inr.gz", "bomb_8g.nii.gz"]
    );
}

/// `--max-memory` raises the readers' limit of `info`, `cover`, `tetra` and `render` too; when
/// the system then refuses the memory (here an address-space limit below what the bomb
/// declares), the run ends with exit 1 and a message naming the file and the size, never an
/// abort. A limit below the file's data refuses it from the header, naming the flag.
#[test]
fn max_memory_sets_the_readers_limit_and_a_refused_allocation_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let bombs = write_bombs(dir.path());
    let bomb = bombs[0].to_str().unwrap();
    let out = dir.path().join("out.ply");
    let out = out.to_str().unwrap();
    for args in [
        vec!["info", bomb, "--max-memory", "100G"],
        vec!["cover", bomb, "-o", out, "--max-memory", "100G"],
    ] {
        let run = sphcover_under_ulimit(ULIMIT_KIB, &args, LIMIT);
        let stderr = text(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains(&format!(
                "{bomb}: cannot allocate 2.0 GiB for 536870912 voxel values"
            )),
            "{args:?}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
    let spheres = dir.path().join("spheres.sph");
    std::fs::write(&spheres, "0 0 0 1\n1 0 0 1\n0 1 0 1\n0 0 1 1\n1 1 1 1\n").unwrap();
    let spheres = spheres.to_str().unwrap();
    let tets = dir.path().join("out.vtk");
    let png = dir.path().join("out.png");
    for args in [
        vec!["info", bomb, "--max-memory", "1M"],
        vec![
            "tetra",
            spheres,
            "-o",
            tets.to_str().unwrap(),
            "--max-memory",
            "100",
        ],
        vec![
            "render",
            spheres,
            "-o",
            png.to_str().unwrap(),
            "--max-memory",
            "100",
        ],
    ] {
        let run = sphcover(&args, LIMIT);
        let stderr = text(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("above the memory limit") && stderr.contains("(--max-memory)"),
            "{args:?}: {stderr}"
        );
    }
    assert_eq!(
        files_in(dir.path()),
        [
            "bomb_1g.nii.gz",
            "bomb_2g.inr.gz",
            "bomb_8g.nii.gz",
            "spheres.sph"
        ]
    );
}

#[test]
fn skeleton_checks_max_memory_from_the_header_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    let bombs = write_bombs(dir.path());
    let out = dir.path().join("sheet.ply");
    for bomb in &bombs {
        let args = [
            "skeleton",
            bomb.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--max-memory",
            "1G",
        ];
        // No address-space limit: only the header can keep this from reading gigabytes.
        let run = sphcover(&args, LIMIT);
        let stderr = text(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains("--max-memory 1.0 GiB"), "{stderr}");
        assert!(stderr.contains("voxels needs about"), "{stderr}");
        assert!(!out.exists());
    }
}

#[test]
fn info_refuses_a_gzip_stream_that_goes_on_past_its_declared_data() {
    let dir = tempfile::tempdir().unwrap();
    // 64³ uint8 declared over 256 MiB of zeros.
    let head = sphcover_core::synthetic::nifti_header([64, 64, 64], 2, 8);
    let path = dir.path().join("long.nii.gz");
    std::fs::write(&path, sphcover_core::synthetic::gzip_with_zeros(&head, 256)).unwrap();
    let run = sphcover(&["info", path.to_str().unwrap()], LIMIT);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("long.nii.gz: byte 262496"), "{stderr}");
    assert!(stderr.contains("goes on after"), "{stderr}");
}

#[test]
fn a_point_file_over_max_memory_is_refused_before_reconstructing() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scan.ply");
    let points = support::fibonacci_sphere(30_000);
    support::write_points_ply(&scan, &points, Some(&points));
    let out = dir.path().join("mesh.ply");
    let args = [
        "recon",
        scan.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--max-memory",
        "1M",
    ];
    let run = sphcover(&args, LIMIT);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    // Positions, normals and line numbers: 56 bytes a vertex.
    assert!(
        stderr.contains(&format!(
            "{}: declares 30000 vertices: 1.6 MiB in memory, above the memory limit 1.0 MiB (--max-memory)",
            scan.display()
        )),
        "{stderr}"
    );
    assert!(!out.exists());
}

#[test]
fn a_las_file_declaring_more_points_than_it_holds_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut las = vec![0u8; 227];
    las[0..4].copy_from_slice(b"LASF");
    las[24] = 1;
    las[25] = 2;
    las[94..96].copy_from_slice(&227u16.to_le_bytes());
    las[96..100].copy_from_slice(&227u32.to_le_bytes());
    las[105..107].copy_from_slice(&20u16.to_le_bytes());
    las[107..111].copy_from_slice(&4_000_000_000u32.to_le_bytes());
    for axis in 0..3 {
        las[131 + 8 * axis..139 + 8 * axis].copy_from_slice(&0.01f64.to_le_bytes());
    }
    las.extend([0u8; 20 * 10]);
    let path = dir.path().join("lie.las");
    std::fs::write(&path, las).unwrap();
    let run = sphcover(&["info", path.to_str().unwrap()], LIMIT);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("vertex 10 truncated (the file declares 4000000000"),
        "{stderr}"
    );
}
