//! The samples inside each support's ball, gathered once for several passes over them.
//!
//! The method is described on [`SupportSamples`].

use crate::LengthMismatch;
use crate::cover::{Cover, CoverError};
use crate::kernel::Kernel;
use crate::point_index::PointIndex;
use rayon::prelude::*;

/// The stored balls exceed the supports' by this relative margin, far above the rounding
/// that separates the two ball tests (`‖p − c‖² < r²` and `‖(p − c) / r‖² < 1`).
const MARGIN: f64 = 1e-9;

/// Supports gathered by one parallel task into a list of their own.
const GATHER_BLOCK: usize = 256;
/// Supports gathered (in blocks, in parallel) while the previous ones are appended.
const GATHER_RUN: usize = 16 * GATHER_BLOCK;

/// Per support of a cover, the slots of a [`PointIndex`] in (a hair more than) its ball, as
/// one compressed row list.
///
/// The rows hold no reference to the cover or the index they were gathered from, so a
/// pipeline can keep them beside both (and change the cover's local functions, which the
/// rows do not depend on); every method takes the two again and checks their sizes.
///
/// A reconstruction visits the samples of every support several times: the support
/// confidence (thesis eq. 5.38) takes their principal axes, the sample confidence
/// (eq. 5.39–5.40) blends the support confidences at every sample, and the fitting terms of
/// the diffusion (eq. 5.33) sum over them again. Each of those would otherwise ask the point
/// index (or, for the blend, the index over the balls) for the same incidences.
/// [`SupportSamples`] asks once and keeps, per support, the slots of the point index inside
/// a ball a hair larger than the support's (so that every test below is a filter of the
/// stored slots):
///
/// * [`SupportSamples::for_each_slot_within`] reports exactly what
///   [`PointIndex::for_each_slot_within`] reports for the support's ball: the same slots in
///   the same order with the same squared distances, so sums over them keep their bits;
/// * [`SupportSamples::blend`] is the partition-of-unity blend of one value per support at
///   every indexed point, bitwise equal to [`crate::PuEvaluator::blend`] with σ = 1. Its
///   sums run over the supports in ascending index as the evaluator's do, but they are
///   scattered from the supports to their samples, so no point has to look its supports up.
///
/// A surface cover's build can give them too ([`crate::build_surface_cover_with_samples`]):
/// most of its supports' fits gathered these very points, so their rows need no query.
///
/// The slots cost 4 bytes per incidence: about 34 MB for the 362K-point bunny's 8.5 million.
///
/// # Example
///
/// ```
/// use sphcover_core::{Cover, DVec3, Kernel, LocalFunctions, PointIndex, PuEvaluator, SupportSamples};
///
/// let points: Vec<DVec3> = (0..200).map(|i| DVec3::new(i as f64 * 0.01, 0.0, 0.0)).collect();
/// let index = PointIndex::new(&points)?;
/// let cover = Cover::new(
///     vec![DVec3::new(0.5, 0.0, 0.0), DVec3::new(1.5, 0.0, 0.0)],
///     vec![0.6, 0.6],
///     LocalFunctions::zero_linear(2),
///     Kernel::QuadraticBSpline,
/// )?;
/// let incidence = SupportSamples::gather(&cover, &index);
///
/// let mut inside = 0;
/// incidence.for_each_slot_within(&cover, &index, 0, |_slot, d2| {
///     assert!(d2 < 0.36);
///     inside += 1;
/// });
/// assert_eq!(inside, 110); // x = 0, 0.01, …, 1.09
///
/// // The blend equals the evaluator's, bit for bit.
/// let values = [1.0, 3.0];
/// let blended = incidence.blend(&cover, &index, &values)?;
/// let reference = PuEvaluator::new(&cover, 1.0)?.blend(&points, &values)?;
/// assert_eq!(blended, reference);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct SupportSamples {
    /// Points of the index the rows were gathered from.
    indexed: usize,
    /// Support `i`'s slots are `slots[offsets[i]..offsets[i + 1]]`.
    offsets: Vec<usize>,
    /// One list, not a vector per support: a large allocation goes back to the system when
    /// it is freed, where the support-sized pieces of the same bytes (34 MB for the
    /// 362K-point bunny, 280 MB for 3M points) would stay in the allocator, beside the later
    /// stages' large buffers.
    slots: Vec<u32>,
}

