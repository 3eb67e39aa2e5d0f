//! A spatially coherent visiting order for batches of query points.
//!
//! Consecutive queries at nearby points touch the same parts of a spatial index and the
//! same data, so a batch visited in Morton (Z-curve) order instead of input order turns most
//! cache misses into hits, and neighbouring points can share one index query: a
//! [`BatchPlan`] cuts the order into blocks of neighbouring points. Each point is still
//! answered on its own, so the order changes no result.

use crate::geometry::Aabb;
use glam::DVec3;
use rayon::prelude::*;
use std::ops::Range;

/// Bits per axis of the Morton code (3 × 21 = 63 bits).
const BITS: u32 = 21;

/// Indices of `points` sorted by the Morton code of their position in the points' bounding
/// box (ties and non-finite points, which go last, by index). Deterministic.
pub(crate) fn morton_order(points: &[DVec3]) -> Vec<u32> {
    let bounds = Aabb::from_points(points);
    let extent = bounds.extent().max_element();
    let scale = if extent > 0.0 {
        ((1u64 << BITS) - 1) as f64 / extent
    } else {
        0.0
    };
    let keyed: Vec<(u64, u32)> = points
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            let code = if p.is_finite() {
                let q = ((p - bounds.min) * scale).max(DVec3::ZERO);
                spread(q.x as u64) | (spread(q.y as u64) << 1) | (spread(q.z as u64) << 2)
            } else {
                u64::MAX
            };
            (code, i as u32)
        })
        .collect();
    radix_sorted(keyed).into_iter().map(|(_, i)| i).collect()
}

/// Bits per digit of [`radix_sorted`]: six passes cover the 64-bit codes.
const RADIX_BITS: usize = 11;
const RADIX_PASSES: usize = 64usize.div_ceil(RADIX_BITS);

/// `keyed` (code, index) sorted by code, equal codes in their given order: a
/// least-significant-digit radix sort, whose passes are stable. Given in ascending index, the
/// pairs come out in the order a sort of the pairs gives (the indices are distinct), at a few
/// operations per pair and pass rather than a comparison sort's dozens per pair.
fn radix_sorted(mut keyed: Vec<(u64, u32)>) -> Vec<(u64, u32)> {
    const BUCKETS: usize = 1 << RADIX_BITS;
    let digit = |code: u64, pass: usize| ((code >> (pass * RADIX_BITS)) as usize) & (BUCKETS - 1);
    let mut counts = vec![[0usize; BUCKETS]; RADIX_PASSES];
    for &(code, _) in &keyed {
        for (pass, count) in counts.iter_mut().enumerate() {
            count[digit(code, pass)] += 1;
        }
    }
    let mut other = vec![(0u64, 0u32); keyed.len()];
    for (pass, count) in counts.iter().enumerate() {
        // A digit that every code shares leaves the order as it is.
        if count.contains(&keyed.len()) {
            continue;
        }
        let mut next = [0usize; BUCKETS];
        let mut start = 0;
        for (next, &c) in next.iter_mut().zip(count) {
            *next = start;
            start += c;
        }
        for &(code, i) in &keyed {
            let d = digit(code, pass);
            other[next[d]] = (code, i);
            next[d] += 1;
        }
        std::mem::swap(&mut keyed, &mut other);
    }
    keyed
}

/// The order in which a batch's points are visited: Morton order, cut into blocks of
/// neighbouring points (ranges of `order` with their bounding boxes), and the block of every
/// position.
pub(crate) struct BatchPlan {
    pub order: Vec<u32>,
    pub blocks: Vec<(Range<usize>, Aabb)>,
    pub block_of: Vec<u32>,
}

