//! Output safety end to end: outputs appear complete or not at all (written to a temporary
//! file in the target directory and renamed on success), an existing output is replaced only
//! by a successful run, an output that is an input is refused however it is spelt, and
//! unwritable destinations, a full file system and interruptions are handled as `docs/cli.md`
//! says (exit status 1 for a runtime failure, 2 for bad usage).

mod support;

use std::io::Read;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
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
const SIGTERM: i32 = 15;

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
    assert_eq!(temporaries.len(), 1, "{temporaries:?}");

    // The next run writing that output removes it: its writer has ended.
    let run = sphcover_in(Some(dir.path()), &recon_args("scan.ply", "mesh.ply"), LIMIT);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains(&format!("removed ./{}", temporaries[0])),
        "{stderr}"
    );
    assert_eq!(files_in(dir.path()), ["mesh.ply", "scan.ply"]);
}

#[test]
fn temporary_files_of_running_or_unknown_writers_are_left_alone() {
    let (dir, _scan) = scan_dir();
    // This test process is running; a name without a process id comes from an older version.
    let running = format!(".mesh.ply.{}.AbC123.tmp", std::process::id());
    let unknown = ".mesh.ply.XyZ789.tmp".to_string();
    for name in [&running, &unknown] {
        std::fs::write(dir.path().join(name), b"partial").unwrap();
    }
    let run = sphcover_in(Some(dir.path()), &recon_args("scan.ply", "mesh.ply"), LIMIT);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{unknown} looks like the temporary file of an earlier run"
        )),
        "{stderr}"
    );
    assert!(!stderr.contains(&running), "{stderr}");
    let mut expected = vec![running, unknown, "mesh.ply".into(), "scan.ply".into()];
    expected.sort();
    assert_eq!(files_in(dir.path()), expected);
}

/// A reconstruction of the bunny long enough to be interrupted mid-way (normal estimation on
/// 37,706 points and a depth-10 grid: several seconds even on a quiet machine), writing
/// `output` in `dir`, with stderr captured.
fn spawn_long_recon(dir: &Path, output: &str) -> Child {
    spawn_long_recon_with(Command::new(env!("CARGO_BIN_EXE_sphcover")), dir, output)
}

fn spawn_long_recon_with(mut command: Command, dir: &Path, output: &str) -> Child {
    let input = fixture("real/bunny00.off");
    command
        .args([
            "recon",
            input.to_str().unwrap(),
            "-o",
            output,
            "--depth",
            "10",
            "--estimate-normals",
        ])
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn send_signal(child: &Child, signal: &str) {
    let kill = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
}

/// Waits for `child` (killing it after 10 s); its status and how long it took.
fn wait_at_most_10_s(child: &mut Child) -> (ExitStatus, Duration) {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return (status, start.elapsed());
        }
        if start.elapsed() > Duration::from_secs(10) {
            child.kill().ok();
            child.wait().ok();
            panic!("the run ignored the signal for 10 s");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn stderr_of(child: &mut Child) -> String {
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut stderr)
        .unwrap();
    stderr
}

#[test]
fn an_interrupt_stops_the_run_within_a_second_and_leaves_no_file() {
    // SIGTERM always; SIGINT (Ctrl-C) unless this process ignores it, since an ignored
    // SIGINT is inherited and stays ignored (see the next test).
    let mut signals = vec![("TERM", SIGTERM)];
    if !sigint_is_ignored() {
        signals.push(("INT", SIGINT));
    } else {
        eprintln!("SIGINT is ignored in this environment: only SIGTERM is sent");
    }
    for (name, number) in signals {
        let dir = tempfile::tempdir().unwrap();
        let mut child = spawn_long_recon(dir.path(), "mesh.ply");
        std::thread::sleep(Duration::from_millis(500));
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before it could be interrupted"
        );
        send_signal(&child, name);
        let (status, stopped_after) = wait_at_most_10_s(&mut child);
        let stderr = stderr_of(&mut child);
        // 128 + the signal's number, as shells report a process the signal ended.
        assert_eq!(
            status.code(),
            Some(128 + number),
            "SIG{name}: {status:?} {stderr}"
        );
        assert!(
            stderr.contains(&format!("interrupted by SIG{name}")),
            "{stderr}"
        );
        assert!(
            stopped_after < Duration::from_secs(1),
            "SIG{name}: {stopped_after:?}"
        );
        assert!(
            files_in(dir.path()).is_empty(),
            "SIG{name}: {:?}",
            files_in(dir.path())
        );
    }
}

