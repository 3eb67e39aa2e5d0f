//! Partition-of-unity evaluation of a cover: `f`, `∇f`, `∇²f` (thesis eq. 3.1, 3.5, 3.9),
//! with the support expansion factor σ of thesis §6.2.2.
//!
//! The method is described on [`PuEvaluator`].

mod packed;

use crate::LengthMismatch;
use crate::ball_index::BallIndex;
use crate::cover::{Cover, CoverError};
use crate::geometry::Aabb;
use crate::kernel::{Kernel, gradient_hessian, outer};
use crate::spatial_order::{BatchPlan, bounding_sphere, in_input_order};
use glam::{DMat3, DVec3};
use packed::{PackedSupport, PackedSupports};
use rayon::prelude::*;
use std::cell::RefCell;

/// Calls `$method::<K, _>(supports, x, ids, extra…)` with the kernel type and packed
/// supports of the evaluator.
macro_rules! dispatch {
    ($self:ident, $x:ident, $ids:ident, $method:ident $(, $extra:expr)*) => {
        dispatch_packed!(&$self.supports, $self.cover.kernel(), $x, $ids, $method $(, $extra)*)
    };
}

/// Calls `$method::<K, _>(supports, x, ids, extra…)` with the kernel type of `$kernel` and
/// the packed supports `$supports`.
macro_rules! dispatch_packed {
    ($supports:expr, $kernel:expr, $x:ident, $ids:ident, $method:ident $(, $extra:expr)*) => {{
        match $supports {
            PackedSupports::Linear(v) => {
                dispatch_packed!(@kernel $kernel, v, $x, $ids, $method $(, $extra)*)
            }
            PackedSupports::Quadratic(v) => {
                dispatch_packed!(@kernel $kernel, v, $x, $ids, $method $(, $extra)*)
            }
        }
    }};
    (@kernel $kernel:expr, $v:ident, $x:ident, $ids:ident, $method:ident $(, $extra:expr)*) => {
        match $kernel {
            Kernel::QuadraticBSpline => {
                $method::<QuadraticBSplineKernel, _>($v, $x, $ids $(, $extra)*)
            }
            Kernel::TruncatedGaussian => {
                $method::<TruncatedGaussianKernel, _>($v, $x, $ids $(, $extra)*)
            }
            Kernel::WendlandC2 => $method::<WendlandC2Kernel, _>($v, $x, $ids $(, $extra)*),
        }
    };
}

mod support_lists;

pub use support_lists::SupportLists;

/// The value and gradient of `f` at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValueGradient {
    /// `f(x)`.
    pub value: f64,
    /// `∇f(x)`.
    pub gradient: DVec3,
}

/// The value, gradient and Hessian of `f` at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValueGradientHessian {
    /// `f(x)`.
    pub value: f64,
    /// `∇f(x)`.
    pub gradient: DVec3,
    /// `∇²f(x)` (exactly symmetric).
    pub hessian: DMat3,
}

