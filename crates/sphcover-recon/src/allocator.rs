//! Tuning of the C library's allocator for a reconstruction.
//!
//! The reconstruction allocates and frees arrays of a few hundred KB to tens of MB at every
//! stage (per-point and per-support arrays, candidate lists, surface-net bricks). By default
//! glibc serves every block above its mmap threshold (128 KiB at first, adapting up to
//! 32 MiB) with its own `mmap` and returns it to the kernel on `free`, and trims the heap
//! whenever more than 128 KiB is free at its top. Each stage then faults its pages in afresh,
//! which shows as system time. Serving blocks below 32 MiB from the heap and trimming only
//! past 1 GiB lets later stages reuse the pages earlier ones freed, at the cost of a slightly
//! higher peak resident set (`docs/benchmarks.md`, *Memory*). Either threshold alone is worse:
//! the trim threshold alone is slower, and the mmap threshold alone raises the system time
//! above glibc's default.
//!
//! The setting is the process's, not the reconstruction's: a program opts in. `sphcover
//! recon` does (the other commands' memory budgets are calibrated without it), and the Python
//! package offers it as `sphcover.keep_freed_memory()`.

/// Keeps freed memory in the process for reuse by the next stages of a reconstruction
/// (glibc's mmap threshold to 32 MiB, its trim threshold to 1 GiB): faster, with a slightly
/// higher peak resident set. Best called before other threads start. A no-op where the C
/// library is not glibc.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    set_glibc_thresholds();
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
fn set_glibc_thresholds() {
    const MMAP_THRESHOLD: libc::c_int = 32 << 20;
    const TRIM_THRESHOLD: libc::c_int = 1 << 30;
    // SAFETY: `mallopt` only changes two allocator parameters under the allocator's own
    // lock; threads allocating meanwhile see either the old or the new threshold, both valid. A refused value (0 returned) leaves glibc's
    // default in place, which is correct, only slower.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD);
    }
}
