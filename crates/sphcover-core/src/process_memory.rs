//! The memory this process may use, for limits a run sets itself before it allocates: the
//! readers refuse a file that declares more data than that ([`crate::io::ReadOptions`]'s
//! `max_bytes`), so that a decompression bomb or a lying header ends in a message naming the
//! file instead of a failed allocation.
//!
//! The memory is the smallest of
//!
//! * the machine's memory, `MemTotal` in `/proc/meminfo`;
//! * the memory limit of the process's cgroup (v2 `memory.max`, v1
//!   `memory.limit_in_bytes`), the lowest along its path;
//! * the address-space limit (`ulimit -v`), the soft "Max address space" of
//!   `/proc/self/limits`.
//!
//! `MemTotal` rather than `MemAvailable`: the same command on the same file gets the same
//! verdict on a machine whatever else runs on it (available memory moves with the page cache
//! and other processes). Where none of them can be read (systems without `/proc`), there is
//! no default: the readers still refuse every count the file's size cannot hold, and a
//! refused allocation of the voxels is reported as an error naming the file.

use std::path::{Path, PathBuf};

use crate::io::format_byte_size;

/// Share of the process's memory a run lets its readers use by default, in percent
/// ([`ProcessMemory::read_limit`]). The data a file declares is only the first of a run's
/// arrays (the skeleton's peak is about seven times its `float32` voxels), and under an
/// address-space limit the program, its thread stacks and allocator arenas need room too.
pub const READ_LIMIT_PERCENT: u64 = 60;

/// Which bound the process's memory is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemorySource {
    /// `MemTotal` of `/proc/meminfo`.
    Machine,
    /// The cgroup's memory limit.
    Cgroup,
    /// The address-space limit (`ulimit -v`).
    AddressSpace,
}

/// The memory this process may use, and which bound it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProcessMemory {
    /// Bytes.
    pub bytes: u64,
    /// The smallest of the bounds.
    pub source: MemorySource,
}

impl ProcessMemory {
    /// `this machine's 23.5 GiB`, `the 2.0 GiB address-space limit (ulimit -v)`, …
    pub fn describe(&self) -> String {
        let size = format_byte_size(self.bytes);
        match self.source {
            MemorySource::Machine => format!("this machine's {size}"),
            MemorySource::Cgroup => format!("the {size} memory limit of this cgroup"),
            MemorySource::AddressSpace => format!("the {size} address-space limit (ulimit -v)"),
        }
    }

    /// [`READ_LIMIT_PERCENT`] of the memory: the readers' default limit.
    pub fn read_limit(&self) -> u64 {
        self.bytes / 100 * READ_LIMIT_PERCENT
    }
}

/// The memory this process may use (see the module docs), or `None` where none of the bounds
/// can be read.
pub fn process_memory() -> Option<ProcessMemory> {
    let read = |path: &Path| std::fs::read_to_string(path).ok();
    let machine = read(Path::new("/proc/meminfo"))
        .and_then(|text| mem_total(&text))
        .map(|bytes| (bytes, MemorySource::Machine));
    let cgroup = read(Path::new("/proc/self/cgroup"))
        .and_then(|text| cgroup_limit(&text, read))
        .map(|bytes| (bytes, MemorySource::Cgroup));
    let address_space = read(Path::new("/proc/self/limits"))
        .and_then(|text| address_space_limit(&text))
        .map(|bytes| (bytes, MemorySource::AddressSpace));
    [machine, cgroup, address_space]
        .into_iter()
        .flatten()
        .min_by_key(|&(bytes, _)| bytes)
        .map(|(bytes, source)| ProcessMemory { bytes, source })
}

/// `MemTotal` of `/proc/meminfo`, in bytes.
fn mem_total(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemTotal:"))?;
    let mut fields = line["MemTotal:".len()..].split_whitespace();
    let value: u64 = fields.next()?.parse().ok()?;
    let unit = match fields.next() {
        Some("kB") => 1024,
        None => 1,
        Some(_) => return None,
    };
    value.checked_mul(unit)
}

