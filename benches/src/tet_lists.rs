//! Tetrahedra as vertex quadruples, compared between triangulators: canonical order,
//! differences, fingerprints, the peer's binary file; and this process's peak memory and CPU
//! time, which the comparison reports beside them.
//!
//! ```
//! use sphcover_benches::tet_lists::{canonical, differences, fnv1a};
//!
//! let ours = canonical(vec![[3, 1, 2, 0], [4, 2, 1, 3]]);
//! assert_eq!(ours, [[0, 1, 2, 3], [1, 2, 3, 4]]);
//! let theirs = canonical(vec![[1, 2, 3, 4], [0, 1, 2, 5]]);
//! assert_eq!(differences(&ours, &theirs), (1, 1));
//! assert_ne!(fnv1a(ours.iter().copied()), fnv1a(theirs.iter().copied()));
//! ```

use std::io::{BufReader, Read};
use std::path::Path;

/// Each quadruple sorted ascending, then the list sorted: the same for two triangulations
/// with the same tetrahedra, whatever their cell order and vertex order.
pub fn canonical(mut tets: Vec<[u32; 4]>) -> Vec<[u32; 4]> {
    for t in &mut tets {
        t.sort_unstable();
    }
    tets.sort_unstable();
    tets
}

/// How many quadruples only `a` holds and how many only `b` holds (both canonical, as
/// [`canonical`] makes them); `(0, 0)` when they are the same.
pub fn differences(a: &[[u32; 4]], b: &[[u32; 4]]) -> (usize, usize) {
    let (mut i, mut j) = (0, 0);
    let (mut only_a, mut only_b) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => {
                only_a += 1;
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                only_b += 1;
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                i += 1;
                j += 1;
            }
        }
    }
    (only_a + a.len() - i, only_b + b.len() - j)
}

/// FNV-1a (64-bit) over the vertex handles, one `u32` at a time (as the
/// `triangulate_bench` example of `sphcover-tetra` computes it).
pub fn fnv1a(tets: impl Iterator<Item = [u32; 4]>) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for t in tets {
        for v in t {
            h = (h ^ u64::from(v)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

/// Reads little-endian `u32` quadruples (the peer's output).
pub fn read_tets(path: &Path) -> std::io::Result<Vec<[u32; 4]>> {
    let file = std::fs::File::open(path)?;
    let bytes = file.metadata()?.len();
    if bytes % 16 != 0 {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "{}: {bytes} bytes is not a whole number of tetrahedra",
                path.display()
            ),
        ));
    }
    let mut input = BufReader::new(file);
    let mut tets = Vec::with_capacity((bytes / 16) as usize);
    let mut buf = [0u8; 16];
    for _ in 0..bytes / 16 {
        input.read_exact(&mut buf)?;
        let v = |i: usize| u32::from_le_bytes(buf[4 * i..4 * i + 4].try_into().expect("4 bytes"));
        tets.push([v(0), v(1), v(2), v(3)]);
    }
    Ok(tets)
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_count_both_sides() {
        let a = canonical(vec![[0, 1, 2, 3], [0, 1, 2, 4], [5, 6, 7, 8]]);
        let b = canonical(vec![[4, 2, 1, 0], [9, 6, 7, 8]]);
        assert_eq!(differences(&a, &b), (2, 1));
        assert_eq!(differences(&a, &a), (0, 0));
        assert_eq!(differences(&[], &b), (0, 2));
    }

    #[test]
    fn tets_round_trip_through_the_peer_format() {
        let path = std::env::temp_dir().join(format!("tet-lists-{}.bin", std::process::id()));
        let tets = vec![[1u32, 2, 3, 4], [u32::MAX, 0, 7, 9]];
        let bytes: Vec<u8> = tets
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        std::fs::write(&path, bytes).unwrap();
        assert_eq!(read_tets(&path).unwrap(), tets);
        std::fs::remove_file(&path).unwrap();
    }
}
