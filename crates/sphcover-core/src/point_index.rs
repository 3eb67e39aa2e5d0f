//! A static k-d tree over points: fixed-radius and k-nearest queries.
//!
//! The method is described on [`PointIndex`].

mod within_batch;

use glam::DVec3;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Points per leaf bucket at most (a split halves a node, so leaves hold 16–32). Larger
/// buckets mean fewer nodes to test and longer sequential runs of points: on the 362K-point
/// bunny, leaves of 22 points instead of 11 make `sphcover recon` use less CPU, most of the
/// saving in the cover's gathers; larger buckets (leaves of 44) are no faster.
const BUCKET: usize = 32;
/// Subtrees with at least this many points are built on two threads.
const PARALLEL_BUILD: usize = 1 << 14;
/// [`PointIndex::nearest_k_run`] and [`PointIndex::nearest_k_run_at_slots`] bound a search by
/// its seed points only while that bound is at most this factor times the previous `k`-th
/// squared distance.
const SEED_BOUND_GROWTH: f64 = 4.0;

/// Why a point index could not be built.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PointIndexError {
    /// More points than `u32` indices can name.
    #[error("{count} points exceed the u32 index range")]
    TooManyPoints {
        /// Number of points given.
        count: usize,
    },
}

/// A node of the tree in pre-order; the left child follows its parent directly.
#[derive(Clone, Copy, Debug)]
struct Node {
    /// Split coordinate (inner nodes).
    split: f64,
    /// First slot of the node's points.
    lo: u32,
    /// One past the last slot.
    hi: u32,
    /// Offset from this node to its right child; 0 for a leaf.
    right: u32,
    /// Split axis (inner nodes).
    axis: u8,
    /// Corners of the tight bounding box of the node's points: for points on a surface it
    /// is far smaller than the node's cell, so it prunes more of a query's tree.
    min: DVec3,
    max: DVec3,
}

impl Node {
    /// The children of inner node `n` (this node): the one on `x`'s side of the split first.
    #[inline]
    fn children_near_far(&self, n: usize, x: DVec3) -> (usize, usize) {
        let (left, right) = (n + 1, n + self.right as usize);
        if x[self.axis as usize] < self.split {
            (left, right)
        } else {
            (right, left)
        }
    }

    /// Squared distance from `x` to the farthest corner of the node's bounding box. Rounding
    /// is monotonic, so no point below is at a larger computed squared distance: when this is
    /// below `r²`, so is every point's.
    #[inline]
    fn box_farthest2(&self, x: DVec3) -> f64 {
        (x - self.min)
            .abs()
            .max((self.max - x).abs())
            .length_squared()
    }

    /// Squared distance from `x` to the node's bounding box (0 inside). Rounding is
    /// monotonic, so it never exceeds the computed squared distance to a point below.
    #[inline]
    fn box_distance2(&self, x: DVec3) -> f64 {
        (self.min - x)
            .max(x - self.max)
            .max(DVec3::ZERO)
            .length_squared()
    }
}

/// A static k-d tree over a set of points (query conventions below).
///
/// Built once (in parallel, with a result that does not depend on the thread count) and
/// queried from many threads through `&self`. The tree keeps its own copy of the points,
/// permuted so that every leaf bucket is a contiguous run of memory; [`PointIndex::order`]
/// maps these *slots* back to the caller's indices, so a caller that queries heavily can
/// permute its own per-point data the same way and read it sequentially too.
///
/// # Query conventions
///
/// * A point `p` is *within* radius `r` of `x` when `‖p − x‖² < r²`, both sides computed in
///   `f64` exactly as written: the open ball, like the supports of a cover.
/// * [`PointIndex::within`] and [`PointIndex::nearest_k`] report caller indices in a defined
///   order (ascending index; ascending `(distance², index)`), so results never depend on the
///   tree's internals. The `for_each_*` visitors report in tree order, which is fixed for a
///   given input and therefore deterministic too.
/// * Non-finite points are not indexed: no query ever reports them.
#[derive(Clone, Debug)]
pub struct PointIndex {
    /// Indexed points in slot order.
    points: Vec<DVec3>,
    /// Caller index of each slot.
    order: Vec<u32>,
    nodes: Vec<Node>,
    /// Number of points given to [`PointIndex::new`], finite or not.
    input_len: usize,
}

