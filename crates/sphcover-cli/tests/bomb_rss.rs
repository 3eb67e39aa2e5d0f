//! Peak resident memory of the commands refusing decompression bombs: the refusal comes
//! from the header, so the peak is the program's own (about 4.5 MB by `/usr/bin/time`),
//! whatever the bomb declares. This test binary holds this one test:
//! `getrusage(RUSAGE_CHILDREN)` reports the largest peak of every child waited for, and no
//! other test's child may count. A child's peak includes the test process's pages it holds
//! between `fork` and `exec` (about 12 MB here, the bombs' bytes among them).
#![cfg(all(target_os = "linux", target_env = "gnu"))]
#![allow(unsafe_code)]

mod support;

use std::time::Duration;

use support::{sphcover, sphcover_under_ulimit, text, write_bombs};

/// The bound asserted: an order of magnitude above the expected peak, far below what reading
/// any of the bombs would take (2 to 16 GiB).
const MAX_PEAK_KIB: i64 = 200 * 1000;

/// The largest peak resident set, in KiB, of the children this process has waited for.
fn children_peak_kib() -> i64 {
    // SAFETY: `rusage` is plain integers, for which all-zero bytes are a valid value.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `getrusage` writes only the struct it is given, which lives through the call.
    let status = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) };
    assert_eq!(status, 0, "getrusage(RUSAGE_CHILDREN)");
    usage.ru_maxrss
}

#[test]
fn refusing_a_bomb_peaks_far_below_what_it_declares() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.ply");
    let out = out.to_str().unwrap();
    let limit = Duration::from_secs(60);
    for bomb in write_bombs(dir.path()) {
        let bomb = bomb.to_str().unwrap();
        let runs = [
            sphcover_under_ulimit(2 << 20, &["info", bomb], limit),
            sphcover_under_ulimit(2 << 20, &["cover", bomb, "-o", out], limit),
            sphcover_under_ulimit(2 << 20, &["skeleton", bomb, "-o", out], limit),
            sphcover(&["skeleton", bomb, "-o", out, "--max-memory", "1G"], limit),
        ];
        for run in runs {
            assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
        }
    }
    let peak = children_peak_kib();
    eprintln!("largest peak RSS of the refusing runs: {peak} KiB");
    assert!(peak < MAX_PEAK_KIB, "{peak} KiB");
}
