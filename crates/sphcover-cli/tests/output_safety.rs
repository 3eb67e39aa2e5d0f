//! Output safety end to end: outputs appear complete or not at all (written to a temporary
//! file in the target directory and renamed on success), an existing output is replaced only
//! by a successful run, an output that is an input is refused however it is spelt, and
//! unwritable destinations, a full file system and interruptions are handled as `docs/cli.md`
//! says (exit status 1 for a runtime failure, 2 for bad usage).

mod support;

use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use sphcover_core::io::{self, ReadOptions};
use support::{
    PANIC_EXIT, fibonacci_sphere, files_in, fixture, run_with_limit, sphcover, sphcover_in, text,
    write_points_ply,
};

const LIMIT: Duration = Duration::from_secs(60);
/// What a pre-existing output holds, to tell whether a run replaced it.
const PREVIOUS: &[u8] = b"previous output, not to be lost\n";
/// The signal a file-size limit sends (Linux); its default action ends the process.
const SIGXFSZ: i32 = 25;
const SIGINT: i32 = 2;

/// A scratch directory with a small oriented scan (`scan.ply`) whose reconstruction is fast.
fn scan_dir() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scan.ply");
    let points = fibonacci_sphere(600);
    write_points_ply(&scan, &points, Some(&points));
    (dir, scan)
}

fn recon_args<'a>(input: &'a str, output: &'a str) -> Vec<&'a str> {
    vec!["recon", input, "-o", output, "--depth", "6"]
}

/// Temporary files the atomic writer left in `dir`: hidden, named after the output.
fn leftover_temporaries(dir: &Path, output_name: &str) -> Vec<String> {
    files_in(dir)
        .into_iter()
        .filter(|name| name.starts_with(&format!(".{output_name}.")) && name.ends_with(".tmp"))
        .collect()
}

/// `sphcover args` under `sh` with the file-size limit set to `blocks` (of `sh`'s `ulimit`
/// unit, 512 or 1024 bytes), so that writing the output fails part-way like on a full disk;
/// `ignore_sigxfsz` makes the write return an error instead of ending the process.
fn sphcover_with_file_size_limit(
    dir: &Path,
    args: &[&str],
    blocks: u32,
    ignore_sigxfsz: bool,
) -> std::process::Output {
    let trap = if ignore_sigxfsz { "trap '' XFSZ; " } else { "" };
    let script = format!("{trap}ulimit -f {blocks}; exec \"$0\" \"$@\"");
    let mut command = Command::new("sh");
    command
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_sphcover"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    run_with_limit(command, LIMIT, &format!("sphcover {}", args.join(" ")))
}

#[test]
fn a_successful_run_leaves_only_the_output() {
    let (dir, scan) = scan_dir();
    let out = dir.path().join("mesh.ply");
    let run = sphcover(
        &recon_args(scan.to_str().unwrap(), out.to_str().unwrap()),
        LIMIT,
    );
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    assert_eq!(files_in(dir.path()), ["mesh.ply", "scan.ply"]);
    let mesh = io::read_mesh(&out, &ReadOptions::default()).unwrap();
    assert!(!mesh.triangles.is_empty());
}

#[test]
fn an_existing_output_is_replaced_only_on_success() {
    let (dir, scan) = scan_dir();
    let out = dir.path().join("mesh.ply");
    std::fs::write(&out, PREVIOUS).unwrap();

    // A refused input (three points) leaves the previous output as it was.
    let bad = dir.path().join("bad.ply");
    let three = [glam::DVec3::ZERO, glam::DVec3::X, glam::DVec3::Y];
    write_points_ply(&bad, &three, Some(&[glam::DVec3::Z; 3]));
    let run = sphcover(
        &recon_args(bad.to_str().unwrap(), out.to_str().unwrap()),
        LIMIT,
    );
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    assert_eq!(std::fs::read(&out).unwrap(), PREVIOUS);
    assert_eq!(files_in(dir.path()), ["bad.ply", "mesh.ply", "scan.ply"]);

    // A successful run replaces it.
    let run = sphcover(
        &recon_args(scan.to_str().unwrap(), out.to_str().unwrap()),
        LIMIT,
    );
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let mesh = io::read_mesh(&out, &ReadOptions::default()).unwrap();
    assert!(!mesh.triangles.is_empty());
    assert_eq!(files_in(dir.path()), ["bad.ply", "mesh.ply", "scan.ply"]);
}

#[test]
fn a_failed_write_keeps_the_previous_output_and_removes_its_temporary_file() {
    // A file-size limit makes the write fail part-way with EFBIG, as a full disk fails it
    // with ENOSPC: the run must report a runtime failure (status 1) naming the output, and
    // leave neither a truncated output nor its temporary file.
    let (dir, _scan) = scan_dir();
    std::fs::write(dir.path().join("mesh.ply"), PREVIOUS).unwrap();
    let run =
        sphcover_with_file_size_limit(dir.path(), &recon_args("scan.ply", "mesh.ply"), 8, true);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("mesh.ply"),
        "the message names the output: {stderr}"
    );
    assert_eq!(
        std::fs::read(dir.path().join("mesh.ply")).unwrap(),
        PREVIOUS
    );
    assert_eq!(files_in(dir.path()), ["mesh.ply", "scan.ply"]);
}

