//! The Python package's test suite, run by `cargo test`.
//!
//! CI runs only `cargo test --workspace --locked` (the README's command, `.ci/run`), so the
//! Python tests run from here: a fresh virtual environment in a temporary directory gets
//! maturin, NumPy, SciPy, pytest, Dask's `distributed` (the tiled reconstruction's tests start
//! a local cluster) and trimesh (small, pure Python: its conversions then run;
//! Open3D is too large to fetch on every run, so its test is skipped) from the package index; maturin builds the package's wheel
//! and cargo the `sphcover` command it is compared with, both with the `python-test` profile
//! into `<target>/python-check` (never the outer `cargo test`'s build directory, whose lock
//! that run holds); the wheel is installed and pytest runs `tests/python`. Any pytest failure,
//! and a package index that cannot be reached, fail this test: it never passes without having
//! run the suite. pytest's summary, with the reasons of skipped tests (Open3D or trimesh not
//! installed), is written to stderr uncaptured.
//!
//! `SPHCOVER_PYTHON` names the interpreter that makes the environment (default `python3`).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// `<target>/python-check`, beside the `tmp` directory cargo gives integration tests.
fn check_dir() -> PathBuf {
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    tmp.parent().unwrap_or(tmp).join("python-check")
}

/// The workspace root: two levels above this crate.
fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .nth(2)
        .expect("the crate sits in crates/")
        .to_path_buf()
}

/// Runs `command`, failing the test with `what` and the command's output unless it succeeds.
fn run(command: &mut Command, what: &str) -> Output {
    let output = command
        .env("CARGO_TERM_COLOR", "never")
        .env_remove("RUSTC_WORKSPACE_WRAPPER")
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot start {command:?}: {e}"));
    assert!(
        output.status.success(),
        "{what} failed ({}):\n{}\n{}",
        output.status,
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

/// The `sphcover` binary of the outer build (`<target>/<profile>/sphcover`, beside the
/// directory of this test's executable), or else one built into `target`.
fn command_under_test(root: &Path, target: &Path) -> PathBuf {
    let exe = std::env::current_exe().expect("the test knows its executable");
    let beside = exe
        .parent()
        .and_then(Path::parent)
        .map(|profile_dir| profile_dir.join("sphcover"));
    if let Some(cli) = beside.filter(|p| p.is_file()) {
        return cli;
    }
    run(
        Command::new(env!("CARGO"))
            .args([
                "build",
                "--locked",
                "--profile",
                "python-test",
                "-p",
                "sphcover-cli",
            ])
            .current_dir(root)
            .env("CARGO_TARGET_DIR", target),
        "building the sphcover command",
    );
    target.join("python-test").join("sphcover")
}

#[test]
fn python_package_passes_its_pytest_suite() {
    let python = std::env::var("SPHCOVER_PYTHON").unwrap_or_else(|_| "python3".to_owned());
    let scratch = tempfile::tempdir().expect("a temporary directory");
    let venv = scratch.path().join("venv");
    run(
        Command::new(&python).args(["-m", "venv"]).arg(&venv),
        &format!("creating a virtual environment with {python}"),
    );
    let bin = venv.join("bin");
    run(
        Command::new(bin.join("python")).args([
            "-m",
            "pip",
            "install",
            "--disable-pip-version-check",
            "--quiet",
            "maturin>=1.9,<2",
            "numpy",
            "scipy",
            "pytest",
            "trimesh",
            "distributed",
        ]),
        "installing maturin, numpy, scipy, pytest, trimesh and distributed from the package index (is it reachable?)",
    );

    let root = workspace();
    let target = check_dir().join("target");
    let cli = command_under_test(&root, &target);
    let wheels = scratch.path().join("wheels");
    run(
        Command::new(bin.join("maturin"))
            .args([
                "build",
                "--locked",
                "--profile",
                "python-test",
                "--manifest-path",
            ])
            .arg(root.join("crates/sphcover-py/Cargo.toml"))
            .arg("--interpreter")
            .arg(bin.join("python"))
            .arg("--out")
            .arg(&wheels)
            .current_dir(&root)
            .env("CARGO_TARGET_DIR", &target),
        "building the wheel with maturin",
    );
    let wheel = std::fs::read_dir(&wheels)
        .expect("maturin wrote its wheel directory")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.extension().is_some_and(|e| e == "whl"))
        .expect("maturin wrote a wheel");
    run(
        Command::new(bin.join("python"))
            .args([
                "-m",
                "pip",
                "install",
                "--disable-pip-version-check",
                "--quiet",
            ])
            .arg(&wheel),
        "installing the wheel",
    );

    // From the scratch directory, so that `import sphcover` is the installed package.
    let output = Command::new(bin.join("python"))
        .args(["-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider"])
        .arg(root.join("crates/sphcover-py/tests/python"))
        .current_dir(scratch.path())
        .env("SPHCOVER_CLI", &cli)
        .output()
        .expect("pytest runs");
    let log = String::from_utf8_lossy(&output.stdout);
    // Direct writes are not captured by the test harness: the summary shows in CI's log.
    let summary: Vec<&str> = log
        .lines()
        .filter(|l| l.starts_with("SKIPPED") || l.contains(" passed") || l.contains(" failed"))
        .collect();
    let _ = writeln!(std::io::stderr(), "pytest: {}", summary.join("\n  "));
    assert!(
        output.status.success(),
        "pytest failed ({}):\n{log}\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
}
