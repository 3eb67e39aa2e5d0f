//! Tetrahedra as vertex quadruples, compared between triangulators: canonical order,
//! differences, fingerprints, the peer's binary file.
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

use std::io::Read;
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
    let (mut input, n) = crate::open_records(path, 16, "tetrahedra")?;
    let mut tets = Vec::with_capacity(n);
    let mut buf = [0u8; 16];
    for _ in 0..n {
        input.read_exact(&mut buf)?;
        let v = |i: usize| u32::from_le_bytes(buf[4 * i..4 * i + 4].try_into().expect("4 bytes"));
        tets.push([v(0), v(1), v(2), v(3)]);
    }
    Ok(tets)
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
