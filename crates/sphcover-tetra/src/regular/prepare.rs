//! What is known of the input before the first insertion: which centres repeat (the heaviest
//! stays), each centre's lexicographic rank (the order of the symbolic perturbation), and
//! whether all centres lie on one dyadic grid.
//!
//! Each is one pass over the whole input that the insertions then only read, so they stay
//! apart from the incremental part.

use rayon::prelude::*;

use super::{VertexStatus, WeightedPoint};
use crate::predicates::Point;

/// Marks points with a repeated centre as duplicates (the heaviest stays, then the first),
/// writes every point's lexicographic rank (equal centres share one), and returns the kept
/// points.
pub(super) fn distinct_points(
    pts: &[Point],
    weights: &[f64],
    status: &mut [VertexStatus],
    rank: &mut [u32],
) -> Vec<u32> {
    let n = pts.len();
    // Order-preserving integer keys (−0 and +0 are one value): an integer sort is much
    // faster than comparing float tuples.
    let key = |x: f64| {
        let b = (x + 0.0).to_bits();
        if b >> 63 == 1 { !b } else { b | (1 << 63) }
    };
    // The pairs are distinct (by index): the parallel sort's order is thread-count independent.
    let mut keyed: Vec<([u64; 3], u32)> = pts
        .par_iter()
        .with_min_len(4096)
        .enumerate()
        .map(|(i, p)| ([key(p[0]), key(p[1]), key(p[2])], i as u32))
        .collect();
    keyed.par_sort_unstable();
    let idx: Vec<u32> = keyed.par_iter().map(|k| k.1).collect();
    drop(keyed);
    let mut kept = Vec::with_capacity(n);
    let mut i = 0;
    while i < n {
        let mut j = i + 1;
        let p = pts[idx[i] as usize];
        while j < n && pts[idx[j] as usize] == p {
            j += 1;
        }
        // Heaviest wins; among equals the lowest index (the group is index-sorted).
        let mut best = idx[i];
        for &k in &idx[i + 1..j] {
            if weights[k as usize] > weights[best as usize] {
                best = k;
            }
        }
        for &k in &idx[i..j] {
            rank[k as usize] = kept.len() as u32;
            if k != best {
                status[k as usize] = VertexStatus::Duplicate;
            }
        }
        kept.push(best);
        i = j;
    }
    kept
}

/// The common dyadic grid of all centres, if their coordinates are integer multiples of one
/// power of two `2^e` below `2^30` of them: `(e, integer coordinates)`.
pub(super) fn integer_grid(pw: &[WeightedPoint]) -> Option<(i32, Vec<[i32; 3]>)> {
    let mut low = i32::MAX;
    let mut high = i32::MIN;
    for c in pw.iter().flat_map(|x| x.p) {
        let raw = c.to_bits();
        let biased = ((raw >> 52) & 0x7ff) as i32;
        if raw << 1 == 0 {
            continue;
        }
        if biased == 0 || biased == 0x7ff {
            return None;
        }
        let mantissa = (raw & ((1u64 << 52) - 1)) | (1u64 << 52);
        let exponent = biased - 1075;
        low = low.min(exponent + mantissa.trailing_zeros() as i32);
        high = high.max(exponent + 53);
        if high - low > 30 {
            return None;
        }
    }
    if low == i32::MAX {
        low = 0;
    }
    let to_int = |c: f64| -> i32 {
        let raw = c.to_bits();
        if raw << 1 == 0 {
            return 0;
        }
        let mantissa = (raw & ((1u64 << 52) - 1)) | (1u64 << 52);
        let shift = ((raw >> 52) & 0x7ff) as i32 - 1075 - low;
        let m = if shift >= 0 {
            (mantissa << shift) as i64
        } else {
            (mantissa >> -shift) as i64
        };
        (if raw >> 63 == 1 { -m } else { m }) as i32
    };
    Some((low, pw.iter().map(|x| x.p.map(to_int)).collect()))
}