/// Evaluates the partition-of-unity function of a [`Cover`] with expansion factor σ.
///
/// Built once per cover and σ (it owns a [`BallIndex`] over the expanded balls and a packed
/// copy of the supports); every query takes `&self`, so one evaluator serves many threads. A
/// query returns `None` where no weight is positive (outside every expanded ball), where `f`
/// is undefined, and for a non-finite `x`. The support set at `x` is the open expanded balls,
/// decided by `‖(x − c_i) / (σ r_i)‖² < 1` as computed in floating point (so within a few
/// ulps of a sphere it may differ from `‖x − c_i‖ < σ r_i`, where the weight is negligible
/// anyway): a point on a sphere gets no weight from support `i`.
///
/// The evaluator copies the local functions when it is built; to evaluate after changing
/// them, build a new evaluator on the changed cover.
///
/// With `W = Σ w_i` and `N = Σ w_i g_i`, `f = N / W` where `W > 0`, and by the quotient rule
///
/// ```text
/// ∇f  = (∇N − f ∇W) / W
/// ∇²f = (∇²N − f ∇²W − ∇f ⊗ ∇W − ∇W ⊗ ∇f) / W
/// ```
///
/// with `∇N = Σ (g_i ∇w_i + w_i ∇g_i)` and
/// `∇²N = Σ (g_i ∇²w_i + ∇w_i ⊗ ∇g_i + ∇g_i ⊗ ∇w_i + w_i ∇²g_i)`.
///
/// The expansion factor σ ≥ 1 evaluates each weight with radius `σ r_i` and keeps `g_i`
/// unchanged (σ = 4 for the skeleton's derivatives in the thesis): more supports overlap at
/// each point, which smooths `f` and its derivatives.
///
/// # Determinism
///
/// The sums run over the supports containing `x` in ascending support index, whatever order
/// the spatial index reports them in; batch evaluation treats each point independently. So a
/// result is bit-identical whatever the thread count and whatever the index's internals.
/// Batches are evaluated in a spatially coherent order for cache efficiency and returned in
/// input order; the order changes no result.
#[derive(Debug)]
pub struct PuEvaluator<'a> {
    cover: &'a Cover,
    sigma: f64,
    supports: PackedSupports,
    index: BallIndex,
    /// The longest bounding-box diagonal of a batch block ([`BLOCK_SPAN_PER_RADIUS`] times
    /// the median expanded radius).
    block_span: f64,
}

thread_local! {
    /// Per-thread buffer for the supports at the point being evaluated, so a query allocates
    /// nothing once the buffer has grown to the largest overlap seen.
    static SUPPORT_BUFFER: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
}

