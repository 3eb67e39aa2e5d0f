//! The supports at a fixed set of points, gathered once for several evaluations.
//!
//! Finding the supports at a point costs more than summing over them: at the 67K support
//! centres of a 362K-point bunny cover (about 25 supports at each), a batch evaluation of
//! `f` and `∇f` costs about four times the sums alone over stored lists. A reconstruction
//! evaluates at the centres once per stage that changes the local functions (graph cut,
//! every diffusion round) while the balls stay the same, so it gathers the lists once.

use super::packed::PackedSupports;
use super::{
    BATCH_MIN_LEN, BatchState, PuEvaluator, QuadraticBSplineKernel, TruncatedGaussianKernel,
    ValueGradient, WendlandC2Kernel, value_gradient_sum, value_sum,
};
use crate::LengthMismatch;
use crate::concat::concat_in_parallel;
use crate::cover::{Cover, CoverError};
use crate::kernel::Kernel;
use crate::spatial_order::in_input_order;
use glam::DVec3;
use rayon::prelude::*;

/// Positions of a batch whose lists one parallel task gathers. Fixed, so the work split
/// never depends on the pool (the lists themselves do not depend on it either).
const POSITIONS_PER_TASK: usize = 1024;

/// For each of a set of points, the supports of a cover whose expanded balls hold it
/// (`‖(x − c_i) / (σ r_i)‖² < 1`, the test of every [`PuEvaluator`] sum), ascending: built by
/// [`PuEvaluator::support_lists`].
///
/// They depend only on the points, the centres, the radii and σ, so they serve every
/// evaluation of a cover with the same balls and other local functions:
/// [`SupportLists::values`] and [`SupportLists::values_gradients`] give bitwise what the
/// [`PuEvaluator`] of that cover gives at the same points, without searching for the
/// supports again. Both check the balls and the points.
///
/// ```
/// use sphcover_core::{Cover, DVec3, Kernel, LocalFunctions, PuEvaluator};
///
/// let centres = vec![DVec3::ZERO, DVec3::new(0.5, 0.0, 0.0)];
/// let funcs = |beta: f64| LocalFunctions::Linear { alpha: vec![DVec3::X; 2], beta: vec![beta; 2] };
/// let mut cover = Cover::new(centres.clone(), vec![1.0; 2], funcs(0.0), Kernel::QuadraticBSpline)?;
/// let points = [DVec3::new(0.2, 0.1, 0.0), DVec3::new(3.0, 0.0, 0.0)];
/// let lists = PuEvaluator::new(&cover, 1.0)?.support_lists(&points);
/// assert_eq!((lists.supports(0), lists.supports(1)), (&[0, 1][..], &[][..]));
///
/// // New local functions on the same balls: the lists still serve.
/// cover.set_funcs(funcs(1.0))?;
/// let values = lists.values(&cover, &points)?;
/// assert_eq!(values, PuEvaluator::new(&cover, 1.0)?.values(&points));
/// assert_eq!(values[1], None);
/// # Ok::<(), sphcover_core::CoverError>(())
/// ```
#[derive(Clone, Debug)]
pub struct SupportLists {
    sigma: f64,
    /// The balls the lists were gathered from, to refuse a cover with other balls.
    centres: Vec<DVec3>,
    radii: Vec<f64>,
    /// The points, in input order.
    points: Vec<DVec3>,
    /// Evaluation order (Morton order for large batches): `order[k]` is the point at
    /// position `k`, `rank[i]` the position of point `i`. Both empty when positions are
    /// input indices.
    order: Vec<u32>,
    rank: Vec<u32>,
    /// The list of position `k` is `ids[offsets[k]..offsets[k + 1]]`.
    offsets: Vec<usize>,
    ids: Vec<u32>,
}

impl PuEvaluator<'_> {
    /// The supports at each of `points` (see [`SupportLists`]), gathered in parallel as
    /// the batch evaluations gather them.
    pub fn support_lists(&self, points: &[DVec3]) -> SupportLists {
        let plan = self.plan(points);
        let position_count = points.len();
        let tasks: Vec<(Vec<u32>, Vec<u32>)> = (0..position_count.div_ceil(POSITIONS_PER_TASK))
            .into_par_iter()
            .map_init(
                || (BatchState::default(), Vec::new()),
                |(state, single), task| {
                    let positions = task * POSITIONS_PER_TASK
                        ..((task + 1) * POSITIONS_PER_TASK).min(position_count);
                    let mut counts = Vec::with_capacity(positions.len());
                    let mut ids = Vec::new();
                    for k in positions {
                        let (x, candidates) = match &plan {
                            Some(plan) => {
                                let x = points[plan.order[k] as usize];
                                (x, state.near(self, points, plan, k))
                            }
                            None => {
                                let x = points[k];
                                self.with_supports(x, |found| {
                                    single.clear();
                                    single.extend_from_slice(found);
                                });
                                (x, &single[..])
                            }
                        };
                        // Every candidate is written and kept on a hit: whether a candidate's
                        // ball holds the point follows no pattern a branch could predict.
                        let before = ids.len();
                        ids.resize(before + candidates.len(), 0);
                        let out = &mut ids[before..];
                        let mut hits = 0;
                        for &j in candidates {
                            let (c, inv_r) = self.supports.centre_inv_radius(j as usize);
                            out[hits] = j;
                            hits += usize::from(((x - c) * inv_r).length_squared() < 1.0);
                        }
                        ids.truncate(before + hits);
                        counts.push(hits as u32);
                    }
                    (counts, ids)
                },
            )
            .collect();
        let mut offsets = Vec::with_capacity(position_count + 1);
        let mut total = 0usize;
        offsets.push(0);
        for (counts, _) in &tasks {
            for &c in counts {
                total += c as usize;
                offsets.push(total);
            }
        }
        let parts: Vec<&[u32]> = tasks.iter().map(|(_, ids)| &ids[..]).collect();
        let ids = concat_in_parallel(&parts);
        let (order, rank) = match plan {
            Some(plan) => {
                let rank = plan.rank();
                (plan.order, rank)
            }
            None => (Vec::new(), Vec::new()),
        };
        SupportLists {
            sigma: self.sigma,
            centres: self.cover.centres().to_vec(),
            radii: self.cover.radii().to_vec(),
            points: points.to_vec(),
            order,
            rank,
            offsets,
            ids,
        }
    }
}

