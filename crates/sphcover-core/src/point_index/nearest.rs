//! The k-nearest queries of [`PointIndex`]: one branch-and-bound descent of the tree
//! (nearest box first) behind the `k` nearest pairs, the nearest distance and the `k`-th
//! distance, and the runs of queries bounded by a previous answer or by nearby slots.

use super::PointIndex;
use glam::DVec3;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// [`PointIndex::nearest_k_run`] and [`PointIndex::nearest_k_run_at_slots`] bound a search by
/// its seed points only while that bound is at most this factor times the previous `k`-th
/// squared distance.
const SEED_BOUND_GROWTH: f64 = 4.0;

impl PointIndex {
    /// The `k` nearest indexed points to `x` (fewer when fewer are indexed), ordered by
    /// ascending `(‖p − x‖², index)` — so ties in distance go to the lower index — into `out`
    /// (cleared first). Nothing for a non-finite `x`.
    pub fn nearest_k(&self, x: DVec3, k: usize, out: &mut Vec<u32>) {
        out.clear();
        let mut best = Vec::with_capacity(k.min(self.len()));
        self.nearest_k_with_distances(x, k, &mut best);
        out.extend(best.iter().map(|&(_, i)| i));
    }

    /// As [`PointIndex::nearest_k`], with the squared distances: `(‖p − x‖², index)` pairs.
    pub fn nearest_k_with_distances(&self, x: DVec3, k: usize, out: &mut Vec<(f64, u32)>) {
        out.clear();
        if k == 0 || self.nodes.is_empty() || !x.is_finite() {
            return;
        }
        if k <= SORTED_INSERTION_MAX {
            // Kept sorted as found: the final order directly.
            self.search_nearest(x, &mut SortedNearest { out, k });
        } else {
            let mut set = HeapNearest {
                heap: BinaryHeap::with_capacity(k.min(self.len()) + 1),
                k,
            };
            self.search_nearest(x, &mut set);
            out.extend(set.heap.into_sorted_vec().iter().map(|p| (p.0, p.1)));
        }
    }

    /// The smallest squared distance `‖p − x‖²` from `x` to an indexed point (the first
    /// distance [`PointIndex::nearest_k_with_distances`] gives for `k = 1`, the same bits),
    /// with the slot of a point at that distance; `None` for a non-finite `x` or an empty
    /// index. `hint`, the slot of a point near `x` (the answer for a neighbouring query, say),
    /// bounds the search from the start; the distance does not depend on it.
    pub fn nearest_distance2(&self, x: DVec3, hint: Option<usize>) -> Option<(f64, usize)> {
        if self.nodes.is_empty() || !x.is_finite() {
            return None;
        }
        let best = match hint.filter(|&s| s < self.points.len()) {
            Some(s) => ((self.points[s] - x).length_squared(), s),
            None => (f64::INFINITY, usize::MAX),
        };
        let mut search = NearestDistance {
            points: &self.points,
            x,
            best,
        };
        self.branch_and_bound(x, &mut search);
        let mut best = search.best;
        // Every point at an infinite distance (coordinates near overflow) leaves no slot.
        if best.1 == usize::MAX {
            best = (f64::INFINITY, 0);
        }
        Some(best)
    }

