//! Insertion order: a biased randomized insertion order (BRIO, Amenta, Choi and Rote 2003)
//! whose rounds are each sorted along a 3D Hilbert curve.
//!
//! Randomized rounds keep the expected cost of incremental construction `O(n log n)`; the
//! Hilbert order inside a round makes consecutive points close, so the walk from the
//! previous insertion is short and memory accesses stay local.

use rayon::prelude::*;

use crate::predicates::Point;
use sphcover_core::random::SplitMix64;

/// Bits per axis of the Hilbert key (63-bit keys).
const HILBERT_BITS: u32 = 21;

/// The Hilbert index of a point with integer coordinates below `2^HILBERT_BITS`
/// (Skilling, "Programming the Hilbert curve", 2004), without branches: the keys of a
/// million points are a tenth of a construction's set-up.
pub fn hilbert_index(mut x: [u32; 3]) -> u64 {
    // Skilling's "inverse undo" of the excess work, level by level.
    let mut q = 1u32 << (HILBERT_BITS - 1);
    while q > 1 {
        let p = q - 1;
        for i in 0..3 {
            // Bit q of x[i] set: invert the low bits of x[0]; clear: exchange them with x[i]'s.
            let set = 0u32.wrapping_sub(u32::from(x[i] & q != 0));
            let t = (x[0] ^ x[i]) & p & !set;
            x[0] ^= (p & set) | t;
            x[i] ^= t;
        }
        q >>= 1;
    }
    // Gray encode.
    x[1] ^= x[0];
    x[2] ^= x[1];
    let mut t = 0;
    let mut q = 1u32 << (HILBERT_BITS - 1);
    while q > 1 {
        t ^= (q - 1) & 0u32.wrapping_sub(u32::from(x[2] & q != 0));
        q >>= 1;
    }
    // Bit b of x[0], x[1], x[2] at 3b + 2, 3b + 1, 3b.
    (spread_bits(x[0] ^ t) << 2) | (spread_bits(x[1] ^ t) << 1) | spread_bits(x[2] ^ t)
}

/// The low 21 bits of `v` moved to every third bit (bit `b` to bit `3b`).
#[inline]
fn spread_bits(v: u32) -> u64 {
    let mut v = u64::from(v) & 0x1f_ffff;
    v = (v | v << 32) & 0x001f_0000_0000_ffff;
    v = (v | v << 16) & 0x001f_0000_ff00_00ff;
    v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
    v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
    v = (v | v << 2) & 0x1249_2492_4924_9249;
    v
}

/// Sorts `indices` in place along the Hilbert curve of the bounding box of `points`
/// (ties by index, so the order is deterministic).
pub fn hilbert_sort(points: &[Point], indices: &mut [u32]) {
    if indices.len() < 2 {
        return;
    }
    // The bounding box, in parallel: min and max give the same box in any order.
    let (lo, hi) = indices
        .par_iter()
        .with_min_len(4096)
        .fold(
            || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(mut lo, mut hi), &i| {
                let p = points[i as usize];
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
                (lo, hi)
            },
        )
        .reduce(
            || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(a, b), (c, d)| {
                (
                    std::array::from_fn(|k| a[k].min(c[k])),
                    std::array::from_fn(|k| b[k].max(d[k])),
                )
            },
        );
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f64, f64::max);
    let scale = if extent > 0.0 {
        ((1u64 << HILBERT_BITS) - 1) as f64 / extent
    } else {
        0.0
    };
    // Keys and sort in parallel: the (key, index) pairs are distinct, so the sorted order is
    // the same whatever the thread count.
    let mut keyed: Vec<(u64, u32)> = indices
        .par_iter()
        .with_min_len(4096)
        .map(|&i| {
            let p = points[i as usize];
            let q: [u32; 3] = std::array::from_fn(|k| ((p[k] - lo[k]) * scale) as u32);
            (hilbert_index(q), i)
        })
        .collect();
    keyed.par_sort_unstable();
    indices
        .par_iter_mut()
        .with_min_len(4096)
        .zip(keyed.par_iter())
        .for_each(|(slot, &(_, i))| *slot = i);
}

