//! Spatial index over balls: "which balls contain x" and "which balls come near a point".
//!
//! The method is described on [`BallIndex`].

use glam::DVec3;
use rayon::prelude::*;
use thiserror::Error;

/// Column width of a level, as a multiple of the level's largest radius: narrower columns
/// mean more columns to visit (two binary searches each), wider ones more balls to test. On
/// the 362K-point bunny (callgrind, one thread) the sphere intersection graph's rows cost
/// 2.74, 2.47 and 2.58 G instructions with widths 0.75, 1.5 and 2, and the
/// partition-of-unity evaluations hardly change.
const CELL_WIDTH_PER_RADIUS: f64 = 1.5;
/// Upper bound on the cells of a level's grid, per ball of the level.
const CELLS_PER_BALL: usize = 4;
/// Cells a level may always have, however few balls it holds.
const MIN_CELLS: usize = 64;
/// Largest level index; larger radius ratios (beyond 2^63) share the last level.
const MAX_LEVEL: usize = 63;
/// Relative widening of a query's reach, so that rounding in the distance test (a few ulps)
/// can never accept a ball that the grid bounds have already excluded.
const REACH_RELATIVE_MARGIN: f64 = 1e-12;
/// Relative widening of the squared reach when bounding the `x` extent of a row (see
/// `Level::for_each_candidate_run`).
const ROW_REACH_SQ_MARGIN: f64 = 1e-10;
/// Absolute widening of a query's reach: squared coordinate differences below about 1e-300
/// underflow, so the distance test may accept balls up to that far beyond its threshold.
const REACH_ABSOLUTE_MARGIN: f64 = 1e-150;

/// Widening of the squared bound in [`BallIndex::extend_within_loose`]: the squared distance,
/// the square of the bound and the literal test's square root are each off by a few ulps.
const LOOSE_SQ_FACTOR: f64 = 1.0 + 1e-12;

/// Bounds below this are squared into the subnormal range, where [`LOOSE_SQ_FACTOR`] no
/// longer covers the rounding.
const TINY_BOUND: f64 = 1e-140;

/// Why a [`BallIndex`] could not be built.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum BallIndexError {
    /// `centres` and `radii` have different lengths.
    #[error("{centres} centres but {radii} radii")]
    LengthMismatch {
        /// Number of centres given.
        centres: usize,
        /// Number of radii given.
        radii: usize,
    },
    /// Ball indices are `u32`; this many balls cannot be indexed.
    #[error("{len} balls exceed the u32 index range")]
    TooManyBalls {
        /// Number of balls given.
        len: usize,
    },
}

/// A ball as stored in the index: centre, radius and original index side by side, so that a
/// candidate costs one cache line at most.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PackedBall {
    pub(crate) centre: DVec3,
    pub(crate) radius: f64,
    pub(crate) id: u32,
}

/// One radius level: its balls sorted by grid column and `x`, and the column table.
#[derive(Clone, Debug)]
struct Level {
    /// Smallest and largest radius in the level; the reach of a query depends on both only
    /// through `scale·r + extra`, which is monotone in `r`.
    radius_lo: f64,
    radius_hi: f64,
    /// The grid of columns along `x`.
    y: GridAxis,
    z: GridAxis,
    /// `cell_start[cell]..cell_start[cell + 1]` are the balls of the column
    /// `cell = cz · y.cells + cy`.
    cell_start: Vec<u32>,
    /// The level's balls by column, each column sorted by `x` (then original index).
    balls: Vec<PackedBall>,
}