impl SupportLists {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The supports at point `i` (input order), ascending. Panics when `i ≥ len()`, like
    /// slice indexing.
    pub fn supports(&self, i: usize) -> &[u32] {
        let k = if self.rank.is_empty() {
            i
        } else {
            self.rank[i] as usize
        };
        &self.ids[self.offsets[k]..self.offsets[k + 1]]
    }

    /// [`PuEvaluator::values`] of `cover` at `points`: `f`, or `None` where no weight is
    /// positive. Fails unless `cover` has the balls and `points` are the points the lists
    /// were gathered for.
    pub fn values(&self, cover: &Cover, points: &[DVec3]) -> Result<Vec<Option<f64>>, CoverError> {
        self.evaluate(cover, points, |supports, x, ids| {
            dispatch_packed!(supports, cover.kernel(), x, ids, value_sum)
        })
    }

    /// [`PuEvaluator::values_gradients`] of `cover` at `points`: `f` and `∇f`, or `None`
    /// where no weight is positive. Fails unless `cover` has the balls and `points` are the
    /// points the lists were gathered for.
    pub fn values_gradients(
        &self,
        cover: &Cover,
        points: &[DVec3],
    ) -> Result<Vec<Option<ValueGradient>>, CoverError> {
        self.evaluate(cover, points, |supports, x, ids| {
            dispatch_packed!(supports, cover.kernel(), x, ids, value_gradient_sum)
        })
    }

    /// `eval(packed supports, x, supports at x)` at every point, in input order.
    fn evaluate<R: Copy + Send + Sync>(
        &self,
        cover: &Cover,
        points: &[DVec3],
        eval: impl Fn(&PackedSupports, DVec3, &[u32]) -> R + Sync,
    ) -> Result<Vec<R>, CoverError> {
        self.check(cover, points)?;
        // Packed as the evaluator packs them, so the sums agree bitwise.
        let supports = PackedSupports::new(cover, self.sigma);
        let by_position: Vec<R> = (0..self.points.len())
            .into_par_iter()
            .with_min_len(BATCH_MIN_LEN)
            .map(|k| {
                let x = match self.order.get(k) {
                    Some(&i) => self.points[i as usize],
                    None => self.points[k],
                };
                eval(
                    &supports,
                    x,
                    &self.ids[self.offsets[k]..self.offsets[k + 1]],
                )
            })
            .collect();
        Ok(if self.rank.is_empty() {
            by_position
        } else {
            in_input_order(&self.rank, &by_position)
        })
    }

    /// `cover` has the balls and `points` are the points the lists were gathered for (bit
    /// for bit).
    fn check(&self, cover: &Cover, points: &[DVec3]) -> Result<(), CoverError> {
        for (array, expected, found) in [
            (
                "supports of the support lists",
                cover.len(),
                self.centres.len(),
            ),
            (
                "points of the support lists",
                points.len(),
                self.points.len(),
            ),
        ] {
            if expected != found {
                return Err(CoverError::LengthMismatch(LengthMismatch {
                    array,
                    expected,
                    found,
                }));
            }
        }
        let bits = |v: DVec3| v.to_array().map(f64::to_bits);
        let other_ball = |i: usize| {
            bits(cover.centres()[i]) != bits(self.centres[i])
                || cover.radii()[i].to_bits() != self.radii[i].to_bits()
        };
        if let Some(index) = (0..cover.len())
            .into_par_iter()
            .find_first(|&i| other_ball(i))
        {
            return Err(CoverError::OtherBalls { index });
        }
        let other_point = |i: usize| bits(points[i]) != bits(self.points[i]);
        match (0..points.len())
            .into_par_iter()
            .find_first(|&i| other_point(i))
        {
            Some(index) => Err(CoverError::OtherPoints { index }),
            None => Ok(()),
        }
    }
}
