//! The covering: which candidates become centres, in which order, and what each new ball
//! marks covered (steps 1–4 of the algorithm and the centre orders in the notes of the
//! `volume_cover` module).
//!
//! The fit of a support knows nothing of the others and the elimination only sees the
//! finished list, so the order-dependent part lives here alone; the thesis' loop and the
//! seeded shuffle are shared with the scattered builder.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::DVec3;
use rand::RngCore;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::elimination::CornerSet;
use super::grid::Grid;
use super::support::Support;
use super::{CentreOrder, Elimination, VolumeCoverParams, VolumeCoverStats};

impl<'a> Grid<'a> {
    /// Marks the points of the new support's `S` that are midpoints of two other points of
    /// `S`, and the centre, as covered.
    fn mark_covered(&self, s: &Support, covered: &mut [bool]) {
        let base = self.base(s.centre as usize);
        covered[s.centre as usize] = true;
        let in_set = |o: [i32; 3]| -> bool {
            let Some(idx) = self.neighbour(base, o) else {
                return false;
            };
            if !(self.bounding_box || self.object[idx]) {
                return false;
            }
            let p = self.linear * DVec3::new(o[0] as f64, o[1] as f64, o[2] as f64);
            p.length_squared() <= s.shell_d2
        };
        for o in &self.offsets[..s.offsets] {
            let Some(idx) = self.neighbour(base, o.step) else {
                continue;
            };
            if covered[idx] || !(self.bounding_box || self.object[idx]) {
                continue;
            }
            let interior = self.steps.iter().any(|(e, _)| {
                let plus = [o.step[0] + e[0], o.step[1] + e[1], o.step[2] + e[2]];
                let minus = [o.step[0] - e[0], o.step[1] - e[1], o.step[2] - e[2]];
                in_set(plus) && in_set(minus)
            });
            if interior {
                covered[idx] = true;
            }
        }
    }

    /// The covering loop; returns the accepted supports in order.
    /// `depth`: when given, candidates go deepest first (ties in the seeded order).
    pub(super) fn cover<const N: usize>(
        &self,
        params: &VolumeCoverParams,
        depth: Option<&[f64]>,
        stats: &mut VolumeCoverStats,
    ) -> Vec<Support> {
        let n = self.volume.len();
        let mut order: Vec<u32> = if self.bounding_box {
            (0..n as u32).collect()
        } else {
            (0..n as u32).filter(|&i| self.object[i as usize]).collect()
        };
        stats.candidates = order.len();
        shuffle(&mut order, params.seed);
        if let Some(d) = depth {
            order.sort_by(|&a, &b| d[b as usize].total_cmp(&d[a as usize]));
        }
        // The linear variant (smoothing input, §6.2.3) keeps the thesis' cover.
        let eliminate = params.elimination != Elimination::Off && !self.bounding_box;
        let corners = (eliminate && params.elimination == Elimination::CellCorners)
            .then(|| CornerSet::new(self));
        let corners = corners.as_ref();
        let supports = if params.centre_order == CentreOrder::MostUncovered {
            self.cover_greedy::<N>(&order, corners, stats)
        } else {
            self.cover_in_order::<N>(&order, eliminate, corners, stats)
        };
        if eliminate {
            self.eliminate_redundant(supports, corners)
        } else {
            supports
        }
    }

    /// Greedy set cover over the supports of every candidate (in `order`, the seeded
    /// order): the support with the most uncovered members next, supports within ε before
    /// those over it (lazy re-evaluation; ties to the earlier candidate).
    fn cover_greedy<const N: usize>(
        &self,
        order: &[u32],
        corners: Option<&CornerSet>,
        stats: &mut VolumeCoverStats,
    ) -> Vec<Support> {
        let fits: Vec<Support> = order
            .par_iter()
            .map(|&c| self.fit::<N>(c as usize))
            .collect();
        stats.fits += fits.len();
        let gains: Vec<u32> = fits
            .par_iter()
            .map(|s| {
                let mut g = 0u32;
                self.for_each_point(s, corners, &mut |_| g += 1);
                g
            })
            .collect();
        let tolerance = self.tolerance;
        let within = |s: &Support| s.rms <= tolerance;
        let mut heap: BinaryHeap<(bool, u32, Reverse<u32>)> = gains
            .iter()
            .zip(&fits)
            .enumerate()
            .map(|(rank, (&g, s))| (within(s), g, Reverse(rank as u32)))
            .collect();
        let total = self.volume.len() + corners.map_or(0, |cs| cs.object.len());
        let mut covered = vec![false; total];
        let mut supports = Vec::new();
        while let Some((ok, stale, Reverse(rank))) = heap.pop() {
            let s = &fits[rank as usize];
            let mut gain = 0u32;
            self.for_each_point(s, corners, &mut |idx| gain += u32::from(!covered[idx]));
            if gain == 0 {
                continue;
            }
            if gain < stale && heap.peek().is_some_and(|&(o, g, _)| (o, g) > (ok, gain)) {
                heap.push((ok, gain, Reverse(rank)));
                continue;
            }
            self.for_each_point(s, corners, &mut |idx| covered[idx] = true);
            supports.push(*s);
        }
        supports
    }

