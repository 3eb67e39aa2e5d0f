//! Tuning of the C library's allocator for a reconstruction.
//!
//! The reconstruction allocates and frees arrays of a few hundred KB to tens of MB at every
//! stage (per-point and per-support arrays, candidate lists, surface-net bricks). By default
//! glibc serves every block above its mmap threshold (128 KiB at first, adapting up to
//! 32 MiB) with its own `mmap` and returns it to the kernel on `free`, and trims the heap
//! whenever more than 128 KiB is free at its top. Each stage then faults its pages in afresh:
//! 0.27–0.32 s of system time in a 362K-point run. Serving blocks below 32 MiB from the heap
//! and trimming only past 1 GiB lets later stages reuse the pages earlier ones freed.
//! Measured on the 2-core machine, 362K points, with the same settings given through the
//! environment (`MALLOC_MMAP_THRESHOLD_`, `MALLOC_TRIM_THRESHOLD_`): wall 3.31–3.49 s
//! instead of 3.40–3.75 s, system time 0.12–0.22 s instead of 0.27–0.32 s. Set here: system
//! time 0.19–0.23 s instead of 0.34–0.41 s, peak resident set 264–274 MiB instead of
//! 248–257 MiB (`docs/benchmarks.md`, *Batched expansion, allocator thresholds, PU block
//! limit*).
//! The trim threshold alone was slower; the mmap threshold alone raised the system time to
//! 0.61–0.73 s.
//!
//! Only `recon` asks for it: the other commands' memory budgets were calibrated without it.

/// Keeps freed memory in the process for reuse (see the module docs). Call before any other
/// thread starts. A no-op where the C library is not glibc.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    set_glibc_thresholds();
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
fn set_glibc_thresholds() {
    const MMAP_THRESHOLD: libc::c_int = 32 << 20;
    const TRIM_THRESHOLD: libc::c_int = 1 << 30;
    // SAFETY: `mallopt` only changes two allocator parameters; it takes the allocator's own
    // lock, and no other thread allocates yet. A refused value (0 returned) leaves glibc's
    // default in place, which is correct, only slower.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD);
    }
}