impl<'a> PuEvaluator<'a> {
    /// Builds the evaluator of `cover` with expansion factor `sigma` (finite, ≥ 1; 1 is the
    /// plain cover).
    pub fn new(cover: &'a Cover, sigma: f64) -> Result<PuEvaluator<'a>, CoverError> {
        if !(sigma.is_finite() && sigma >= 1.0) {
            return Err(CoverError::InvalidExpansion { sigma });
        }
        let mut expanded = Vec::with_capacity(cover.len());
        for (index, &radius) in cover.radii().iter().enumerate() {
            let r = sigma * radius;
            if !r.is_finite() {
                return Err(CoverError::ExpandedRadiusOverflow {
                    index,
                    radius,
                    sigma,
                });
            }
            expanded.push(r);
        }
        let supports = PackedSupports::new(cover, sigma);
        let index = BallIndex::new(cover.centres(), &expanded);
        let block_span = if expanded.is_empty() {
            0.0
        } else {
            let mid = expanded.len() / 2;
            BLOCK_SPAN_PER_RADIUS * *expanded.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        Ok(PuEvaluator {
            cover,
            sigma,
            supports,
            index,
            block_span,
        })
    }

    /// The cover being evaluated.
    pub fn cover(&self) -> &'a Cover {
        self.cover
    }

    /// The expansion factor σ.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// The spatial index over the expanded balls `(c_i, σ r_i)`.
    pub fn ball_index(&self) -> &BallIndex {
        &self.index
    }

    /// The supports whose expanded ball contains `x` (`‖x − c_i‖ < σ r_i`), ascending, into
    /// `out` (cleared first). These are the supports with a positive weight at `x` (up to
    /// underflow of the weight right at the sphere).
    pub fn supports_containing(&self, x: DVec3, out: &mut Vec<u32>) {
        if !x.is_finite() {
            out.clear();
            return;
        }
        self.index.containing(x, out);
    }

    /// The positive weights `(i, w_i(x))` at `x`, ascending in `i`, into `out` (cleared
    /// first). Dividing by their sum gives the partition-of-unity coefficients at `x`.
    pub fn weights(&self, x: DVec3, out: &mut Vec<(u32, f64)>) {
        out.clear();
        let kernel = self.cover.kernel();
        self.with_supports(x, |ids| {
            for &j in ids {
                let (c, inv_r) = self.supports.centre_inv_radius(j as usize);
                let u = (x - c) * inv_r;
                let w = kernel.value_sq(u.length_squared());
                if w > 0.0 {
                    out.push((j, w));
                }
            }
        });
    }

    /// `f(x)`, or `None` where no weight is positive.
    pub fn value(&self, x: DVec3) -> Option<f64> {
        self.with_supports(x, |ids| dispatch!(self, x, ids, value_sum))
    }

    /// `f(x)` and `∇f(x)`, or `None` where no weight is positive.
    pub fn value_gradient(&self, x: DVec3) -> Option<ValueGradient> {
        self.with_supports(x, |ids| dispatch!(self, x, ids, value_gradient_sum))
    }

    /// `f(x)`, `∇f(x)` and `∇²f(x)`, or `None` where no weight is positive.
    pub fn value_gradient_hessian(&self, x: DVec3) -> Option<ValueGradientHessian> {
        self.with_supports(x, |ids| dispatch!(self, x, ids, value_gradient_hessian_sum))
    }

    /// [`PuEvaluator::value`] at every point, in parallel, in input order.
    pub fn values(&self, points: &[DVec3]) -> Vec<Option<f64>> {
        self.batch(points, |x, ids| dispatch!(self, x, ids, value_sum))
    }

    /// [`PuEvaluator::value_gradient`] at every point, in parallel, in input order.
    pub fn values_gradients(&self, points: &[DVec3]) -> Vec<Option<ValueGradient>> {
        self.batch(points, |x, ids| dispatch!(self, x, ids, value_gradient_sum))
    }

    /// [`PuEvaluator::value_gradient_hessian`] at every point, in parallel, in input order.
    pub fn values_gradients_hessians(&self, points: &[DVec3]) -> Vec<Option<ValueGradientHessian>> {
        self.batch(points, |x, ids| {
            dispatch!(self, x, ids, value_gradient_hessian_sum)
        })
    }

    /// The partition-of-unity blend `Σ w_i(x) v_i / Σ w_i(x)` of one value per support at
    /// every point, in parallel, in input order; `None` where no weight is positive.
    ///
    /// Bitwise equal to summing [`PuEvaluator::weights`] in its ascending order, but the
    /// supports are gathered per block of neighbouring points as in the other batch queries,
    /// which is several times cheaper than one index query per point.
    pub fn blend(&self, points: &[DVec3], values: &[f64]) -> Result<Vec<Option<f64>>, CoverError> {
        if values.len() != self.cover.len() {
            return Err(CoverError::LengthMismatch(LengthMismatch {
                array: "blended values",
                expected: self.cover.len(),
                found: values.len(),
            }));
        }
        Ok(self.batch(points, |x, ids| dispatch!(self, x, ids, blend_sum, values)))
    }

    /// [`PuEvaluator::values_gradients`] and [`PuEvaluator::blend`] of `values` (one per
    /// support) at every point, from one gathering of the supports per block of points
    /// instead of two: `(f, ∇f)` and the blend, each bitwise equal to its own query; `None`
    /// where no weight is positive.
    pub fn values_gradients_blends(
        &self,
        points: &[DVec3],
        values: &[f64],
    ) -> Result<Vec<Option<(ValueGradient, f64)>>, CoverError> {
        if values.len() != self.cover.len() {
            return Err(CoverError::LengthMismatch(LengthMismatch {
                array: "blended values",
                expected: self.cover.len(),
                found: values.len(),
            }));
        }
        Ok(self.batch(points, |x, ids| {
            dispatch!(self, x, ids, value_gradient_blend_sum, values)
        }))
    }

    /// `eval(x, supports at x)` at every point, in parallel, in input order, bitwise equal to
    /// the single-point queries.
    ///
    /// Large batches run in Morton order in blocks of up to [`BLOCK_LEN`] neighbouring points
    /// (see [`BLOCK_SPAN_PER_RADIUS`]), and every point sums over the ascending candidate
    /// list of its run ([`BatchState::near`]). The sums skip the candidates with `s ≥ 1`
    /// (see [`GATHER_SCALE`]), so each point sums over exactly the supports of a
    /// single-point query, in the same order.
    /// This amortises the index traversal, which otherwise dominates the cost, over the
    /// block, and spares a containment pass (a square root per candidate) before the sum.
    fn batch<R: Copy + Send + Sync>(
        &self,
        points: &[DVec3],
        eval: impl Fn(DVec3, &[u32]) -> R + Sync,
    ) -> Vec<R> {
        let Some(plan) = self.plan(points) else {
            return points
                .par_iter()
                .with_min_len(BATCH_MIN_LEN)
                .map(|&x| self.with_supports(x, |ids| eval(x, ids)))
                .collect();
        };
        // One result per position of the plan's order, collected straight into place:
        // collecting per block would go through a list of per-task vectors that one thread
        // then copies into one, faulting in fresh pages while the others wait.
        let in_order: Vec<R> = (0..plan.order.len())
            .into_par_iter()
            .with_min_len(BATCH_MIN_LEN)
            .map_init(BatchState::default, |state, k| {
                let x = points[plan.order[k] as usize];
                eval(x, state.near(self, points, &plan, k))
            })
            .collect();
        in_input_order(&plan.rank(), &in_order)
    }

    /// The Morton order and blocks of a batch (see [`PuEvaluator::batch`]); `None` for a
    /// batch too short to be worth ordering, whose points are queried one by one.
    fn plan(&self, points: &[DVec3]) -> Option<BatchPlan> {
        if points.len() < SPATIAL_ORDER_MIN_LEN || u32::try_from(points.len()).is_err() {
            return None;
        }
        Some(BatchPlan::new(points, BLOCK_LEN, self.block_span))
    }

    /// The candidates (ascending) that may hold one of the finite points `run` in their
    /// expanded ball, into `near` (cleared first), in their order. A candidate is left out
    /// only when `‖(m − c_j) / (σ r_j)‖ ≥ 1 + t / (σ r_j)` (widened by a relative 1e-9 for
    /// rounding), `m` being the centre of the points' bounding box and `t` half its
    /// diagonal: for every point `x` of the box, `‖(x − c_j) / (σ r_j)‖ ≥ 1` then, so its
    /// sum skips the candidate anyway.
    fn candidates_near(
        &self,
        points: &[DVec3],
        run: &[u32],
        candidates: &[u32],
        near: &mut Vec<u32>,
    ) {
        near.clear();
        let mut bounds = Aabb::EMPTY;
        for &i in run {
            let x = points[i as usize];
            if x.is_finite() {
                bounds.add(x);
            }
        }
        let Some((m, reach)) = bounding_sphere(&bounds) else {
            return;
        };
        near.extend(candidates.iter().copied().filter(|&j| {
            let (c, inv_r) = self.supports.centre_inv_radius(j as usize);
            let t = 1.0 + reach * inv_r;
            let d2 = ((m - c) * inv_r).length_squared();
            // A NaN on either side keeps the candidate.
            matches!(
                d2.partial_cmp(&(t * t * (1.0 + 1e-9))),
                Some(std::cmp::Ordering::Less) | None
            )
        }));
    }

    /// Runs `body` on a superset of the supports whose expanded ball holds `x` (none for a
    /// non-finite `x`; see [`GATHER_SCALE`]), sorted ascending, using the thread's reusable
    /// buffer.
    #[inline]
    fn with_supports<R>(&self, x: DVec3, body: impl FnOnce(&[u32]) -> R) -> R {
        let gather = |buf: &mut Vec<u32>| {
            buf.clear();
            // A non-finite point lies in no ball; skipping it also keeps NaN out of the sums,
            // so the loops can test `s >= 1` alone.
            if !x.is_finite() {
                return;
            }
            self.index.extend_within_loose(x, GATHER_SCALE, 0.0, buf);
            buf.sort_unstable();
        };
        SUPPORT_BUFFER.with(|cell| match cell.try_borrow_mut() {
            Ok(mut buf) => {
                gather(&mut buf);
                body(&buf)
            }
            // Only reachable if `body` re-entered the evaluator on this thread; stay correct.
            Err(_) => {
                let mut buf = Vec::new();
                gather(&mut buf);
                body(&buf)
            }
        })
    }
}

/// The supports at `x` are those with `s = ‖(x − c_i) / (σ r_i)‖² < 1`, the test every sum
/// applies. Gathering the balls with `‖x − c_i‖ < GATHER_SCALE · σ r_i` from the index holds
/// all of them (the two tests differ by a few ulps), so single-point and batch queries,
/// which gather differently, sum over the same supports in the same ascending order.
const GATHER_SCALE: f64 = 1.0 + 1e-9;

/// What a task of [`PuEvaluator::batch`] keeps between neighbouring points: the block and
/// the run of its last point, the block's candidate supports and the run's.
#[derive(Default)]
struct BatchState {
    block: Option<usize>,
    run: Option<usize>,
    candidates: Vec<u32>,
    near: Vec<u32>,
}

impl BatchState {
    /// The candidate supports of position `k` of `plan`, ascending: a superset of the
    /// supports whose sums' test `s < 1` holds at the point (none for a non-finite point).
    /// The index is asked once per block for the balls within reach of the block's bounding
    /// sphere (again by a task that starts inside a block), and each run of
    /// [`SUB_BLOCK_LEN`] points keeps those that may reach its own bounding sphere.
    fn near(
        &mut self,
        eval: &PuEvaluator<'_>,
        points: &[DVec3],
        plan: &BatchPlan,
        k: usize,
    ) -> &[u32] {
        let b = plan.block_of[k] as usize;
        let (range, bounds) = &plan.blocks[b];
        if self.block != Some(b) {
            self.block = Some(b);
            self.run = None;
            self.candidates.clear();
            if let Some((centre, reach)) = bounding_sphere(bounds) {
                eval.index
                    .extend_within_loose(centre, GATHER_SCALE, reach, &mut self.candidates);
                self.candidates.sort_unstable();
            }
        }
        let run = (k - range.start) / SUB_BLOCK_LEN;
        if self.run != Some(run) {
            self.run = Some(run);
            let start = range.start + run * SUB_BLOCK_LEN;
            let end = (start + SUB_BLOCK_LEN).min(range.end);
            eval.candidates_near(
                points,
                &plan.order[start..end],
                &self.candidates,
                &mut self.near,
            );
        }
        if points[plan.order[k] as usize].is_finite() {
            &self.near
        } else {
            &[]
        }
    }
}

/// Points per rayon task at least: one point costs about a microsecond, so smaller tasks would
/// spend more on scheduling than on work.
const BATCH_MIN_LEN: usize = 256;

/// Batches at least this long are evaluated in Morton order; below it the sort costs more
/// than the cache misses it saves.
const SPATIAL_ORDER_MIN_LEN: usize = 4096;

/// Neighbouring points (in Morton order) that share one index query in batch evaluation, at
/// most (see [`BLOCK_SPAN_PER_RADIUS`], which closes most blocks earlier).
const BLOCK_LEN: usize = 256;

/// Consecutive points of a block that sum over one list: the block's candidates that may
/// reach them. A block's candidates are several times the supports at any one of its points,
/// and each would cost every point a distance test. On the 362K-point bunny's grid and
/// vertex evaluations, blocks of 256 points in runs of 16 are about a fifth faster than
/// blocks of 16 points without runs, and about a tenth faster than blocks of 64 in runs of 8.
/// Runs of 8 in blocks of 256 sum over fewer candidates still: the whole reconstruction
/// (callgrind, one thread) counts 30.79 G instructions with runs of 16, 30.33 G with 8 and
/// 30.30 G with 4, where filtering the lists begins to cost what it saves.
const SUB_BLOCK_LEN: usize = 8;

/// A batch block's bounding box has a diagonal of at most this many times the cover's median
/// expanded radius. Consecutive points of a scattered set (the support centres of a
/// surface cover: small supports on the surface, large ones in empty space) can span many
/// radii, and then every point of the block sums over the candidates of the whole span: at
/// the 67K centres of the 362K-point bunny's cover, 542 candidates per point with blocks of
/// 16. Closing such blocks early makes the three evaluations at the centres about 40%
/// faster; spans of 2 and 4 radii are as fast, spans of 1.5 radii slower.
const BLOCK_SPAN_PER_RADIUS: f64 = 3.0;

/// [`value_gradient_sum`] and [`blend_sum`] of `values` in one pass over `ids`, each summed
/// exactly as in its own function.
#[inline]
fn value_gradient_blend_sum<K: FixedKernel, S: PackedSupport>(
    supports: &[S],
    x: DVec3,
    ids: &[u32],
    values: &[f64],
) -> Option<(ValueGradient, f64)> {
    let (mut num, mut den) = (0.0, 0.0);
    let vg = value_gradient_sum_visiting::<K, S>(supports, x, ids, |j, w| {
        if w > 0.0 {
            num += w * values[j as usize];
            den += w;
        }
    })?;
    (den > 0.0).then(|| (vg, num / den))
}

/// `a bᵀ + b aᵀ`.
#[inline]
fn sym_outer(a: DVec3, b: DVec3) -> DMat3 {
    let m = outer(a, b);
    m + m.transpose()
}

/// `f` from `Σ w_i` and `Σ w_i g_i` in the order of `ids` (a support outside its ball adds
/// exact zeros, see [`Kernel::value_sq_clamped`]).
#[inline]
fn value_sum<K: FixedKernel, S: PackedSupport>(
    supports: &[S],
    x: DVec3,
    ids: &[u32],
) -> Option<f64> {
    let mut w_sum = 0.0;
    let mut n_sum = 0.0;
    for &j in ids {
        let sup = &supports[j as usize];
        let d = x - sup.centre();
        let u = d * sup.inv_radius();
        let s = u.length_squared();
        let w = K::KERNEL.value_sq_clamped(s);
        w_sum += w;
        n_sum += w * sup.value(d);
    }
    (w_sum > 0.0).then(|| n_sum / w_sum)
}

/// `Σ w_i v_i / Σ w_i` over the listed supports with `s < 1`, in the order of `ids`.
#[inline]
fn blend_sum<K: FixedKernel, S: PackedSupport>(
    supports: &[S],
    x: DVec3,
    ids: &[u32],
    values: &[f64],
) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for &j in ids {
        let sup = &supports[j as usize];
        let u = (x - sup.centre()) * sup.inv_radius();
        let s = u.length_squared();
        if s >= 1.0 {
            continue;
        }
        let w = K::KERNEL.value_sq(s);
        if w > 0.0 {
            num += w * values[j as usize];
            den += w;
        }
    }
    (den > 0.0).then(|| num / den)
}