    /// The covering loop of the thesis over candidates in `order`; returns the accepted
    /// supports in order. With `defer`, a centre whose fit misses ε is set aside and taken
    /// at the end only if it holds a member that no accepted ball holds by then (with
    /// `corners`, cell corners count as members).
    fn cover_in_order<const N: usize>(
        &self,
        order: &[u32],
        defer: bool,
        corners: Option<&CornerSet>,
        stats: &mut VolumeCoverStats,
    ) -> Vec<Support> {
        let n = self.volume.len();
        let mut supports = Vec::new();
        let mut deferred = Vec::new();
        covering_loop(
            order,
            n,
            |c| self.fit::<N>(c),
            stats,
            |s, covered| {
                if defer && s.rms > self.tolerance {
                    deferred.push(s);
                } else {
                    self.mark_covered(&s, covered);
                    supports.push(s);
                }
            },
        );
        if !deferred.is_empty() {
            let total = n + corners.map_or(0, |cs| cs.object.len());
            let mut in_ball = vec![false; total];
            for s in &supports {
                self.for_each_point(s, corners, &mut |idx| in_ball[idx] = true);
            }
            for s in deferred {
                // Taken when it holds a member (its centre, or with `corners` a cell corner)
                // that no accepted ball holds.
                let mut needed = false;
                self.for_each_point(&s, corners, &mut |idx| needed |= !in_ball[idx]);
                if needed {
                    self.for_each_point(&s, corners, &mut |idx| in_ball[idx] = true);
                    supports.push(s);
                }
            }
        }
        supports
    }
}

/// Fisher–Yates with Lemire's unbiased bounded integers on PCG-64: portable across `rand`
/// versions, unlike `SliceRandom::shuffle`.
pub(super) fn shuffle(items: &mut [u32], seed: u64) {
    let mut rng = Pcg64::new(
        0xcafe_f00d_d15e_a5e5 ^ u128::from(seed),
        0x0a02_bdbf_7bb3_c0a7_ac28_fa16_a64a_bf96,
    );
    for i in (1..items.len()).rev() {
        let bound = i as u64 + 1;
        let j = loop {
            let m = u128::from(rng.next_u64()) * u128::from(bound);
            let low = m as u64;
            if low >= bound.wrapping_neg() % bound {
                break (m >> 64) as usize;
            }
        };
        items.swap(i, j);
    }
}

/// The thesis' covering loop (§3.4.2): the candidates of `order` (indices below `n`) not yet
/// covered are fitted in parallel batches, then handed in order to `take`, which marks what
/// the support covers; a candidate covered by an earlier support of its batch is skipped.
/// The result depends on the order only, not on the thread count.
pub(super) fn covering_loop(
    order: &[u32],
    n: usize,
    fit: impl Fn(usize) -> Support + Sync,
    stats: &mut VolumeCoverStats,
    mut take: impl FnMut(Support, &mut [bool]),
) {
    let mut covered = vec![false; n];
    let batch_size = (rayon::current_num_threads() * 4).clamp(1, 256);
    let mut pos = 0;
    let mut batch = Vec::with_capacity(batch_size);
    while pos < order.len() {
        batch.clear();
        while pos < order.len() && batch.len() < batch_size {
            let c = order[pos] as usize;
            pos += 1;
            if !covered[c] {
                batch.push(c);
            }
        }
        let fits: Vec<Support> = batch.par_iter().map(|&c| fit(c)).collect();
        stats.fits += fits.len();
        for s in fits {
            if !covered[s.centre as usize] {
                take(s, &mut covered);
            }
        }
    }
}