impl SupportSamples {
    /// Gathers the samples of every support of `cover` from `index`, in parallel. The result
    /// does not depend on the thread count.
    pub fn gather(cover: &Cover, index: &PointIndex) -> SupportSamples {
        // Runs of supports are gathered in parallel, block by block, while the previous run
        // is appended to the one list: the appending (a copy, and the first touch of the
        // list's memory) holds one thread, and the run being gathered keeps the other busy.
        // Only two runs' blocks are alive at a time, so the list is the only large
        // allocation, as if each support's row were appended in turn.
        let n = cover.len();
        let gather_run = |run: std::ops::Range<usize>| -> Vec<(Vec<u32>, Vec<u32>)> {
            cover.centres()[run.clone()]
                .par_chunks(GATHER_BLOCK)
                .zip(cover.radii()[run].par_chunks(GATHER_BLOCK))
                .map(|(centres, radii)| {
                    let mut lengths = Vec::with_capacity(centres.len());
                    let mut slots = Vec::new();
                    for (&c, &r) in centres.iter().zip(radii) {
                        let before = slots.len();
                        index.extend_within(c, Self::ball_radius(r), &mut slots, None);
                        lengths.push((slots.len() - before) as u32);
                    }
                    (lengths, slots)
                })
                .collect()
        };
        let mut runs = (0..n)
            .step_by(GATHER_RUN)
            .map(|s| s..(s + GATHER_RUN).min(n));
        let mut pending = runs.next().map(&gather_run);
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        let mut slots: Vec<u32> = Vec::new();
        if let Some(first) = &pending {
            // Room for a tenth more than the first run's rate predicts, so that the list
            // is rarely copied as it grows (room never written is never touched).
            let rate =
                first.iter().map(|(_, b)| b.len()).sum::<usize>() as f64 / GATHER_RUN.min(n) as f64;
            slots.reserve((1.1 * rate * n as f64) as usize);
        }
        let mut append = |blocks: Vec<(Vec<u32>, Vec<u32>)>| {
            for (lengths, block) in blocks {
                for len in lengths {
                    offsets.push(offsets[offsets.len() - 1] + len as usize);
                }
                slots.extend_from_slice(&block);
            }
        };
        while let Some(blocks) = pending.take() {
            let next = runs.next();
            pending = rayon::join(|| append(blocks), || next.map(&gather_run)).1;
        }
        SupportSamples {
            indexed: index.len(),
            offsets,
            slots,
        }
    }

    /// [`SupportSamples::gather`] with the rows given in `rows` (support `i`'s, when given,
    /// must be what the gather would find: the slots inside the ball of radius
    /// [`SupportSamples::ball_radius`], in tree order); the others are gathered. The rows are
    /// copied into the one list in parallel, each into its place.
    pub(crate) fn from_rows(
        cover: &Cover,
        index: &PointIndex,
        mut rows: Vec<Option<Vec<u32>>>,
    ) -> SupportSamples {
        let n = cover.len();
        rows.resize(n, None);
        rows.par_iter_mut()
            .enumerate()
            .with_min_len(GATHER_BLOCK)
            .filter(|(_, row)| row.is_none())
            .for_each(|(i, row)| {
                let mut slots = Vec::new();
                let (c, r) = (cover.centres()[i], cover.radii()[i]);
                index.extend_within(c, Self::ball_radius(r), &mut slots, None);
                *row = Some(slots);
            });
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        for row in &rows {
            offsets.push(offsets[offsets.len() - 1] + row.as_ref().map_or(0, Vec::len));
        }
        // Zeroed pages are mapped as they are first written, by the threads that copy.
        let mut slots = vec![0u32; offsets[n]];
        let mut places = Vec::with_capacity(n.div_ceil(GATHER_BLOCK));
        let mut rest = &mut slots[..];
        for start in (0..n).step_by(GATHER_BLOCK) {
            let end = (start + GATHER_BLOCK).min(n);
            let (place, tail) = rest.split_at_mut(offsets[end] - offsets[start]);
            places.push(place);
            rest = tail;
        }
        rows.par_chunks(GATHER_BLOCK)
            .zip(places)
            .for_each(|(rows, place)| {
                let mut at = 0;
                for row in rows.iter().flatten() {
                    place[at..at + row.len()].copy_from_slice(row);
                    at += row.len();
                }
            });
        SupportSamples {
            indexed: index.len(),
            offsets,
            slots,
        }
    }