impl PointIndex {
    /// Builds the index over `points` (non-finite points are left out). The tree depends only
    /// on the input, never on the number of threads.
    pub fn new(points: &[DVec3]) -> Result<PointIndex, PointIndexError> {
        if u32::try_from(points.len()).is_err() {
            return Err(PointIndexError::TooManyPoints {
                count: points.len(),
            });
        }
        // Sized up front: a filtered collect grows the list by doubling, copying it again
        // each time.
        let mut items: Vec<(DVec3, u32)> = Vec::with_capacity(points.len());
        items.extend(
            points
                .iter()
                .enumerate()
                .filter(|(_, p)| p.is_finite())
                .map(|(i, &p)| (p, i as u32)),
        );
        let nodes = build(&mut items, 0);
        let (points_sorted, order) = items.par_iter().copied().unzip();
        Ok(PointIndex {
            points: points_sorted,
            order,
            nodes,
            input_len: points.len(),
        })
    }

    /// Number of indexed (finite) points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when no point is indexed.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Number of points given at construction, including non-finite ones left out.
    pub fn input_len(&self) -> usize {
        self.input_len
    }

    /// The caller index of each slot: slot `s` holds point `order()[s]`.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// The indexed points in slot order.
    pub fn slot_points(&self) -> &[DVec3] {
        &self.points
    }

    /// Calls `visit(slot, distance²)` for every indexed point with `‖p − x‖² < r²`, in tree
    /// order. Nothing is reported for a non-finite `x` or a radius that is not positive.
    pub fn for_each_slot_within(&self, x: DVec3, r: f64, visit: impl FnMut(usize, f64)) {
        if r.is_nan() || r <= 0.0 {
            return;
        }
        self.for_each_slot_in_ball::<false>(x, r * r, visit);
    }

    /// Calls `visit(index, point)` for every indexed point with `‖p − x‖² < r²`, in tree
    /// order.
    pub fn for_each_within(&self, x: DVec3, r: f64, mut visit: impl FnMut(u32, DVec3)) {
        self.for_each_slot_within(x, r, |s, _| visit(self.order[s], self.points[s]));
    }

    /// The indices of the points with `‖p − x‖² < r²`, ascending, into `out` (cleared
    /// first).
    pub fn within(&self, x: DVec3, r: f64, out: &mut Vec<u32>) {
        out.clear();
        self.for_each_slot_within(x, r, |s, _| out.push(self.order[s]));
        out.sort_unstable();
    }

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

