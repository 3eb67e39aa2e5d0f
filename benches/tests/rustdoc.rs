//! The documentation of the whole workspace builds without a rustdoc warning.
//!
//! CI runs only `cargo test --workspace --locked` (the README's command, `.ci/run`), so the
//! doc check is a test: it runs `cargo doc --no-deps --workspace --locked` with
//! `RUSTDOCFLAGS="-D warnings"` (broken intra-doc links, missing docs under
//! `#![deny(missing_docs)]`, bad code-block attributes, …) and fails with rustdoc's output.
//!
//! It builds into its own target directory, `<target>/doc-check`, so it never waits for the
//! lock of the outer `cargo test`'s build directory and never disturbs its artefacts. The first
//! run checks the dependencies too (about a minute on two cores); later runs redo only the
//! workspace's own crates.

use std::path::{Path, PathBuf};
use std::process::Command;

/// `<target>/doc-check`, beside the `tmp` directory cargo gives integration tests.
fn doc_target_dir() -> PathBuf {
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    tmp.parent().unwrap_or(tmp).join("doc-check")
}

/// The diagnostics of a cargo/rustdoc log: every line that starts a warning or an error.
fn diagnostics(log: &str) -> Vec<&str> {
    log.lines()
        .filter(|l| {
            let l = l.trim_start();
            l.starts_with("warning") || l.starts_with("error")
        })
        .collect()
}

#[test]
fn workspace_docs_build_without_warnings() {
    let workspace = sphcover_benches::workspace_root();
    let output = Command::new(env!("CARGO"))
        .args(["doc", "--no-deps", "--workspace", "--locked"])
        .current_dir(&workspace)
        .env("CARGO_TARGET_DIR", doc_target_dir())
        .env("RUSTDOCFLAGS", "-D warnings")
        // Plain, uncoloured text for the failure message.
        .env("CARGO_TERM_COLOR", "never")
        .env_remove("RUSTC_WORKSPACE_WRAPPER")
        .output()
        .expect("cargo runs");
    let log = String::from_utf8_lossy(&output.stderr);
    let found = diagnostics(&log);
    assert!(
        output.status.success() && found.is_empty(),
        "`cargo doc --no-deps --workspace --locked` with RUSTDOCFLAGS=\"-D warnings\" \
         ({}) reported {} diagnostic line(s):\n{}\n\nfull output:\n{log}",
        output.status,
        found.len(),
        found.join("\n"),
    );
}

#[test]
fn diagnostics_are_the_warning_and_error_lines() {
    let log = "   Documenting sphcover-core v0.1.0\n\
               warning: unresolved link to `Foo`\n  --> src/lib.rs:3:5\n\
               error: could not document `sphcover-core`\n    Finished `dev` profile\n";
    assert_eq!(
        diagnostics(log),
        vec![
            "warning: unresolved link to `Foo`",
            "error: could not document `sphcover-core`"
        ]
    );
    assert!(
        diagnostics("    Finished `dev` profile\n   Generated target/doc/x/index.html").is_empty()
    );
}