    /// Whether an indexed point lies within `r` of `x` (`‖p − x‖² < r²`, as
    /// [`PointIndex::for_each_slot_within`] tests it). The search descends towards `x` and
    /// stops at the first such point, so it costs far less than the nearest distance where
    /// the answer is yes. False for a non-finite `x`, a radius that is not positive or an
    /// empty index.
    ///
    /// ```
    /// use sphcover_core::{DVec3, PointIndex};
    ///
    /// let points: Vec<DVec3> = (0..100).map(|i| DVec3::new(i as f64, 0.0, 0.0)).collect();
    /// let index = PointIndex::new(&points)?;
    /// assert!(index.any_within(DVec3::new(41.2, 0.5, 0.0), 0.6));
    /// assert!(!index.any_within(DVec3::new(41.5, 0.5, 0.0), 0.6));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn any_within(&self, x: DVec3, r: f64) -> bool {
        if self.nodes.is_empty() || !x.is_finite() || r.is_nan() || r <= 0.0 {
            return false;
        }
        let mut search = AnyWithin {
            points: &self.points,
            x,
            r2: r * r,
            found: false,
        };
        self.branch_and_bound(x, &mut search);
        search.found
    }

    /// The largest squared distance among the `k` nearest indexed points to `x` (among all
    /// of them when fewer are indexed): the last distance
    /// [`PointIndex::nearest_k_with_distances`] gives, the same bits. `None` for `k = 0`, a
    /// non-finite `x` or an empty index. Which points tie at a distance does not change the
    /// `k`-th distance, so the search keeps distances alone and prunes ties.
    pub(crate) fn kth_nearest_distance2(&self, x: DVec3, k: usize) -> Option<f64> {
        let k = k.min(self.len());
        if k == 0 || !x.is_finite() {
            return None;
        }
        let mut search = KthDistance {
            points: &self.points,
            x,
            k,
            kept: Vec::with_capacity(k + 1),
        };
        self.branch_and_bound(x, &mut search);
        search.kept.last().copied()
    }

    /// The branch-and-bound search behind [`PointIndex::nearest_k_with_distances`], offering
    /// every point that may belong to the answer to `set`.
    fn search_nearest(&self, x: DVec3, set: &mut impl NearestSet) {
        let mut search = NearestK {
            points: &self.points,
            order: &self.order,
            x,
            set,
        };
        self.branch_and_bound(x, &mut search);
    }

    /// Visits the tree from the root, the child whose box is nearer to `x` first, skipping
    /// every node whose box `search` prunes (asked when the node is taken, so a bound that
    /// tightened meanwhile counts), and hands each leaf's slots to `search`.
    #[inline(always)]
    fn branch_and_bound(&self, x: DVec3, search: &mut impl BranchAndBound) {
        // The stack holds each node with the squared distance to its box.
        let mut stack = [(0u32, 0.0f64); 64];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let (n, box_d2) = stack[top];
            if search.prunes(box_d2) {
                continue;
            }
            let n = n as usize;
            let node = &self.nodes[n];
            if node.right == 0 {
                search.leaf(node.lo as usize, node.hi as usize);
                continue;
            }
            // The child whose box is nearer first (not the one on `x`'s side of the split:
            // from a query off the data, as the octree's empty cells are, that child's box
            // may be the farther one, and the first `k` points found bound the search
            // poorly). The answer does not depend on the order.
            let (left, right) = (n + 1, n + node.right as usize);
            let (dl, dr) = (
                self.nodes[left].box_distance2(x),
                self.nodes[right].box_distance2(x),
            );
            let (near, far) = if dl <= dr {
                ((left, dl), (right, dr))
            } else {
                ((right, dr), (left, dl))
            };
            stack[top] = (far.0 as u32, far.1);
            stack[top + 1] = (near.0 as u32, near.1);
            top += 2;
        }
    }

    /// The `k` nearest indexed points to each of `queries` in turn: `visit(q, neighbours)`
    /// gets exactly what [`PointIndex::nearest_k_with_distances`] gives for `queries[q]`
    /// (same pairs, same order), only faster when consecutive queries lie close together
    /// (points in slot order, say). Each search after the first is bounded by the previous
    /// answer: the previous query's `k` neighbours are `k` points at squared distance at most
    /// `b` (their `k`-th smallest, computed exactly as the search computes distances) from
    /// the new query, so the answer lies in the closed ball of squared radius `b`. Collecting
    /// that ball and selecting the `k` smallest `(distance², index)` pairs replaces the
    /// search's insertions into a sorted list, and the bound prunes the tree from the start.
    pub fn nearest_k_run(
        &self,
        queries: &[DVec3],
        k: usize,
        visit: impl FnMut(usize, &[(f64, u32)]),
    ) {
        self.nearest_k_run_by(queries.len(), |q| (queries[q], None), k, visit);
    }

    /// As [`PointIndex::nearest_k_run`], for the indexed points at `slots` (slot order
    /// positions, see [`PointIndex::slot_points`]; each point is its own nearest, at distance
    /// 0): `visit(q, neighbours)` gets exactly what [`PointIndex::nearest_k_with_distances`]
    /// gives for the point at `slots[q]`. Each search is bounded by the `2k + 1` slots around
    /// the query's own instead of the previous answer: slot order follows the tree, so `k` of
    /// them nearly always lie close, even where slot order jumps between subtrees and the
    /// previous query lies far. On the noise estimate of a 362K-point scan (12,929 queries of
    /// 174 neighbours, every 28th sample) a bound by the previous answer falls back to a
    /// plain search 4,038 times.
    ///
    /// # Panics
    ///
    /// When a slot is not below [`PointIndex::len`].
    pub fn nearest_k_run_at_slots(
        &self,
        slots: &[u32],
        k: usize,
        visit: impl FnMut(usize, &[(f64, u32)]),
    ) {
        if let Some(&s) = slots.iter().find(|&&s| s as usize >= self.len()) {
            panic!("slot {s} out of range for {} indexed points", self.len());
        }
        self.nearest_k_run_by(
            slots.len(),
            |q| {
                let s = slots[q] as usize;
                (self.points[s], Some(s))
            },
            k,
            visit,
        );
    }

    /// The runs of [`PointIndex::nearest_k_run`] and [`PointIndex::nearest_k_run_at_slots`]:
    /// `query(q)` gives the position of query `q` and, for an indexed point, its slot.
    fn nearest_k_run_by(
        &self,
        count: usize,
        query: impl Fn(usize) -> (DVec3, Option<usize>),
        k: usize,
        mut visit: impl FnMut(usize, &[(f64, u32)]),
    ) {
        let k_eff = k.min(self.len());
        let mut found: Vec<(f64, u32)> = Vec::with_capacity(k_eff);
        // The current answer, as (distance², index, slot).
        let mut answer: Vec<(f64, u32, u32)> = Vec::with_capacity(k_eff);
        let mut seed_d2: Vec<f64> = Vec::with_capacity(2 * k_eff + 1);
        let mut heap: Vec<NearKey> = Vec::with_capacity(k_eff + 1);
        let key =
            |a: &(f64, u32, u32), b: &(f64, u32, u32)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
        for q in 0..count {
            let (x, slot) = query(q);
            found.clear();
            if k_eff == 0 || !x.is_finite() {
                answer.clear();
                visit(q, &found);
                continue;
            }
            // Any `k` indexed points bound the answer by their `k`-th smallest squared
            // distance (computed exactly as the search computes distances): the query's slot
            // neighbours, or else the previous answer.
            seed_d2.clear();
            if let Some(s) = slot {
                let width = (2 * k_eff + 1).min(self.len());
                let start = s.saturating_sub(k_eff).min(self.len() - width);
                seed_d2.extend(
                    self.points[start..start + width]
                        .iter()
                        .map(|&p| (p - x).length_squared()),
                );
            } else if answer.len() == k_eff {
                seed_d2.extend(
                    answer
                        .iter()
                        .map(|&(_, _, s)| (self.points[s as usize] - x).length_squared()),
                );
            }
            let previous = (answer.len() == k_eff).then(|| answer[k_eff - 1].0);
            let mut bound = if seed_d2.len() >= k_eff {
                *seed_d2.select_nth_unstable_by(k_eff - 1, f64::total_cmp).1
            } else {
                f64::INFINITY
            };
            // A bound far above the previous answer's (a query far from the previous one, or
            // slot neighbours split between distant subtrees) would collect a large ball:
            // search it plainly instead.
            if previous.is_some_and(|kth| bound > SEED_BOUND_GROWTH * kth) {
                bound = f64::INFINITY;
            }
            answer.clear();
            if bound == f64::INFINITY {
                // A plain search, which also gives the slots the next query's bound needs.
                let mut set = HeapNearest {
                    heap: BinaryHeap::from(std::mem::take(&mut heap)),
                    k: k_eff,
                };
                set.heap.clear();
                self.search_nearest(x, &mut set);
                heap = set.heap.into_sorted_vec();
                answer.extend(heap.iter().map(|p| (p.0, p.1, p.2)));
            } else {
                self.for_each_slot_within_closed(x, bound, |s, d2| {
                    answer.push((d2, self.order[s], s as u32));
                });
                // At least `k_eff` points lie in the closed ball, so its `k_eff` smallest
                // pairs are the answer.
                debug_assert!(answer.len() >= k_eff);
                if answer.len() > k_eff {
                    answer.select_nth_unstable_by(k_eff - 1, key);
                    answer.truncate(k_eff);
                }
                answer.sort_unstable_by(key);
            }
            found.extend(answer.iter().map(|&(d2, i, _)| (d2, i)));
            visit(q, &found);
        }
    }
}

