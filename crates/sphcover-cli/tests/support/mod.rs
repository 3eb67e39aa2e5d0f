//! Helpers shared by the end-to-end tests of hostile input, determinism and output safety:
//! running the binary under a time limit and writing small point files.

#![allow(dead_code)]

use sphcover_core::random::XorShift64;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use glam::DVec3;

/// Exit status of a Rust panic: never acceptable from the command.
pub const PANIC_EXIT: i32 = 101;

/// A bundled fixture by its path under `fixtures/`.
pub fn fixture(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(rel)
}

/// Lossy text of captured output, for assertion messages.
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Runs `sphcover` with `args` in `dir` (or the current directory), killing it after
/// `limit`: a run that hangs fails the test instead of blocking the suite.
pub fn sphcover_in(dir: Option<&Path>, args: &[&str], limit: Duration) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_sphcover"));
    command
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if let Some(dir) = dir {
        command.current_dir(dir);
    }
    run_with_limit(command, limit, &format!("sphcover {}", args.join(" ")))
}

/// `sphcover` with a limit far above what the small test inputs need: a hang fails the
/// test instead of blocking the suite.
pub fn run(args: &[&str]) -> Output {
    sphcover(args, Duration::from_secs(120))
}

/// `sphcover recon SCAN -o OUT --report REPORT EXTRA…` with [`run`]'s limit.
pub fn recon_with_report(scan: &Path, out: &Path, report: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "recon",
        scan.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    run(&args)
}

/// [`sphcover_in`] in the current directory.
pub fn sphcover(args: &[&str], limit: Duration) -> Output {
    sphcover_in(None, args, limit)
}

/// Runs `command` to completion, panicking (with `what`) when it outlives `limit`.
pub fn run_with_limit(mut command: Command, limit: Duration, what: &str) -> Output {
    let mut child = command.spawn().expect("the command starts");
    // Drain the pipes on threads so that a chatty child cannot block on a full pipe.
    let mut stdout = child.stdout.take().expect("stdout is piped");
    let mut stderr = child.stderr.take().expect("stderr is piped");
    let out_reader = std::thread::spawn(move || {
        let mut buf = Vec::new();
        std::io::Read::read_to_end(&mut stdout, &mut buf).ok();
        buf
    });
    let err_reader = std::thread::spawn(move || {
        let mut buf = Vec::new();
        std::io::Read::read_to_end(&mut stderr, &mut buf).ok();
        buf
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("the child can be waited for") {
            break status;
        }
        if start.elapsed() > limit {
            child.kill().ok();
            child.wait().ok();
            panic!("{what} still ran after {limit:?}: a hang");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    Output {
        status,
        stdout: out_reader.join().unwrap_or_default(),
        stderr: err_reader.join().unwrap_or_default(),
    }
}

/// Writes an ascii PLY of `points` (doubles, so that 1e±30 survive exactly), with normals
/// when given.
pub fn write_points_ply(path: &Path, points: &[DVec3], normals: Option<&[DVec3]>) {
    let mut s = String::new();
    s.push_str("ply\nformat ascii 1.0\n");
    writeln!(s, "element vertex {}", points.len()).unwrap();
    s.push_str("property double x\nproperty double y\nproperty double z\n");
    if normals.is_some() {
        s.push_str("property double nx\nproperty double ny\nproperty double nz\n");
    }
    s.push_str("end_header\n");
    for (i, p) in points.iter().enumerate() {
        write!(s, "{:e} {:e} {:e}", p.x, p.y, p.z).unwrap();
        if let Some(n) = normals {
            write!(s, " {:e} {:e} {:e}", n[i].x, n[i].y, n[i].z).unwrap();
        }
        s.push('\n');
    }
    std::fs::write(path, s).expect("the test directory is writable");
}

/// `n` points spread evenly over the unit sphere (Fibonacci lattice) with their outward
/// normals, which are the points themselves.
pub fn fibonacci_sphere(n: usize) -> Vec<DVec3> {
    // The core's lattice has its poles on ±z; these tests want them on ±y.
    sphcover_core::synthetic::fibonacci_sphere(n)
        .into_iter()
        .map(|u| DVec3::new(u.x, u.z, u.y))
        .collect()
}

/// The files of `dir`, sorted, for checking that nothing (not even a temporary file) was
/// left behind.
pub fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("the directory is readable")
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Writes an ascii PLY of samples on the lattice `0..dims` jittered by up to ±0.3 (seeded
/// xorshift, so the file is the same on every run), with `value(position, sample)` as the
/// `density` property.
pub fn write_jittered_samples(
    path: &Path,
    dims: [usize; 3],
    seed: u64,
    value: impl Fn(DVec3, usize) -> f64,
) {
    let mut rng = XorShift64::new(seed);
    let mut uniform = move || rng.uniform();
    let mut body = String::new();
    let mut count = 0;
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let jitter = DVec3::new(uniform(), uniform(), uniform()) * 0.6 - 0.3;
                let p = DVec3::new(i as f64, j as f64, k as f64) + jitter;
                writeln!(body, "{} {} {} {}", p.x, p.y, p.z, value(p, count)).unwrap();
                count += 1;
            }
        }
    }
    let header = format!(
        "ply\nformat ascii 1.0\nelement vertex {count}\nproperty double x\nproperty double y\nproperty double z\nproperty double density\nend_header\n"
    );
    std::fs::write(path, header + &body).unwrap();
}

/// Decompression bombs as a user met them, written to `dir`: gzip volumes of zeros whose
/// headers declare what the streams really inflate to. `(name, declared bytes)`:
/// `bomb_1g.nii.gz` (1024 x 1024 x 512 int16, 1 GiB, a 1 MB file), `bomb_8g.nii.gz`
/// (2048 x 2048 x 1024 int16, 8 GiB, an 8 MB file) and `bomb_2g.inr.gz` (1024³ int16).
pub fn write_bombs(dir: &Path) -> Vec<PathBuf> {
    use sphcover_core::synthetic::{gzip_with_zeros, inrimage_header, nifti_header};
    let bombs = [
        (
            "bomb_1g.nii.gz",
            nifti_header([1024, 1024, 512], 4, 16),
            1024,
        ),
        (
            "bomb_8g.nii.gz",
            nifti_header([2048, 2048, 1024], 4, 16),
            8192,
        ),
        ("bomb_2g.inr.gz", inrimage_header([1024, 1024, 1024]), 2048),
    ];
    bombs
        .into_iter()
        .map(|(name, head, mib)| {
            let path = dir.join(name);
            std::fs::write(&path, gzip_with_zeros(&head, mib)).unwrap();
            path
        })
        .collect()
}

/// Runs `sphcover` under an address-space limit of `kib` KiB (`ulimit -v`, as a user capping
/// a run does), killing it after `limit`.
pub fn sphcover_under_ulimit(kib: u64, args: &[&str], limit: Duration) -> Output {
    let mut command = Command::new("sh");
    command
        .arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_sphcover"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    run_with_limit(
        command,
        limit,
        &format!("ulimit -v {kib}; sphcover {}", args.join(" ")),
    )
}