#[inline]
fn value_gradient_sum<K: FixedKernel, S: PackedSupport>(
    supports: &[S],
    x: DVec3,
    ids: &[u32],
) -> Option<ValueGradient> {
    value_gradient_sum_visiting::<K, S>(supports, x, ids, |_, _| {})
}

/// `f` and `∇f` over `ids`, calling `visit(j, w_j)` for every support summed.
#[inline(always)]
fn value_gradient_sum_visiting<K: FixedKernel, S: PackedSupport>(
    supports: &[S],
    x: DVec3,
    ids: &[u32],
    mut visit: impl FnMut(u32, f64),
) -> Option<ValueGradient> {
    let mut w_sum = 0.0;
    let mut n_sum = 0.0;
    let mut w_grad = DVec3::ZERO;
    let mut n_grad = DVec3::ZERO;
    for &j in ids {
        let sup = &supports[j as usize];
        let inv_r = sup.inv_radius();
        let d = x - sup.centre();
        let u = d * inv_r;
        let s = u.length_squared();
        if s >= 1.0 {
            continue;
        }
        let (w, a) = K::KERNEL.value_slope_sq(s);
        // The expression of `gradient_hessian`, so all paths agree bitwise on ∇f.
        let grad_w = u * (a * inv_r);
        let (g, grad_g) = sup.value_gradient(d);
        w_sum += w;
        n_sum += w * g;
        w_grad += grad_w;
        n_grad += grad_w * g + grad_g * w;
        visit(j, w);
    }
    if w_sum <= 0.0 {
        return None;
    }
    // `f` divides exactly as in `value_sum`, so all query paths agree bitwise on `f`.
    let value = n_sum / w_sum;
    let inv_w = 1.0 / w_sum;
    Some(ValueGradient {
        value,
        gradient: (n_grad - w_grad * value) * inv_w,
    })
}