impl BatchPlan {
    /// The plan of `points` (at most `u32::MAX`): blocks of at most `max_len` consecutive
    /// points, a block closing early where the next point would stretch its box to a
    /// diagonal over `span` (a finite point after only non-finite ones never does).
    pub fn new(points: &[DVec3], max_len: usize, span: f64) -> BatchPlan {
        let order = morton_order(points);
        let span2 = span * span;
        let mut blocks = Vec::with_capacity(order.len() / max_len.max(1) + 1);
        let mut start = 0;
        let mut bounds = Aabb::EMPTY;
        for (k, &i) in order.iter().enumerate() {
            let x = points[i as usize];
            let mut grown = bounds;
            if x.is_finite() {
                grown.add(x);
            }
            let len = k - start;
            if len == max_len || (len > 0 && grown.extent().length_squared() > span2) {
                blocks.push((start..k, bounds));
                start = k;
                bounds = Aabb::EMPTY;
                if x.is_finite() {
                    bounds.add(x);
                }
            } else {
                bounds = grown;
            }
        }
        if start < order.len() {
            blocks.push((start..order.len(), bounds));
        }
        let mut block_of = vec![0u32; order.len()];
        for (b, (range, _)) in blocks.iter().enumerate() {
            block_of[range.clone()].fill(b as u32);
        }
        BatchPlan {
            order,
            blocks,
            block_of,
        }
    }

    /// The position of every point in `order`, by input index.
    pub fn rank(&self) -> Vec<u32> {
        let mut rank = vec![0u32; self.order.len()];
        for (k, &i) in self.order.iter().enumerate() {
            rank[i as usize] = k as u32;
        }
        rank
    }
}

/// Results by position (`by_position[rank[i]]` belongs to point `i`) in input order.
pub(crate) fn in_input_order<R: Copy + Send + Sync>(rank: &[u32], by_position: &[R]) -> Vec<R> {
    rank.par_iter().map(|&k| by_position[k as usize]).collect()
}

/// The centre and radius of a sphere holding the box `bounds` (`None` when it is empty),
/// the radius widened by a relative margin so that rounding never leaves out a point of the
/// box: a ball of radius `r` around any point of the box lies in the ball of radius
/// `r + radius` around the centre, whatever the rounding of the distances.
pub(crate) fn bounding_sphere(bounds: &Aabb) -> Option<(DVec3, f64)> {
    if bounds.is_empty() {
        return None;
    }
    let centre = bounds.centre();
    let reach = 0.5 * bounds.diagonal() * (1.0 + 1e-9) + f64::EPSILON * centre.abs().max_element();
    Some((centre, reach))
}

/// Spreads the low 21 bits of `v` to every third bit.
fn spread(v: u64) -> u64 {
    let mut x = v.min((1 << BITS) - 1);
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn spread_interleaves_bits() {
        for v in [0u64, 1, 2, 3, 0x1f_ffff, 0x15_5555, 12345] {
            let s = spread(v);
            for bit in 0..BITS {
                assert_eq!((s >> (3 * bit)) & 1, (v >> bit) & 1, "v {v:#x} bit {bit}");
            }
            assert_eq!(s & !0x1249_2492_4924_9249, 0);
        }
    }

    proptest! {
        /// The radix sort gives the order of a sort of the (code, index) pairs, with codes
        /// that share digits, repeat, or are all ones (non-finite points).
        #[test]
        fn radix_sorted_is_the_sort_of_the_pairs(
            codes in prop::collection::vec(
                prop_oneof![
                    any::<u64>(),
                    0u64..8,
                    Just(u64::MAX),
                    (0u64..1 << 20).prop_map(|c| c << 40),
                ],
                0..3000,
            ),
        ) {
            let keyed: Vec<(u64, u32)> =
                codes.iter().enumerate().map(|(i, &c)| (c, i as u32)).collect();
            let mut sorted = keyed.clone();
            sorted.sort_unstable();
            prop_assert_eq!(radix_sorted(keyed), sorted);
        }
    }

    #[test]
    fn order_is_a_permutation_with_non_finite_last() {
        let points = vec![
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(f64::NAN, 0.0, 0.0),
            DVec3::ZERO,
            DVec3::new(0.1, 0.0, 0.0),
        ];
        let order = morton_order(&points);
        assert_eq!(order, vec![2, 3, 0, 1]);
        assert_eq!(morton_order(&[]), Vec::<u32>::new());
    }
}
