//! A static k-d tree over points: fixed-radius and k-nearest queries.
//!
//! The method is described on [`PointIndex`].

mod nearest;
mod within_batch;

use glam::DVec3;
use rayon::prelude::*;

/// Points per leaf bucket at most (a split halves a node, so leaves hold 16–32). Larger
/// buckets mean fewer nodes to test and longer sequential runs of points: on the 362K-point
/// bunny, leaves of 22 points instead of 11 make `sphcover recon` use less CPU, most of the
/// saving in the cover's gathers; larger buckets (leaves of 44) are no faster.
const BUCKET: usize = 32;
/// Subtrees with at least this many points are built on two threads.
const PARALLEL_BUILD: usize = 1 << 14;

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
        self.for_each_leaf_near::<CLOSED, false>(x, r2, |leaf| {
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
        dist2: Option<&mut Vec<f64>>,
    ) {
        self.extend_within_in::<false>(x, r, slots, dist2);
    }

    /// [`PointIndex::extend_within`] in ascending slot order rather than tree order (the
    /// same slots, as a sort of them would give).
    pub(crate) fn extend_within_ascending(&self, x: DVec3, r: f64, slots: &mut Vec<u32>) {
        self.extend_within_in::<true>(x, r, slots, None);
    }

    /// [`PointIndex::extend_within`] in tree order, or in ascending slot order when
    /// `ASCENDING`.
    fn extend_within_in<const ASCENDING: bool>(
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
        self.for_each_leaf_near::<false, ASCENDING>(x, r2, |leaf| {
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
    /// (`≤` when `CLOSED`), nearer children first (tree order), or left children first
    /// (ascending slots) when `ASCENDING`. Nothing for a non-finite `x` or a NaN `r2`.
    fn for_each_leaf_near<const CLOSED: bool, const ASCENDING: bool>(
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
            let (near, far) = if ASCENDING {
                (n + 1, n + node.right as usize)
            } else {
                node.children_near_far(n, x)
            };
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
pub(crate) fn keep_inside(slots: &mut [u32], dist2: &mut [f64], r2: f64) -> usize {
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
            // In ascending slot order: the same slots, sorted.
            let mut ascending = vec![u32::MAX];
            index.extend_within_ascending(x, r, &mut ascending);
            let mut sorted = appended[1..].to_vec();
            sorted.sort_unstable();
            prop_assert_eq!(ascending[0], u32::MAX);
            prop_assert_eq!(&ascending[1..], &sorted[..]);
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
                // Some point lies within `r` exactly when the brute force finds one.
                for r in [0.0, 0.05, 0.2, 0.6] {
                    let brute = points.iter().any(|&p| (p - x).length_squared() < r * r);
                    prop_assert_eq!(index.any_within(x, r), brute);
                }
            }
        }
    }
}