/// The soft "Max address space" of `/proc/self/limits`, in bytes; `None` when unlimited.
fn address_space_limit(limits: &str) -> Option<u64> {
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// The lowest memory limit along the process's cgroup path (`proc_self_cgroup` is the text of
/// `/proc/self/cgroup`; `read` reads a file), v2 or v1; `None` when there is none. A
/// cgroup namespace shows the process's own cgroup as the root, so the walk goes up to it.
fn cgroup_limit(proc_self_cgroup: &str, read: impl Fn(&Path) -> Option<String>) -> Option<u64> {
    let mut limits = Vec::new();
    for line in proc_self_cgroup.lines() {
        let mut parts = line.splitn(3, ':');
        let (Some(_), Some(controllers), Some(path)) = (parts.next(), parts.next(), parts.next())
        else {
            continue;
        };
        let (mount, file) = if controllers.is_empty() {
            ("/sys/fs/cgroup", "memory.max")
        } else if controllers.split(',').any(|c| c == "memory") {
            ("/sys/fs/cgroup/memory", "memory.limit_in_bytes")
        } else {
            continue;
        };
        let relative = path.trim_start_matches('/');
        for dir in Path::new(relative).ancestors() {
            let file: PathBuf = Path::new(mount).join(dir).join(file);
            // "max" (v2) means no limit; v1 writes a huge number instead.
            if let Some(bytes) = read(&file).and_then(|t| t.trim().parse::<u64>().ok()) {
                limits.push(bytes);
            }
        }
    }
    limits.into_iter().min()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_total_is_read_in_kib() {
        let text = "MemTotal:       24683792 kB\nMemFree:         8104648 kB\n";
        assert_eq!(mem_total(text), Some(24_683_792 * 1024));
        assert_eq!(mem_total("MemFree: 1 kB\n"), None);
        assert_eq!(mem_total("MemTotal: lots kB\n"), None);
    }

    #[test]
    fn the_address_space_limit_is_the_soft_one_and_unlimited_is_none() {
        let head =
            "Limit                     Soft Limit           Hard Limit           Units     \n";
        let unlimited = format!(
            "{head}Max address space         unlimited            unlimited            bytes     \n"
        );
        assert_eq!(address_space_limit(&unlimited), None);
        let capped = format!(
            "{head}Max address space         4294967296           unlimited            bytes     \n"
        );
        assert_eq!(address_space_limit(&capped), Some(4 << 30));
    }

    #[test]
    fn cgroup_limits_are_the_lowest_along_the_path_v1_and_v2() {
        let files = |path: &Path| -> Option<String> {
            match path.to_str()? {
                "/sys/fs/cgroup/user.slice/memory.max" => Some("2147483648\n".into()),
                "/sys/fs/cgroup/user.slice/run.scope/memory.max" => Some("max\n".into()),
                "/sys/fs/cgroup/memory/memory.limit_in_bytes" => {
                    Some("9223372036854771712\n".into())
                }
                "/sys/fs/cgroup/memory/job/memory.limit_in_bytes" => Some("1073741824\n".into()),
                _ => None,
            }
        };
        assert_eq!(
            cgroup_limit("0::/user.slice/run.scope\n", files),
            Some(2 << 30)
        );
        assert_eq!(
            cgroup_limit("4:memory:/job\n2:cpu,cpuacct:/job\n", files),
            Some(1 << 30)
        );
        // A namespaced cgroup whose path is not under the mount: its root file counts.
        assert_eq!(
            cgroup_limit("4:memory:/elsewhere/deep\n", files),
            Some(9_223_372_036_854_771_712)
        );
        assert_eq!(cgroup_limit("3:cpuset:/\n", files), None);
    }

    #[test]
    fn this_machine_has_a_default_on_linux() {
        if cfg!(target_os = "linux") {
            let memory = process_memory().expect("/proc/meminfo is readable on Linux");
            assert!(memory.bytes > 0);
        }
    }
}
