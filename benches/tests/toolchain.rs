//! The workspace's `rust-version` is the real minimum: no locked dependency declares a
//! higher one (`cargo metadata --locked`, which reads only the lock file and the manifests
//! cargo already has). A dependency update that raises the minimum fails here until the
//! manifest says so.

use std::process::Command;

/// `"1.89.0"` → `(1, 89, 0)`; missing parts are 0.
fn version(text: &str) -> (u64, u64, u64) {
    let mut parts = text.split('.').map(|p| p.parse::<u64>().unwrap_or(0));
    let mut next = || parts.next().unwrap_or(0);
    (next(), next(), next())
}

#[test]
fn rust_version_is_at_least_every_locked_dependencys() {
    let workspace = sphcover_benches::workspace_root();
    let output = Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--locked"])
        .current_dir(&workspace)
        .output()
        .expect("cargo metadata runs");
    assert!(
        output.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let metadata: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let packages = metadata["packages"].as_array().unwrap();
    let ours: Vec<&serde_json::Value> = packages.iter().filter(|p| p["source"].is_null()).collect();
    let declared = ours
        .iter()
        .find(|p| p["name"] == "sphcover-core")
        .and_then(|p| p["rust_version"].as_str())
        .expect("sphcover-core declares a rust-version");
    let highest = packages
        .iter()
        .filter(|p| !p["source"].is_null())
        .filter_map(|p| Some((version(p["rust_version"].as_str()?), p["name"].as_str()?)))
        .max()
        .expect("dependencies declare rust-versions");
    assert!(
        version(declared) >= highest.0,
        "rust-version {declared} is below {}.{}.{}, which {} needs",
        highest.0.0,
        highest.0.1,
        highest.0.2,
        highest.1
    );
}