/// An index over a fixed set of balls `(c_j, r_j)`; see below for the
/// structure and its cost.
///
/// # Structure
///
/// Covers built from octrees (thesis §3.4.1) have radii spanning several orders of magnitude,
/// so a single grid is either too coarse for the small balls or too fine for the large ones.
/// Thesis Appendix B answers this with an octree keyed by sphere size; this index uses the
/// flat equivalent, which needs no pointer chasing:
///
/// * Balls are grouped into **radius levels**: level `L` holds the radii in
///   `[2^L, 2^{L+1}) · r_ref`, where `r_ref` is the smallest positive radius (zero and
///   negative radii join level 0). Within a level, radii differ by at most a factor of two, so
///   a query reach computed from the level's largest radius wastes little.
/// * Each level has a uniform grid of columns along `x` whose cross-sections are about as
///   wide as the level's largest radius (`CELL_WIDTH_PER_RADIUS`). The level's balls are
///   stored contiguously, sorted by column and within a column by `x`, each centre, radius
///   and original index copied side by side; `cell_start` maps a column to its range of balls
///   (compressed sparse rows over the dense column array).
/// * A query with reach `t` visits, per level, the columns `(y, z)` that meet the ball of
///   radius `t` around `x`, and in each only the balls whose `x` lies within that ball,
///   found by two binary searches: the candidates are those in a sphere's cross-section
///   times the columns' width, not in whole grid cells. (With cells along `x` as well, the
///   cap on cells made the cells of the smallest level of a surface cover many radii long
///   along `x`, and the sphere intersection graph of the 362K-point bunny met 13 candidates
///   per neighbour.)
/// * Balls with a non-finite radius live in a short list checked on every query; balls with
///   a non-finite centre can never pass the test and are dropped.
///
/// The grid is capped at `max(CELLS_PER_BALL · n_L, MIN_CELLS)` columns per level: memory
/// stays `O(n)` whatever the spread of the coordinates (one far-away ball cannot blow up the
/// table), at the price of wider columns.
///
/// # Complexity
///
/// Building takes `O(n log n)` time (one parallel sort) and `O(n)` memory, and gives the same
/// index for any thread count (the sort keys are distinct: column, `x`, then index). A query
/// with reach `t_L = max(scale·r, 0) + extra` over the radii `r` of level `L`, whose columns
/// have width `w_L`, costs per non-empty level `O((1 + 2 t_L / w_L)² log m_L + k_L)`, where
/// `m_L` is the most balls in a column and `k_L` the number of balls in the columns' parts
/// within `t_L` of `x` along `x`. For a
/// containment query (`scale = 1`, `extra = 0`) on a cover whose balls overlap a bounded
/// number of times, that is `O(levels + answer)`. A query spanning more grid rows than its
/// level has balls scans the level linearly instead, so no query costs more than `O(n)`.
#[derive(Clone, Debug)]
pub struct BallIndex {
    len: usize,
    levels: Vec<Level>,
    /// Balls with a finite centre and a non-finite radius, tested on every query.
    unbounded: Vec<PackedBall>,
}

impl BallIndex {
    /// Builds the index. `centres` and `radii` have the same length; radii are finite and
    /// non-negative (other values are tolerated: every query applies its test literally).
    ///
    /// # Panics
    ///
    /// When the lengths differ or there are more than `u32::MAX` balls; use
    /// [`BallIndex::try_new`] to get an error instead.
    pub fn new(centres: &[DVec3], radii: &[f64]) -> BallIndex {
        match BallIndex::try_new(centres, radii) {
            Ok(index) => index,
            Err(e) => panic!("BallIndex::new: {e}"),
        }
    }

    /// Builds the index, or says why the input cannot be indexed.
    pub fn try_new(centres: &[DVec3], radii: &[f64]) -> Result<BallIndex, BallIndexError> {
        if centres.len() != radii.len() {
            return Err(BallIndexError::LengthMismatch {
                centres: centres.len(),
                radii: radii.len(),
            });
        }
        let len = centres.len();
        if u32::try_from(len).is_err() {
            return Err(BallIndexError::TooManyBalls { len });
        }

        let mut unbounded = Vec::new();
        // Level of each ball; `u8::MAX` marks balls kept out of the levels.
        const NOT_IN_LEVEL: u8 = u8::MAX;
        let reference_radius = radii
            .par_iter()
            .zip(centres)
            .filter(|(r, c)| r.is_finite() && **r > 0.0 && c.is_finite())
            .map(|(r, _)| *r)
            .reduce(|| f64::INFINITY, f64::min);
        let level_of: Vec<u8> = centres
            .par_iter()
            .zip(radii)
            .map(|(c, &r)| {
                if !c.is_finite() || !r.is_finite() {
                    NOT_IN_LEVEL
                } else {
                    radius_level(r, reference_radius) as u8
                }
            })
            .collect();
        for (j, (c, &r)) in centres.iter().zip(radii).enumerate() {
            if c.is_finite() && !r.is_finite() {
                unbounded.push(PackedBall {
                    centre: *c,
                    radius: r,
                    id: j as u32,
                });
            }
        }

        let mut members: Vec<Vec<u32>> = vec![Vec::new(); MAX_LEVEL + 1];
        for (j, &level) in level_of.iter().enumerate() {
            if level != NOT_IN_LEVEL {
                members[level as usize].push(j as u32);
            }
        }
        let levels = members
            .into_par_iter()
            .filter(|m| !m.is_empty())
            .map(|m| Level::build(&m, centres, radii))
            .collect();

        Ok(BallIndex {
            len,
            levels,
            unbounded,
        })
    }