#[test]
fn an_interrupt_of_a_streamed_run_removes_its_tile_files() {
    let dir = tempfile::tempdir().unwrap();
    // A sphere of 400K oriented points, streamed into 3×3×3 tiles at depth 9: some seconds.
    let unit = fibonacci_sphere(400_000);
    let mut cloud = sphcover_core::PointCloud::from_positions(unit.clone());
    cloud.normals = Some(unit);
    let scan = dir.path().join("sphere.ply");
    io::write_point_cloud(&scan, &cloud, &io::WriteOptions::default()).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_sphcover"))
        .args([
            "recon",
            "sphere.ply",
            "-o",
            "mesh.ply",
            "--tiles",
            "3",
            "--stream",
        ])
        .args(["--depth", "9"])
        .current_dir(dir.path())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Signalled once the tile files are there.
    let start = Instant::now();
    while !files_in(dir.path())
        .iter()
        .any(|f| f.starts_with(".sphcover-tiles-"))
    {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before its tile files were seen"
        );
        assert!(start.elapsed() < Duration::from_secs(20), "no tile files");
        std::thread::sleep(Duration::from_millis(2));
    }
    send_signal(&child, "TERM");
    let (status, _) = wait_at_most_10_s(&mut child);
    let stderr = stderr_of(&mut child);
    assert_eq!(status.code(), Some(128 + SIGTERM), "{status:?} {stderr}");
    assert_eq!(files_in(dir.path()), ["sphere.ply"], "{stderr}");
}

#[test]
fn an_interrupt_while_writing_removes_the_temporary_file() {
    // The depth-10 bunny as OBJ text takes a while to write: signal as soon as the
    // temporary file appears, which the handler must then remove.
    let dir = tempfile::tempdir().unwrap();
    let mut child = spawn_long_recon(dir.path(), "mesh.obj");
    let seen = loop {
        if child.try_wait().unwrap().is_some() {
            break false;
        }
        if !leftover_temporaries(dir.path(), "mesh.obj").is_empty() {
            break true;
        }
        std::thread::sleep(Duration::from_micros(500));
    };
    assert!(seen, "the run ended before its write could be interrupted");
    send_signal(&child, "TERM");
    let (status, _) = wait_at_most_10_s(&mut child);
    let stderr = stderr_of(&mut child);
    assert_eq!(status.code(), Some(128 + SIGTERM), "{status:?} {stderr}");
    assert!(
        files_in(dir.path()).is_empty(),
        "{:?} {stderr}",
        files_in(dir.path())
    );
    assert!(stderr.contains("removed 1 partial output"), "{stderr}");
}

#[test]
fn a_sigint_ignored_at_start_stays_ignored() {
    // `trap '' INT` is how a shell starts a background job without job control, and how a
    // user asks a run to survive Ctrl-C: the handler must not take SIGINT over.
    let dir = tempfile::tempdir().unwrap();
    let mut command = Command::new("sh");
    command
        .arg("-c")
        .arg("trap '' INT; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_sphcover"));
    let mut child = spawn_long_recon_with(command, dir.path(), "mesh.ply");
    std::thread::sleep(Duration::from_millis(500));
    send_signal(&child, "INT");
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        child.try_wait().unwrap().is_none(),
        "an ignored SIGINT ended the run"
    );
    send_signal(&child, "TERM");
    let (status, _) = wait_at_most_10_s(&mut child);
    assert_eq!(status.code(), Some(128 + SIGTERM), "{status:?}");
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
