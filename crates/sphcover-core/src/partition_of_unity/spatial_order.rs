//! A spatially coherent visiting order for batches of query points.
//!
//! Consecutive queries at nearby points touch the same supports and the same parts of the
//! spatial index, so evaluating a batch in Morton (Z-curve) order instead of input order turns
//! most cache misses into hits. Each point is still evaluated on its own, so the order changes
//! no result.

use crate::geometry::Aabb;
use glam::DVec3;
use rayon::prelude::*;

/// Bits per axis of the Morton code (3 × 21 = 63 bits).
const BITS: u32 = 21;

/// Indices of `points` sorted by the Morton code of their position in the points' bounding
/// box (ties and non-finite points, which go last, by index). Deterministic.
pub(super) fn morton_order(points: &[DVec3]) -> Vec<u32> {
    let bounds = Aabb::from_points(points);
    let extent = bounds.extent().max_element();
    let scale = if extent > 0.0 {
        ((1u64 << BITS) - 1) as f64 / extent
    } else {
        0.0
    };
    let mut keyed: Vec<(u64, u32)> = points
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
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
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