#[test]
fn a_run_killed_while_writing_leaves_no_file_at_the_output_path() {
    // Without the trap the file-size limit ends the process by signal in the middle of the
    // write, as a kill would: nothing may appear at the output path. The temporary file
    // cannot be cleaned up by a killed process; it is hidden and named after the output.
    let (dir, _scan) = scan_dir();
    let run =
        sphcover_with_file_size_limit(dir.path(), &recon_args("scan.ply", "mesh.ply"), 8, false);
    assert_eq!(run.status.signal(), Some(SIGXFSZ), "{}", text(&run.stderr));
    assert!(!dir.path().join("mesh.ply").exists());
    let temporaries = leftover_temporaries(dir.path(), "mesh.ply");
    let mut expected = vec!["scan.ply".to_string()];
    expected.extend(temporaries.iter().cloned());
    expected.sort();
    assert_eq!(files_in(dir.path()), expected);
    eprintln!("temporary files left by the killed run: {temporaries:?}");
}

#[test]
fn an_interrupt_stops_the_run_within_a_second_and_leaves_no_file() {
    if sigint_is_ignored() {
        // A background job of a non-interactive shell inherits SIGINT ignored, and so does
        // every process it starts: no interrupt can be delivered here.
        eprintln!("SIGINT is ignored in this environment: interrupt test skipped");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("real/bunny00.off");
    let out = dir.path().join("mesh.ply");
    // Long enough (normal estimation on 37,706 points, depth 10: several seconds even on a
    // quiet machine) to be interrupted mid-way; at depth 9 without estimated normals an
    // idle machine finished the run before the interrupt arrived.
    let mut child = Command::new(env!("CARGO_BIN_EXE_sphcover"))
        .args([
            "recon",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--depth",
            "10",
            "--estimate-normals",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the run ended before it could be interrupted"
    );
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let sent = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if sent.elapsed() > Duration::from_secs(10) {
            child.kill().ok();
            child.wait().ok();
            panic!("the run ignored the interrupt for 10 s");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stopped_after = sent.elapsed();
    // No handler is installed: SIGINT's default action ends the process at once. A
    // handler would have to exit with 130 (128 + SIGINT), as shells report it.
    assert!(
        status.signal() == Some(SIGINT) || status.code() == Some(130),
        "{status:?}"
    );
    assert!(stopped_after < Duration::from_secs(1), "{stopped_after:?}");
    assert!(!out.exists());
    assert!(
        files_in(dir.path()).is_empty(),
        "{:?}",
        files_in(dir.path())
    );
}

#[test]
fn an_output_equal_to_the_input_is_refused_however_it_is_spelt() {
    let (dir, scan) = scan_dir();
    let original = std::fs::read(&scan).unwrap();
    std::os::unix::fs::symlink("scan.ply", dir.path().join("link.ply")).unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    for output in ["scan.ply", "./scan.ply", "sub/../scan.ply", "link.ply"] {
        for args in [
            recon_args("scan.ply", output),
            vec!["render", "scan.ply", "-o", output, "--size", "32x24"],
            vec!["cover", "scan.ply", "-o", output],
        ] {
            let run = sphcover_in(Some(dir.path()), &args, LIMIT);
            let stderr = text(&run.stderr);
            assert_eq!(run.status.code(), Some(2), "{}: {stderr}", args.join(" "));
            assert!(
                stderr.contains(output),
                "{}: the message names the output: {stderr}",
                args.join(" ")
            );
            assert_eq!(
                std::fs::read(&scan).unwrap(),
                original,
                "{}",
                args.join(" ")
            );
            assert_eq!(files_in(dir.path()), ["link.ply", "scan.ply", "sub"]);
        }
    }
}

#[test]
fn an_unwritable_destination_is_a_runtime_failure_naming_it() {
    let (dir, scan) = scan_dir();
    let scan = scan.to_str().unwrap();
    std::fs::write(dir.path().join("file"), b"").unwrap();
    let mut destinations = vec![
        dir.path().join("missing/mesh.ply"),
        dir.path().join("file/mesh.ply"),
    ];
    // Permissions stop only an unprivileged user (tests may run as root).
    let locked = dir.path().join("locked");
    std::fs::create_dir(&locked).unwrap();
    std::fs::set_permissions(&locked, std::os::unix::fs::PermissionsExt::from_mode(0o555)).unwrap();
    if std::fs::write(locked.join("probe"), b"").is_err() {
        destinations.push(locked.join("mesh.ply"));
    }
    for out in &destinations {
        let out_text = out.to_str().unwrap();
        let run = sphcover(&recon_args(scan, out_text), LIMIT);
        let stderr = text(&run.stderr);
        assert_ne!(run.status.code(), Some(PANIC_EXIT), "{stderr}");
        assert_eq!(run.status.code(), Some(1), "{out_text}: {stderr}");
        assert!(
            stderr.contains(out_text),
            "the message names the output: {stderr}"
        );
        assert!(!out.exists());
    }
    std::fs::set_permissions(&locked, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
}

/// Whether this process ignores SIGINT (bit 2 of `SigIgn` in `/proc/self/status`), which its
/// children then inherit.
fn sigint_is_ignored() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            let line = status.lines().find(|l| l.starts_with("SigIgn:"))?;
            u64::from_str_radix(line["SigIgn:".len()..].trim(), 16).ok()
        })
        .is_some_and(|mask| mask & (1 << (SIGINT - 1)) != 0)
}