    /// The radius of the ball whose slots are stored for a support of radius `r`.
    pub(crate) fn ball_radius(r: f64) -> f64 {
        r * (1.0 + MARGIN)
    }

    /// The stored slots of support `i`.
    fn row(&self, i: usize) -> &[u32] {
        &self.slots[self.offsets[i]..self.offsets[i + 1]]
    }

    /// Number of supports the rows were gathered for.
    pub fn supports(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Whether `cover` and `index` have the sizes of the ones the rows were gathered from.
    pub fn fits(&self, cover: &Cover, index: &PointIndex) -> bool {
        cover.len() == self.supports() && index.len() == self.indexed
    }

    /// Panics unless [`SupportSamples::fits`]: rows read against another cover or index
    /// would name wrong points.
    fn assert_fits(&self, cover: &Cover, index: &PointIndex) {
        assert!(
            self.fits(cover, index),
            "support samples gathered for {} supports and {} points, used with {} and {}",
            self.supports(),
            self.indexed,
            cover.len(),
            index.len()
        );
    }

    /// Number of stored incidences (a few more than the supports' balls hold).
    pub fn incidences(&self) -> usize {
        self.slots.len()
    }

    /// Calls `visit(slot, distance²)` for every indexed point inside the ball of support `i`,
    /// exactly as [`PointIndex::for_each_slot_within`] does for that ball: the same slots, in
    /// the same order, with the same squared distances.
    ///
    /// # Panics
    ///
    /// When `i` is not a support of the cover, or `cover` and `index` are not the ones the
    /// rows were gathered from ([`SupportSamples::fits`]).
    pub fn for_each_slot_within(
        &self,
        cover: &Cover,
        index: &PointIndex,
        i: usize,
        mut visit: impl FnMut(usize, f64),
    ) {
        self.assert_fits(cover, index);
        let c = cover.centres()[i];
        let r = cover.radii()[i];
        if r.is_nan() || r <= 0.0 {
            return;
        }
        let r2 = r * r;
        let points = index.slot_points();
        // The larger ball's query visits the tree in the same order (the near child first,
        // chosen by the centre alone), so the slots inside the support's ball keep theirs.
        for &s in self.row(i) {
            let s = s as usize;
            let d2 = (points[s] - c).length_squared();
            if d2 < r2 {
                visit(s, d2);
            }
        }
    }

    /// The partition-of-unity blend `Σ_i w_i(p) v_i / Σ_i w_i(p)` of one value per support
    /// at every point `p` of the index, in the index's input order; `None` where no weight
    /// is positive (and for the points the index leaves out, the non-finite ones). Bitwise
    /// equal to [`crate::PuEvaluator::blend`] of the cover with σ = 1 at the indexed points.
    ///
    /// # Panics
    ///
    /// When `cover` and `index` are not the ones the rows were gathered from
    /// ([`SupportSamples::fits`]).
    pub fn blend(
        &self,
        cover: &Cover,
        index: &PointIndex,
        values: &[f64],
    ) -> Result<Vec<Option<f64>>, CoverError> {
        if values.len() != cover.len() {
            return Err(CoverError::LengthMismatch(LengthMismatch {
                array: "blended values",
                expected: cover.len(),
                found: values.len(),
            }));
        }
        self.assert_fits(cover, index);
        let by_slot = match cover.kernel() {
            Kernel::QuadraticBSpline => self.blend_by_slot(cover, index, values, |s| {
                Kernel::QuadraticBSpline.value_sq(s)
            }),
            Kernel::TruncatedGaussian => self.blend_by_slot(cover, index, values, |s| {
                Kernel::TruncatedGaussian.value_sq(s)
            }),
            Kernel::WendlandC2 => {
                self.blend_by_slot(cover, index, values, |s| Kernel::WendlandC2.value_sq(s))
            }
        };
        let mut out = vec![None; index.input_len()];
        for (&i, (num, den)) in index.order().iter().zip(by_slot) {
            out[i as usize] = (den > 0.0).then(|| num / den);
        }
        Ok(out)
    }

    /// `(Σ w v, Σ w)` per slot. Each slot's sums take the supports in ascending index, like
    /// the evaluator's, with its arithmetic (`u = (p − c)·(1/r)`, skip `‖u‖² ≥ 1`, sum
    /// `w > 0`). The slots are split into ranges, one per thread; each thread walks every
    /// support and keeps the slots of its range, so no sum depends on the split.
    fn blend_by_slot(
        &self,
        cover: &Cover,
        index: &PointIndex,
        values: &[f64],
        kernel: impl Fn(f64) -> f64 + Sync,
    ) -> Vec<(f64, f64)> {
        let n = index.len();
        let parts = rayon::current_num_threads().clamp(1, n.max(1));
        let points = index.slot_points();
        let centres = cover.centres();
        let radii = cover.radii();
        let mut sums = vec![(0.0, 0.0); n];
        let part_len = n.div_ceil(parts).max(1);
        sums.par_chunks_mut(part_len)
            .enumerate()
            .for_each(|(part, sums)| {
                let lo = part * part_len;
                let hi = lo + sums.len();
                for i in 0..cover.len() {
                    let (c, inv_r) = (centres[i], 1.0 / radii[i]);
                    let v = values[i];
                    for &s in self.row(i) {
                        let s = s as usize;
                        if s < lo || s >= hi {
                            continue;
                        }
                        let u = (points[s] - c) * inv_r;
                        let q = u.length_squared();
                        if q >= 1.0 {
                            continue;
                        }
                        let w = kernel(q);
                        if w > 0.0 {
                            let sum = &mut sums[s - lo];
                            sum.0 += w * v;
                            sum.1 += w;
                        }
                    }
                }
            });
        sums
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PuEvaluator;
    use crate::local_function::LocalFunctions;
    use glam::DVec3;
    use proptest::prelude::*;

    fn cloud() -> impl Strategy<Value = Vec<DVec3>> {
        prop::collection::vec((-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0), 0..300)
            .prop_map(|v| v.into_iter().map(|(x, y, z)| DVec3::new(x, y, z)).collect())
    }

    fn balls() -> impl Strategy<Value = Vec<(DVec3, f64, f64)>> {
        prop::collection::vec(
            (
                (-1.2f64..1.2, -1.2f64..1.2, -1.2f64..1.2),
                0.01f64..0.8,
                -1.0f64..1.0,
            ),
            1..60,
        )
        .prop_map(|v| {
            v.into_iter()
                .map(|((x, y, z), r, value)| (DVec3::new(x, y, z), r, value))
                .collect()
        })
    }

    proptest! {
        /// The stored incidences filter to exactly the range query of each ball, and the
        /// scattered blend is the evaluator's, bit for bit, for every kernel; with points on
        /// the spheres (the ball tests disagree there within rounding) and a duplicate.
        #[test]
        fn incidences_and_blend_match_the_direct_queries(
            mut points in cloud(),
            balls in balls(),
            kernel in prop::sample::select(vec![
                Kernel::QuadraticBSpline,
                Kernel::TruncatedGaussian,
                Kernel::WendlandC2,
            ]),
        ) {
            for &(c, r, _) in balls.iter().take(10) {
                points.push(c + DVec3::new(r, 0.0, 0.0));
                points.push(c + DVec3::new(0.0, r, 0.0) * (1.0 - f64::EPSILON));
            }
            if let Some(&p) = points.first() {
                points.push(p);
            }
            points.push(DVec3::new(f64::NAN, 0.0, 0.0));
            let index = PointIndex::new(&points).unwrap();
            let cover = Cover::new(
                balls.iter().map(|b| b.0).collect(),
                balls.iter().map(|b| b.1).collect(),
                LocalFunctions::zero_linear(balls.len()),
                kernel,
            )
            .unwrap();
            let incidence = SupportSamples::gather(&cover, &index);
            for (i, &(c, r, _)) in balls.iter().enumerate() {
                let mut direct = Vec::new();
                index.for_each_slot_within(c, r, |s, d2| direct.push((s, d2.to_bits())));
                let mut stored = Vec::new();
                incidence.for_each_slot_within(&cover, &index, i, |s, d2| stored.push((s, d2.to_bits())));
                prop_assert_eq!(stored, direct);
            }
            let values: Vec<f64> = balls.iter().map(|b| b.2).collect();
            let blended = incidence.blend(&cover, &index, &values).unwrap();
            let reference = PuEvaluator::new(&cover, 1.0).unwrap().blend(&points, &values).unwrap();
            let bits = |v: &[Option<f64>]| v.iter().map(|x| x.map(f64::to_bits)).collect::<Vec<_>>();
            prop_assert_eq!(bits(&blended), bits(&reference));
        }
    }

    #[test]
    fn rows_stay_in_order_across_gather_blocks_and_runs() {
        // More supports than two gather runs hold, some of them empty.
        let points: Vec<DVec3> = (0..2000)
            .map(|i| {
                let t = i as f64 * 0.618_033_988_75;
                DVec3::new(t.fract(), (t * 7.0).fract(), (t * 13.0).fract())
            })
            .collect();
        let index = PointIndex::new(&points).unwrap();
        let n = 2 * GATHER_RUN + 3 * GATHER_BLOCK + 17;
        let centres: Vec<DVec3> = (0..n)
            .map(|i| {
                let t = i as f64 * 0.414_213_562_37;
                DVec3::new(t.fract(), (t * 3.0).fract(), (t * 5.0).fract() * 1.5)
            })
            .collect();
        let radii: Vec<f64> = (0..n)
            .map(|i| 0.02 + 0.1 * ((i % 7) as f64 / 7.0))
            .collect();
        let cover = Cover::new(
            centres.clone(),
            radii.clone(),
            LocalFunctions::zero_linear(n),
            Kernel::QuadraticBSpline,
        )
        .unwrap();
        let incidence = SupportSamples::gather(&cover, &index);
        let mut total = 0;
        for i in 0..n {
            let mut direct = Vec::new();
            index.for_each_slot_within(centres[i], radii[i], |s, d2| direct.push((s, d2)));
            let mut stored = Vec::new();
            incidence.for_each_slot_within(&cover, &index, i, |s, d2| stored.push((s, d2)));
            assert_eq!(stored, direct, "support {i}");
            total += direct.len();
        }
        assert!(total > n, "{total}");
        assert!(incidence.incidences() >= total);
    }

    #[test]
    fn blend_refuses_a_value_count_other_than_the_supports() {
        let points = [DVec3::ZERO];
        let index = PointIndex::new(&points).unwrap();
        let cover = Cover::new(
            vec![DVec3::ZERO],
            vec![1.0],
            LocalFunctions::zero_linear(1),
            Kernel::QuadraticBSpline,
        )
        .unwrap();
        let incidence = SupportSamples::gather(&cover, &index);
        assert!(matches!(
            incidence.blend(&cover, &index, &[1.0, 2.0]),
            Err(CoverError::LengthMismatch(LengthMismatch {
                expected: 1,
                found: 2,
                ..
            }))
        ));
        assert_eq!(
            incidence.blend(&cover, &index, &[0.5]).unwrap(),
            vec![Some(0.5)]
        );
        assert_eq!(incidence.incidences(), 1);
        assert!(incidence.fits(&cover, &index));
        let other = PointIndex::new(&[DVec3::ZERO, DVec3::ONE]).unwrap();
        assert!(!incidence.fits(&cover, &other));
    }

    #[test]
    #[should_panic(expected = "support samples gathered for 1 supports and 1 points")]
    fn rows_refuse_another_index() {
        let index = PointIndex::new(&[DVec3::ZERO]).unwrap();
        let cover = Cover::new(
            vec![DVec3::ZERO],
            vec![1.0],
            LocalFunctions::zero_linear(1),
            Kernel::QuadraticBSpline,
        )
        .unwrap();
        let incidence = SupportSamples::gather(&cover, &index);
        let other = PointIndex::new(&[DVec3::ZERO, DVec3::ONE]).unwrap();
        incidence.for_each_slot_within(&cover, &other, 0, |_, _| {});
    }
}