fn less(a: (f64, u32), b: (f64, u32)) -> bool {
    a.0 < b.0 || (a.0 == b.0 && a.1 < b.1)
}

/// Up to this many nearest points are kept in a sorted vector during a search, more in a
/// heap: inserting into the vector moves half of it, which for the hundreds of neighbours
/// of a scan's noise estimate costs more than the search itself.
const SORTED_INSERTION_MAX: usize = 48;

/// What a branch-and-bound search over the tree keeps (see
/// `PointIndex::branch_and_bound`).
trait BranchAndBound {
    /// Whether a node whose box lies at squared distance `box_d2` can hold nothing better.
    fn prunes(&self, box_d2: f64) -> bool;
    /// Offers the points of slots `lo..hi`.
    fn leaf(&mut self, lo: usize, hi: usize);
}

/// The smallest squared distance and a slot at it. Only the distance is asked for, not which
/// of several points at it: a subtree whose box is no nearer than the best distance so far
/// is pruned, ties included, with no list of candidates kept.
struct NearestDistance<'a> {
    points: &'a [DVec3],
    x: DVec3,
    best: (f64, usize),
}

impl BranchAndBound for NearestDistance<'_> {
    #[inline(always)]
    fn prunes(&self, box_d2: f64) -> bool {
        box_d2 >= self.best.0
    }

    #[inline(always)]
    fn leaf(&mut self, lo: usize, hi: usize) {
        for (s, &p) in (lo..).zip(&self.points[lo..hi]) {
            let d2 = (p - self.x).length_squared();
            if d2 < self.best.0 {
                self.best = (d2, s);
            }
        }
    }
}