    /// Number of balls.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when the index holds no ball.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Calls `visit(j)` for every ball `j` with `‖x − c_j‖ < scale·r_j + extra`, in no
    /// particular order. `scale > 0`, `extra ≥ 0`.
    ///
    /// The test is evaluated literally as `c_j.distance(x) < scale * r_j + extra`, so the
    /// result is exactly that of a scan over all balls.
    pub fn for_each_within(&self, x: DVec3, scale: f64, extra: f64, mut visit: impl FnMut(u32)) {
        self.for_each_candidate_run(x, scale, extra, |balls| {
            for ball in balls {
                if ball.centre.distance(x) < scale * ball.radius + extra {
                    visit(ball.id);
                }
            }
        });
    }

    /// Appends to `out`, in no particular order, every ball `j` with
    /// `‖x − c_j‖ < scale·r_j + extra` and possibly a few more within rounding of that bound.
    ///
    /// For callers that apply their own exact test afterwards: comparing squared distances
    /// against a bound widened by a relative 1e-12 takes no square root per candidate, and
    /// the widening keeps every ball the literal test of [`BallIndex::for_each_within`] keeps.
    pub(crate) fn extend_within_loose(&self, x: DVec3, scale: f64, extra: f64, out: &mut Vec<u32>) {
        let mut len = out.len();
        self.for_each_candidate_run(x, scale, extra, |balls| {
            if out.len() < len + balls.len() {
                out.resize(2 * (len + balls.len()), 0);
            }
            // Write every candidate and keep it on a hit, as in `containing`.
            let run_out = &mut out[len..len + balls.len()];
            let mut hits = 0;
            for ball in balls {
                let t = scale * ball.radius + extra;
                let d2 = ball.centre.distance_squared(x);
                run_out[hits] = ball.id;
                // Below about 1e-150 the square of the bound loses its precision to
                // underflow: such balls get the literal test.
                let hit =
                    d2 < t * t * LOOSE_SQ_FACTOR || (t < TINY_BOUND && ball.centre.distance(x) < t);
                hits += usize::from(hit);
            }
            len += hits;
        });
        out.truncate(len);
    }

    /// The balls whose open interior contains `x` (`‖x − c_j‖ < r_j`), ascending, into `out`
    /// (cleared first).
    pub fn containing(&self, x: DVec3, out: &mut Vec<u32>) {
        out.clear();
        let mut len = 0;
        self.for_each_candidate_run(x, 1.0, 0.0, |balls| {
            if out.len() < len + balls.len() {
                out.resize(2 * (len + balls.len()), 0);
            }
            // Write every candidate and keep it on a hit: the test passes for a fraction of
            // the candidates that no branch predictor can guess.
            let run_out = &mut out[len..len + balls.len()];
            let mut hits = 0;
            for ball in balls {
                run_out[hits] = ball.id;
                hits += usize::from(ball.centre.distance(x) < ball.radius);
            }
            len += hits;
        });
        out.truncate(len);
        out.sort_unstable();
    }