#[inline]
fn value_gradient_hessian_sum<K: FixedKernel, S: PackedSupport>(
    supports: &[S],
    x: DVec3,
    ids: &[u32],
) -> Option<ValueGradientHessian> {
    let mut w_sum = 0.0;
    let mut n_sum = 0.0;
    let mut w_grad = DVec3::ZERO;
    let mut n_grad = DVec3::ZERO;
    let mut w_hess = DMat3::ZERO;
    let mut n_hess = DMat3::ZERO;
    for &j in ids {
        let sup = &supports[j as usize];
        let inv_r = sup.inv_radius();
        let d = x - sup.centre();
        let u = d * inv_r;
        let s = u.length_squared();
        if s >= 1.0 {
            continue;
        }
        let (w, a, b) = K::KERNEL.value_slope_curvature_sq(s);
        let (grad_w, hess_w) = gradient_hessian(u, inv_r, a, b);
        let (g, grad_g, hess_g) = sup.value_gradient_hessian(d);
        w_sum += w;
        n_sum += w * g;
        w_grad += grad_w;
        n_grad += grad_w * g + grad_g * w;
        w_hess += hess_w;
        n_hess += hess_w * g + sym_outer(grad_w, grad_g);
        if let Some(hess_g) = hess_g {
            n_hess += hess_g * w;
        }
    }
    if w_sum <= 0.0 {
        return None;
    }
    let value = n_sum / w_sum;
    let inv_w = 1.0 / w_sum;
    let gradient = (n_grad - w_grad * value) * inv_w;
    let hessian = (n_hess - w_hess * value - sym_outer(gradient, w_grad)) * inv_w;
    Some(ValueGradientHessian {
        value,
        gradient,
        hessian,
    })
}

/// A kernel fixed at compile time, so the inner loops are monomorphised per kernel and the
/// kernel `match` folds away.
trait FixedKernel {
    const KERNEL: Kernel;
}

struct QuadraticBSplineKernel;
struct TruncatedGaussianKernel;
struct WendlandC2Kernel;

impl FixedKernel for QuadraticBSplineKernel {
    const KERNEL: Kernel = Kernel::QuadraticBSpline;
}
impl FixedKernel for TruncatedGaussianKernel {
    const KERNEL: Kernel = Kernel::TruncatedGaussian;
}
impl FixedKernel for WendlandC2Kernel {
    const KERNEL: Kernel = Kernel::WendlandC2;
}
