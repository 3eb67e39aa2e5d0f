//! This process's peak resident memory and CPU time, read from Linux's `/proc`, for the
//! benchmarks and examples that measure work they run themselves.
//!
//! ```
//! use sphcover_core::this_process::{peak_resident_bytes, process_cpu_seconds};
//!
//! if let (Some(peak), Some(cpu)) = (peak_resident_bytes(), process_cpu_seconds()) {
//!     assert!(peak > 0 && cpu >= 0.0);
//! }
//! ```

/// This process's peak resident memory (`VmHWM` of `/proc/self/status`) in bytes; `None`
/// where there is no `/proc`.
pub fn peak_resident_bytes() -> Option<u64> {
    status_field("VmHWM:")
}

/// User plus system CPU seconds of this process, all threads (`/proc/self/stat`, in clock
/// ticks of 1/100 s); `None` where there is no `/proc`.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// Resets the peak resident memory to the current one (`5` into `/proc/self/clear_refs`,
/// Linux ≥ 4.0), so that a later [`peak_resident_bytes`] sees only what came after. False
/// when the kernel refuses.
pub fn reset_peak_resident() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

fn status_field(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