/// Whether a point lies within the ball: once one is found, every node left is pruned.
struct AnyWithin<'a> {
    points: &'a [DVec3],
    x: DVec3,
    r2: f64,
    found: bool,
}

impl BranchAndBound for AnyWithin<'_> {
    #[inline(always)]
    fn prunes(&self, box_d2: f64) -> bool {
        self.found || box_d2 >= self.r2
    }

    #[inline(always)]
    fn leaf(&mut self, lo: usize, hi: usize) {
        self.found = self.points[lo..hi]
            .iter()
            .any(|&p| (p - self.x).length_squared() < self.r2);
    }
}

/// The `k` smallest squared distances met, ascending. Which points tie at a distance does
/// not change them, so ties are pruned.
struct KthDistance<'a> {
    points: &'a [DVec3],
    x: DVec3,
    k: usize,
    kept: Vec<f64>,
}

impl BranchAndBound for KthDistance<'_> {
    #[inline(always)]
    fn prunes(&self, box_d2: f64) -> bool {
        self.kept.len() == self.k && box_d2 >= self.kept[self.k - 1]
    }

    #[inline(always)]
    fn leaf(&mut self, lo: usize, hi: usize) {
        let k = self.k;
        for &p in &self.points[lo..hi] {
            let d2 = (p - self.x).length_squared();
            if self.kept.len() < k || d2 < self.kept[k - 1] {
                let at = self.kept.partition_point(|&e| e <= d2);
                self.kept.insert(at, d2);
                self.kept.truncate(k);
            }
        }
    }
}

/// The `k` nearest `(distance², index)` pairs, into a [`NearestSet`].
struct NearestK<'a, S> {
    points: &'a [DVec3],
    order: &'a [u32],
    x: DVec3,
    set: &'a mut S,
}

impl<S: NearestSet> BranchAndBound for NearestK<'_, S> {
    #[inline(always)]
    fn prunes(&self, box_d2: f64) -> bool {
        // A tie at exactly the bound may still hold a lower index, so prune only on `>`.
        self.set.bound().is_some_and(|b| box_d2 > b.0)
    }

    #[inline(always)]
    fn leaf(&mut self, lo: usize, hi: usize) {
        for s in lo..hi {
            let d2 = (self.points[s] - self.x).length_squared();
            let key = (d2, self.order[s]);
            if self.set.bound().is_none_or(|b| less(key, b)) {
                self.set.insert(NearKey(d2, key.1, s as u32));
            }
        }
    }
}

/// The best `(distance², index)` pairs a nearest-point search has met, at most `k`.
trait NearestSet {
    /// The worst pair kept, once `k` are kept (no later pair can enter unless below it).
    fn bound(&self) -> Option<(f64, u32)>;
    /// Keeps `key`, dropping the worst pair when `k` are kept. Called only for a pair below
    /// the bound.
    fn insert(&mut self, key: NearKey);
}

/// The pairs in ascending order.
struct SortedNearest<'a> {
    out: &'a mut Vec<(f64, u32)>,
    k: usize,
}

impl NearestSet for SortedNearest<'_> {
    #[inline]
    fn bound(&self) -> Option<(f64, u32)> {
        (self.out.len() == self.k).then(|| self.out[self.k - 1])
    }

    #[inline]
    fn insert(&mut self, key: NearKey) {
        let key = (key.0, key.1);
        let at = self.out.partition_point(|&e| less(e, key));
        if self.out.len() == self.k {
            self.out.pop();
        }
        self.out.insert(at, key);
    }
}

/// The pairs in a max-heap.
struct HeapNearest {
    heap: BinaryHeap<NearKey>,
    k: usize,
}

impl NearestSet for HeapNearest {
    #[inline]
    fn bound(&self) -> Option<(f64, u32)> {
        (self.heap.len() == self.k).then(|| self.heap.peek().map(|p| (p.0, p.1)))?
    }

    #[inline]
    fn insert(&mut self, key: NearKey) {
        if self.heap.len() == self.k {
            self.heap.pop();
        }
        self.heap.push(key);
    }
}

/// A point met by a search: `(distance², index, slot)`, ordered by `(distance², index)` as
/// [`less`] orders them (distances are never NaN).
#[derive(Clone, Copy, Debug)]
struct NearKey(f64, u32, u32);

impl PartialEq for NearKey {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for NearKey {}

impl PartialOrd for NearKey {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for NearKey {
    fn cmp(&self, other: &Self) -> Ordering {
        self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
    }
}