    /// Calls `visit(balls)` on runs of balls that together hold every ball with
    /// `‖x − c_j‖ < scale·r_j + extra`, each ball at most once, in no particular order. The
    /// runs hold other balls too: callers apply their own exact test. The search reach is
    /// widened by a relative 1e-12 (`REACH_RELATIVE_MARGIN`), so a test against
    /// `scale·r_j + extra` evaluated in any order of operations, off by a few ulps, is still
    /// covered.
    ///
    /// Handing out runs rather than single balls keeps the caller's inner loop free of calls,
    /// so its counters stay in registers.
    pub(crate) fn for_each_candidate_run(
        &self,
        x: DVec3,
        scale: f64,
        extra: f64,
        mut visit: impl FnMut(&[PackedBall]),
    ) {
        // A non-finite query point is at infinite or undefined distance from every finite
        // centre: no test `distance < threshold` can pass.
        if !x.is_finite() {
            return;
        }
        for level in &self.levels {
            level.for_each_candidate_run(x, scale, extra, &mut visit);
        }
        if !self.unbounded.is_empty() {
            visit(&self.unbounded);
        }
    }
}

/// Level of a finite radius `r` relative to the smallest positive radius `reference`: the
/// binary exponent of `r / reference`, read from its bits so that it is exact.
fn radius_level(r: f64, reference: f64) -> usize {
    if r.is_nan() || r <= 0.0 || !reference.is_finite() {
        return 0;
    }
    // r ≥ reference, so the ratio is ≥ 1 (division is monotone and reference/reference = 1);
    // it may overflow to +inf, whose exponent field is the largest.
    let ratio = r / reference;
    let exponent = ((ratio.to_bits() >> 52) & 0x7ff) as i64 - 1023;
    exponent.clamp(0, MAX_LEVEL as i64) as usize
}

/// One axis of a level's grid: `cells` cells of width `width` from `origin`, the first and
/// last cells extended to infinity so that every coordinate has a cell.
#[derive(Clone, Copy, Debug)]
struct GridAxis {
    origin: f64,
    width: f64,
    /// `1 / width`, or 0 on a one-cell axis.
    inv_width: f64,
    cells: usize,
    /// Safety distance for [`GridAxis::gap`]: the cell computation and the cell bounds are
    /// each off by a few ulps of `|lo| + |hi|` (at most about 1.1e-15 of it together), and
    /// the slack is 90 times that.
    slack: f64,
}

impl GridAxis {
    /// The axis over `[lo, hi]` with cells of about `target_width`, at most `max_cells`.
    fn new(lo: f64, hi: f64, target_width: f64, max_cells: usize) -> GridAxis {
        let extent = hi - lo;
        let one_cell = GridAxis {
            origin: lo,
            width: f64::INFINITY,
            inv_width: 0.0,
            cells: 1,
            slack: 0.0,
        };
        if !(extent > 0.0 && extent.is_finite() && target_width > 0.0) {
            return one_cell;
        }
        let wanted = (extent / target_width).ceil();
        let cells = if wanted >= max_cells as f64 {
            max_cells
        } else {
            wanted as usize
        };
        GridAxis::with_cells(lo, hi, cells)
    }

    fn with_cells(lo: f64, hi: f64, cells: usize) -> GridAxis {
        let extent = hi - lo;
        if cells <= 1 || !(extent > 0.0 && extent.is_finite()) {
            return GridAxis::new(lo, hi, 0.0, 1);
        }
        let width = extent / cells as f64;
        GridAxis {
            origin: lo,
            width,
            inv_width: 1.0 / width,
            cells,
            slack: 1e-13 * (lo.abs() + hi.abs()),
        }
    }

    /// Cell of coordinate `v`: monotone non-decreasing in `v`, clamped to `[0, cells)`, and
    /// total (NaN, from `±inf · 0` on a one-cell axis, maps to 0).
    #[inline]
    fn cell(&self, v: f64) -> usize {
        let t = (v - self.origin) * self.inv_width;
        if t >= 1.0 {
            // `as` saturates, so +inf and huge values land in the last cell.
            (t as usize).min(self.cells - 1)
        } else {
            0
        }
    }

    /// A lower bound on `|v − u|` over the coordinates `u` that [`GridAxis::cell`] puts in
    /// cell `k`, conservative by `slack`.
    #[inline]
    fn gap(&self, v: f64, k: usize) -> f64 {
        let below = if k == 0 {
            f64::NEG_INFINITY
        } else {
            self.origin + k as f64 * self.width
        };
        let above = if k + 1 == self.cells {
            f64::INFINITY
        } else {
            self.origin + (k + 1) as f64 * self.width
        };
        let gap = (below - v).max(v - above);
        (gap - self.slack).max(0.0)
    }
}