    /// The number of indexed points with `‖p − x‖² < r²` (exactly those
    /// [`PointIndex::for_each_slot_within`] reports), with `visit(slot)` called for a sample
    /// of them spread over the ball: one slot of each subtree that lies wholly in the ball
    /// and is a leaf or has a bounding box of diagonal at most `grain`, and the first slot in
    /// the ball of every other leaf met. A subtree wholly in the ball is counted without
    /// reading its points, so for a ball holding many points this costs a small part of
    /// gathering them.
    pub(crate) fn count_within_sampled(
        &self,
        x: DVec3,
        r: f64,
        grain: f64,
        mut visit: impl FnMut(usize),
    ) -> usize {
        let r2 = r * r;
        if self.nodes.is_empty() || !x.is_finite() || r.is_nan() || r <= 0.0 {
            return 0;
        }
        // `x` is finite and the boxes are, so the distance is never NaN.
        if self.nodes[0].box_distance2(x) >= r2 {
            return 0;
        }
        let grain2 = grain * grain;
        let mut count = 0;
        // Each node with whether an ancestor already lies wholly in the ball.
        let mut stack = [(0u32, false); 64];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let (n, contained) = stack[top];
            let n = n as usize;
            let node = &self.nodes[n];
            if contained || node.box_farthest2(x) < r2 {
                if !contained {
                    count += (node.hi - node.lo) as usize;
                }
                if node.right == 0 || (node.max - node.min).length_squared() <= grain2 {
                    visit(node.lo as usize);
                } else {
                    stack[top] = ((n + node.right as usize) as u32, true);
                    stack[top + 1] = ((n + 1) as u32, true);
                    top += 2;
                }
                continue;
            }
            if node.right == 0 {
                let mut first = true;
                for s in node.lo as usize..node.hi as usize {
                    if (self.points[s] - x).length_squared() < r2 {
                        count += 1;
                        if first {
                            visit(s);
                            first = false;
                        }
                    }
                }
                continue;
            }
            for child in [n + node.right as usize, n + 1] {
                if self.nodes[child].box_distance2(x) < r2 {
                    stack[top] = (child as u32, false);
                    top += 1;
                }
            }
        }
        count
    }

    /// Calls `visit(slot, distance²)` for every indexed point with `‖p − x‖² ≤ bound`, in
    /// tree order (the closed ball, unlike [`PointIndex::for_each_slot_within`]).
    fn for_each_slot_within_closed(&self, x: DVec3, bound: f64, visit: impl FnMut(usize, f64)) {
        self.for_each_slot_in_ball::<true>(x, bound, visit);
    }

    /// Calls `visit(slot, distance²)` for every indexed point with `‖p − x‖² < r2` (`≤` when
    /// `CLOSED`), in tree order. Nothing is reported for a non-finite `x` or a NaN `r2`.
    fn for_each_slot_in_ball<const CLOSED: bool>(
        &self,
        x: DVec3,
        r2: f64,
        mut visit: impl FnMut(usize, f64),
    ) {
        let inside = |d2: f64| if CLOSED { d2 <= r2 } else { d2 < r2 };
        self.for_each_leaf_near::<CLOSED>(x, r2, |leaf| {
            for s in leaf.lo as usize..leaf.hi as usize {
                let d2 = (self.points[s] - x).length_squared();
                if inside(d2) {
                    visit(s, d2);
                }
            }
        });
    }

    /// Appends to `slots` the slots that [`PointIndex::for_each_slot_within`] reports for
    /// `x` and `r`, in the same order, and to `dist2`, when given, their squared distances
    /// (the same bits). A leaf whose box lies wholly inside the ball is appended without a
    /// test (by the rounding argument of `box_farthest2`, each of its points passes it), and
    /// the others are filtered without a branch per point, which no predictor could guess.
    /// `dist2` must be as long as `slots`.
    pub(crate) fn extend_within(
        &self,
        x: DVec3,
        r: f64,
        slots: &mut Vec<u32>,
        mut dist2: Option<&mut Vec<f64>>,
    ) {
        if r.is_nan() || r <= 0.0 {
            return;
        }
        debug_assert!(dist2.as_ref().is_none_or(|d| d.len() == slots.len()));
        let r2 = r * r;
        self.for_each_leaf_near::<false>(x, r2, |leaf| {
            let points = &self.points[leaf.lo as usize..leaf.hi as usize];
            let start = slots.len();
            // Every slot of the leaf is appended, then those outside are squeezed out: a
            // write per point without a branch, through slices whose length the compiler
            // knows (writing through `slots[len]` checked a bound per point).
            slots.extend(leaf.lo..leaf.hi);
            let whole = leaf.box_farthest2(x) < r2;
            match dist2.as_deref_mut() {
                Some(dist2) => {
                    dist2.extend(points.iter().map(|&p| (p - x).length_squared()));
                    if !whole {
                        let kept = keep_inside(&mut slots[start..], &mut dist2[start..], r2);
                        slots.truncate(start + kept);
                        dist2.truncate(start + kept);
                    }
                }
                None if !whole => {
                    let out = &mut slots[start..];
                    let mut kept = 0;
                    for (s, &p) in (leaf.lo..).zip(points) {
                        out[kept] = s;
                        kept += usize::from((p - x).length_squared() < r2);
                    }
                    slots.truncate(start + kept);
                }
                None => {}
            }
        });
    }

    /// Calls `visit(leaf)` for every leaf whose bounding box meets the ball `‖p − x‖² < r2`
    /// (`≤` when `CLOSED`), nearer children first (tree order). Nothing for a non-finite `x`
    /// or a NaN `r2`.
    fn for_each_leaf_near<const CLOSED: bool>(
        &self,
        x: DVec3,
        r2: f64,
        mut visit: impl FnMut(&Node),
    ) {
        if self.nodes.is_empty() || !x.is_finite() || r2.is_nan() {
            return;
        }
        let inside = |d2: f64| if CLOSED { d2 <= r2 } else { d2 < r2 };
        if !inside(self.nodes[0].box_distance2(x)) {
            return;
        }
        // Children whose bounding box lies outside the ball hold no point inside it; the near
        // child is visited first, so the points come in tree order.
        let mut stack = [0u32; 64];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let n = stack[top] as usize;
            let node = &self.nodes[n];
            if node.right == 0 {
                visit(node);
                continue;
            }
            let (near, far) = node.children_near_far(n, x);
            for child in [far, near] {
                if inside(self.nodes[child].box_distance2(x)) {
                    stack[top] = child as u32;
                    top += 1;
                }
            }
        }
    }
}