/// The BRIO order of `indices`: shuffled with `seed`, split into rounds of doubling size
/// (the last holds half the points), each round Hilbert-sorted. Returns the rounds' ends.
pub fn brio_order(points: &[Point], indices: &mut [u32], seed: u64) -> Vec<usize> {
    let n = indices.len();
    let mut rng = SplitMix64::new(seed);
    for i in (1..n).rev() {
        let j = rng.below(i as u64 + 1) as usize;
        indices.swap(i, j);
    }
    const FIRST_ROUND: usize = 256;
    let mut ends = Vec::new();
    let mut end = n;
    while end > FIRST_ROUND {
        ends.push(end);
        end /= 2;
    }
    ends.push(end);
    ends.reverse();
    let mut start = 0;
    for &end in &ends {
        hilbert_sort(points, &mut indices[start..end]);
        start = end;
    }
    ends
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Skilling's transform with branches and the bits interleaved one by one.
    fn hilbert_index_plain(mut x: [u32; 3]) -> u64 {
        let m = 1u32 << (HILBERT_BITS - 1);
        let mut q = m;
        while q > 1 {
            let p = q - 1;
            for i in 0..3 {
                if x[i] & q != 0 {
                    x[0] ^= p;
                } else {
                    let t = (x[0] ^ x[i]) & p;
                    x[0] ^= t;
                    x[i] ^= t;
                }
            }
            q >>= 1;
        }
        for i in 1..3 {
            x[i] ^= x[i - 1];
        }
        let mut t = 0;
        let mut q = m;
        while q > 1 {
            if x[2] & q != 0 {
                t ^= q - 1;
            }
            q >>= 1;
        }
        for xi in &mut x {
            *xi ^= t;
        }
        let mut h = 0u64;
        for b in (0..HILBERT_BITS).rev() {
            for xi in &x {
                h = (h << 1) | ((xi >> b) & 1) as u64;
            }
        }
        h
    }

    proptest! {
        #[test]
        fn hilbert_index_matches_the_plain_transform(
            x in 0u32..1 << HILBERT_BITS,
            y in 0u32..1 << HILBERT_BITS,
            z in 0u32..1 << HILBERT_BITS,
        ) {
            prop_assert_eq!(hilbert_index([x, y, z]), hilbert_index_plain([x, y, z]));
        }
    }

    #[test]
    fn hilbert_neighbours_are_adjacent_cells() {
        // On a 4³ grid, consecutive Hilbert indices are face-adjacent cells.
        let mut cells: Vec<(u64, [u32; 3])> = Vec::new();
        for x in 0..4u32 {
            for y in 0..4u32 {
                for z in 0..4u32 {
                    let s = 1 << (HILBERT_BITS - 2);
                    cells.push((hilbert_index([x * s, y * s, z * s]), [x, y, z]));
                }
            }
        }
        cells.sort();
        for w in cells.windows(2) {
            let d: u32 = (0..3).map(|k| w[0].1[k].abs_diff(w[1].1[k])).sum();
            assert_eq!(d, 1, "{:?} -> {:?}", w[0].1, w[1].1);
        }
    }

    #[test]
    fn brio_is_a_permutation_and_deterministic() {
        let pts: Vec<Point> = (0..1000)
            .map(|i| [(i * 7 % 13) as f64, (i * 11 % 17) as f64, i as f64])
            .collect();
        let mut a: Vec<u32> = (0..1000).collect();
        let mut b = a.clone();
        brio_order(&pts, &mut a, 7);
        brio_order(&pts, &mut b, 7);
        assert_eq!(a, b);
        let mut s = a.clone();
        s.sort();
        assert_eq!(s, (0..1000).collect::<Vec<u32>>());
    }
}