impl Level {
    /// Builds the level holding the balls `members` (ascending original indices; centres and
    /// radii finite).
    fn build(members: &[u32], centres: &[DVec3], radii: &[f64]) -> Level {
        let (radius_lo, radius_hi, lo, hi) = members
            .par_iter()
            .map(|&j| {
                let (c, r) = (centres[j as usize], radii[j as usize]);
                (r, r, c, c)
            })
            .reduce(
                || {
                    (
                        f64::INFINITY,
                        f64::NEG_INFINITY,
                        DVec3::INFINITY,
                        DVec3::NEG_INFINITY,
                    )
                },
                |a, b| (a.0.min(b.0), a.1.max(b.1), a.2.min(b.2), a.3.max(b.3)),
            );

        let max_cells = (CELLS_PER_BALL * members.len())
            .max(MIN_CELLS)
            .min(u32::MAX as usize);
        // A level of points (radius 0) has no natural cell size: let the cap decide.
        let width = if radius_hi > 0.0 {
            CELL_WIDTH_PER_RADIUS * radius_hi
        } else {
            f64::MIN_POSITIVE
        };
        let mut y = GridAxis::new(lo.y, hi.y, width, max_cells);
        let mut z = GridAxis::new(lo.z, hi.z, width, max_cells);
        if y.cells.saturating_mul(z.cells) > max_cells {
            // Coarsen both axes by the same factor so the rows stay roughly square.
            let shrink = (max_cells as f64 / (y.cells as f64 * z.cells as f64)).sqrt();
            let mut cells_y = ((y.cells as f64 * shrink) as usize).max(1);
            let mut cells_z = ((z.cells as f64 * shrink) as usize).max(1);
            while cells_y * cells_z > max_cells {
                if cells_y >= cells_z {
                    cells_y -= 1;
                } else {
                    cells_z -= 1;
                }
            }
            y = GridAxis::with_cells(lo.y, hi.y, cells_y);
            z = GridAxis::with_cells(lo.z, hi.z, cells_z);
        }
        let cells = y.cells * z.cells;

        let mut balls: Vec<(u32, PackedBall)> = members
            .par_iter()
            .map(|&j| {
                let c = centres[j as usize];
                let cell = z.cell(c.z) * y.cells + y.cell(c.y);
                let ball = PackedBall {
                    centre: c,
                    radius: radii[j as usize],
                    id: j,
                };
                (cell as u32, ball)
            })
            .collect();
        // Distinct keys (the index last), so any sort gives the same order.
        balls.par_sort_unstable_by(|(ca, a), (cb, b)| {
            ca.cmp(cb)
                .then(a.centre.x.total_cmp(&b.centre.x))
                .then(a.id.cmp(&b.id))
        });

        let mut cell_start = vec![0u32; cells + 1];
        for &(cell, _) in &balls {
            cell_start[cell as usize + 1] += 1;
        }
        for cell in 0..cells {
            cell_start[cell + 1] += cell_start[cell];
        }

        Level {
            radius_lo,
            radius_hi,
            y,
            z,
            cell_start,
            balls: balls.into_par_iter().map(|(_, ball)| ball).collect(),
        }
    }

    /// Largest threshold `scale·r + extra` over the level's radii, widened by the rounding
    /// margins; `None` when no ball of the level can pass (threshold ≤ 0 or NaN).
    #[inline]
    fn reach(&self, scale: f64, extra: f64) -> Option<f64> {
        // `scale·r + extra` is monotone in r (either direction, whatever the sign of scale), so
        // its maximum over the level is at one end; `max` skips a NaN end (e.g. inf · 0).
        let threshold = (scale * self.radius_lo + extra).max(scale * self.radius_hi + extra);
        if threshold > 0.0 {
            Some(threshold * (1.0 + REACH_RELATIVE_MARGIN) + REACH_ABSOLUTE_MARGIN)
        } else {
            None
        }
    }