/// Moves the pairs `(slots[k], dist2[k])` with `dist2[k] < r2` to the front, in order,
/// without a branch per pair; returns how many there are.
#[inline]
fn keep_inside(slots: &mut [u32], dist2: &mut [f64], r2: f64) -> usize {
    let n = slots.len().min(dist2.len());
    let (slots, dist2) = (&mut slots[..n], &mut dist2[..n]);
    let mut kept = 0;
    for k in 0..n {
        let d2 = dist2[k];
        slots[kept] = slots[k];
        dist2[kept] = d2;
        kept += usize::from(d2 < r2);
    }
    kept
}

/// Lexicographic `(distance², index)` order.
#[inline]
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

/// Builds the subtree over `items` (slots `base..base + items.len()`), returning its nodes in
/// pre-order with relative child offsets, so subtrees built on other threads concatenate.
fn build(items: &mut [(DVec3, u32)], base: usize) -> Vec<Node> {
    let n = items.len();
    if n == 0 {
        return Vec::new();
    }
    let (lo, hi) = items.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), (p, _)| (lo.min(*p), hi.max(*p)),
    );
    let leaf = Node {
        split: 0.0,
        lo: base as u32,
        hi: (base + n) as u32,
        right: 0,
        axis: 0,
        min: lo,
        max: hi,
    };
    if n <= BUCKET {
        return vec![leaf];
    }
    let extent = hi - lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    if extent[axis] == 0.0 {
        // All points coincide: splitting cannot separate them.
        return vec![leaf];
    }
    let mid = n / 2;
    // Ties in the coordinate are broken by index, so the partition is a pure function of
    // the input. One comparison per axis: indexing the point by a variable axis inside the
    // comparison cost a branch per point.
    fn select_by(items: &mut [(DVec3, u32)], mid: usize, coordinate: impl Fn(DVec3) -> f64) {
        items.select_nth_unstable_by(mid, |a, b| {
            coordinate(a.0)
                .total_cmp(&coordinate(b.0))
                .then(a.1.cmp(&b.1))
        });
    }
    match axis {
        0 => select_by(items, mid, |p| p.x),
        1 => select_by(items, mid, |p| p.y),
        _ => select_by(items, mid, |p| p.z),
    }
    let split = items[mid].0[axis];
    let (left, right) = items.split_at_mut(mid);
    let (left_nodes, right_nodes) = if n >= PARALLEL_BUILD {
        rayon::join(|| build(left, base), || build(right, base + mid))
    } else {
        (build(left, base), build(right, base + mid))
    };
    let mut nodes = Vec::with_capacity(1 + left_nodes.len() + right_nodes.len());
    nodes.push(Node {
        split,
        lo: base as u32,
        hi: (base + n) as u32,
        right: (1 + left_nodes.len()) as u32,
        axis: axis as u8,
        min: lo,
        max: hi,
    });
    nodes.extend(left_nodes);
    nodes.extend(right_nodes);
    nodes
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The count is that of the open ball, brute force; the sample holds distinct points
        /// of the ball, at least one when the ball holds any; the ball's slots come the same
        /// from every gathering.
        #[test]
        fn sampled_count_matches_brute_force(
            points in prop::collection::vec(
                (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
                    .prop_map(|(x, y, z)| DVec3::new(x, y, z)),
                0..400,
            ),
            centre in (-1.2..1.2f64, -1.2..1.2f64, -1.2..1.2f64),
            radius in 0.0..2.5f64,
            grain in 0.0..1.0f64,
            on_a_point in any::<prop::sample::Index>(),
        ) {
            let index = PointIndex::new(&points).unwrap();
            // Half the time the ball passes exactly through a point: the open ball leaves
            // it out.
            let x = DVec3::new(centre.0, centre.1, centre.2);
            let r = if points.is_empty() || radius < 1.0 {
                radius
            } else {
                (points[on_a_point.index(points.len())] - x).length()
            };
            let brute = points.iter().filter(|p| (**p - x).length_squared() < r * r).count();
            let mut sample = Vec::new();
            let count = index.count_within_sampled(x, r, grain * r, |s| sample.push(s));
            prop_assert_eq!(count, brute);
            let mut gathered = Vec::new();
            index.for_each_slot_within(x, r, |s, _| gathered.push(s));
            prop_assert_eq!(gathered.len(), brute);
            // The branch-free gathering appends the same slots in the same order, after what
            // the list held.
            let mut appended = vec![u32::MAX];
            index.extend_within(x, r, &mut appended, None);
            prop_assert_eq!(appended[0], u32::MAX);
            prop_assert!(appended[1..].iter().map(|&s| s as usize).eq(gathered.iter().copied()));
            let (mut slots, mut dist2) = (vec![u32::MAX], vec![-1.0]);
            index.extend_within(x, r, &mut slots, Some(&mut dist2));
            let mut visited = Vec::new();
            index.for_each_slot_within(x, r, |s, d2| visited.push((s as u32, d2.to_bits())));
            prop_assert_eq!((slots[0], dist2[0]), (u32::MAX, -1.0));
            prop_assert!(slots[1..].iter().zip(&dist2[1..]).map(|(&s, d)| (s, d.to_bits())).eq(visited));
            for &s in &sample {
                prop_assert!(gathered.contains(&s));
            }
            let total = sample.len();
            sample.sort_unstable();
            sample.dedup();
            prop_assert_eq!(sample.len(), total);
            prop_assert_eq!(sample.is_empty(), brute == 0);
        }

        /// The nearest distance is bitwise the first of the `k = 1` search, whatever the
        /// hint, and its slot holds a point at that distance.
        #[test]
        fn nearest_distance_matches_the_nearest_search(
            points in prop::collection::vec(
                (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
                    .prop_map(|(x, y, z)| DVec3::new(x, y, z)),
                0..300,
            ),
            queries in prop::collection::vec((-1.5..1.5f64, -1.5..1.5f64, -1.5..1.5f64), 1..20),
            hint in any::<prop::sample::Index>(),
        ) {
            let index = PointIndex::new(&points).unwrap();
            let mut found = Vec::new();
            for (x, y, z) in queries {
                let x = DVec3::new(x, y, z);
                index.nearest_k_with_distances(x, 1, &mut found);
                let hint = (!points.is_empty()).then(|| hint.index(points.len()));
                for k in [1, 2, 5, 15] {
                    index.nearest_k_with_distances(x, k, &mut found);
                    prop_assert_eq!(
                        index.kth_nearest_distance2(x, k).map(f64::to_bits),
                        found.last().map(|f| f.0.to_bits())
                    );
                }
                index.nearest_k_with_distances(x, 1, &mut found);
                for h in [None, hint] {
                    let got = index.nearest_distance2(x, h);
                    prop_assert_eq!(got.map(|g| g.0.to_bits()), found.first().map(|f| f.0.to_bits()));
                    if let Some((d2, s)) = got {
                        prop_assert_eq!((index.points[s] - x).length_squared().to_bits(), d2.to_bits());
                    }
                }
            }
        }
    }
}