    #[inline]
    fn for_each_candidate_run(
        &self,
        x: DVec3,
        scale: f64,
        extra: f64,
        visit: &mut impl FnMut(&[PackedBall]),
    ) {
        let Some(reach) = self.reach(scale, extra) else {
            return;
        };
        let cy0 = self.y.cell(x.y - reach);
        let cy1 = self.y.cell(x.y + reach);
        let cz0 = self.z.cell(x.z - reach);
        let cz1 = self.z.cell(x.z + reach);

        let rows = (cy1 - cy0 + 1) * (cz1 - cz0 + 1);
        // Beyond about 1e154 the reach has no finite square and the row bounds below would
        // meet inf − inf: such reaches simply scan the level.
        let reach_sq = reach * reach * (1.0 + ROW_REACH_SQ_MARGIN);
        if rows >= self.balls.len() || reach_sq == f64::INFINITY {
            visit(&self.balls);
            return;
        }
        // Only the part of a column inside the ball of radius `reach` around x can hold a
        // candidate: a column at (y, z) distance g from x needs |c.x − x.x| < sqrt(reach² − g²).
        // The relative widening of reach² keeps that bound above the exact one despite the
        // rounding of the subtraction (which loses all precision when g ≈ reach). With reach_sq
        // finite, a gap whose square overflows makes `left` −inf and skips the column.
        for cz in cz0..=cz1 {
            let gz = self.z.gap(x.z, cz);
            let left_z = reach_sq - gz * gz;
            if left_z < 0.0 {
                continue;
            }
            for cy in cy0..=cy1 {
                let gy = self.y.gap(x.y, cy);
                let left = left_z - gy * gy;
                if left < 0.0 {
                    continue;
                }
                let column = cz * self.y.cells + cy;
                let (start, end) = (
                    self.cell_start[column] as usize,
                    self.cell_start[column + 1] as usize,
                );
                if start == end {
                    continue;
                }
                // The tests compare the same difference `c.x − x.x` (up to its sign), and
                // `fl(c.x − x.x)` is monotone in `c.x`, so the column's candidates are one
                // range. The relative widening covers the rounding of the tests' sums of
                // squares (a few ulps), the absolute one the underflow of their squares.
                let half = left.sqrt() * (1.0 + 1e-9) + REACH_ABSOLUTE_MARGIN;
                let column = &self.balls[start..end];
                let first = column.partition_point(|b| b.centre.x - x.x < -half);
                let last = first + column[first..].partition_point(|b| b.centre.x - x.x <= half);
                if first < last {
                    visit(&column[first..last]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn coord() -> impl Strategy<Value = f64> {
        -1.0f64..1.0
    }

    proptest! {
        /// The loose query keeps every ball of the literal one, only adds balls within
        /// rounding of the bound, and appends after what `out` held.
        #[test]
        fn loose_query_holds_the_literal_one(
            balls in prop::collection::vec((coord(), coord(), coord(), 1e-3f64..0.5), 1..200),
            (qx, qy, qz) in (coord(), coord(), coord()),
            on_sphere in any::<prop::sample::Index>(),
            extra in prop_oneof![Just(0.0), 0.0f64..0.3],
        ) {
            let centres: Vec<DVec3> = balls.iter().map(|b| DVec3::new(b.0, b.1, b.2)).collect();
            let radii: Vec<f64> = balls.iter().map(|b| b.3).collect();
            let index = BallIndex::new(&centres, &radii);
            // Half of the queries sit on a sphere, where the two tests are closest.
            let mut queries = vec![DVec3::new(qx, qy, qz)];
            let j = on_sphere.index(centres.len());
            let dir = DVec3::new(qx, qy, qz).normalize_or(DVec3::X);
            queries.push(centres[j] + dir * (radii[j] + extra));
            for x in queries {
                let mut literal = Vec::new();
                index.for_each_within(x, 1.0, extra, |j| literal.push(j));
                literal.sort_unstable();
                let mut loose = vec![u32::MAX];
                index.extend_within_loose(x, 1.0, extra, &mut loose);
                prop_assert_eq!(loose[0], u32::MAX);
                let mut loose = loose.split_off(1);
                loose.sort_unstable();
                for j in &literal {
                    prop_assert!(loose.binary_search(j).is_ok(), "ball {j} missing");
                }
                for &j in &loose {
                    let bound = radii[j as usize] + extra;
                    prop_assert!(centres[j as usize].distance(x) < bound * (1.0 + 1e-9));
                }
            }
        }
    }
}
