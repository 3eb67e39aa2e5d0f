//! The volume cover of scattered samples with values (beyond thesis §3.4.2: samples off any
//! grid, which the thesis names as an advantage over image methods).
//!
//! The method is described on [`build_scattered_cover()`].

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::covering::shuffle;
use super::fit::{LINEAR, NormalEquations, QUADRATIC};
use super::radii::radius_cap;
use super::support::{Support, supports_to_cover};
use super::{
    Threshold, VolumeCoverError, VolumeCoverParams, VolumeCoverStats, VolumeCoverVariant,
    check_params,
};
use crate::cover::Cover;
use crate::point_index::PointIndex;

/// Builds a cover of scattered samples `positions[j]` with values `values[j]` (thesis §3.4.2 with
/// samples off any grid): the object is where the value exceeds the threshold, and every
/// object sample ends strictly inside a support whose local function fits the normalised
/// values of the samples in its ball with an RMS error of at most ε where the sampling
/// allows it. See the module documentation of `volume_cover::scattered` for what differs
/// from [`build_volume_cover`](super::build_volume_cover).
///
/// Values are normalised to `[0, 1]` over their range, as for a volume; positions are in
/// world units, and so are the radii and the cover. Every position and value must be
/// finite.
///
/// ```
/// use sphcover_core::{DVec3, VolumeCoverParams, Threshold, build_scattered_cover};
///
/// // Jittered samples of a ball's indicator blurred into a smooth ramp.
/// let mut positions = Vec::new();
/// let mut values = Vec::new();
/// let mut state = 1u64;
/// let mut jitter = || {
///     state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
///     ((state >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 0.3
/// };
/// for k in 0..12 {
///     for j in 0..12 {
///         for i in 0..12 {
///             let p = DVec3::new(i as f64 + jitter(), j as f64 + jitter(), k as f64 + jitter());
///             let d = p.distance(DVec3::splat(5.5));
///             positions.push(p);
///             values.push(1.0 / (1.0 + (d - 4.0).exp()));
///         }
///     }
/// }
/// let params = VolumeCoverParams { threshold: Threshold::Raw(0.5), ..Default::default() };
/// let (cover, stats) = build_scattered_cover(&positions, &values, &params).unwrap();
/// assert!(cover.len() > 0 && cover.len() < stats.object_points);
/// ```
///
/// The algorithm is the one of the grid builder ([`super::build_volume_cover`]): the same
/// quadratic (or linear) least-squares fits in centred, scaled coordinates, the same RMS
/// error, the same shell-wise gallop and bisection of the radius in `[r_min, r_max]`, the
/// same seeded candidate order and speculative parallel fits. What changes is how samples
/// are found and three quantities the grid gives for free:
///
/// * **Neighbours** come from a k-d tree ([`PointIndex`]) instead of lattice offsets. A fit
///   gathers the samples around its centre lazily, sorted by `(distance², index)`, growing
///   the query radius by factors of 2 up to `r_max` only when the radius search needs more;
///   shells are runs of samples at equal distance (within a relative 1e-9), as on the grid.
/// * **Spacing `h`** (the grid's voxel diagonal): `√3 ×` the median nearest-neighbour
///   distance, which is the voxel diagonal for the centres of a cubic grid. It is the
///   default `r_min` and the unit of [`VolumeCoverParams::max_radius_voxels`].
/// * **`r_max`** (the grid's distance transform): twice the largest distance from an object
///   sample to its nearest background sample (exact, by a k-d tree over the background
///   samples); for the centres of a grid this is the grid builder's figure.
/// * **Covering rule** (thesis Fig. 3.12): with `S` the object samples in the new ball (all
///   samples for the linear variant), an uncovered point `p` of `S` stays a candidate when
///   no point of `S` lies farther than `p` along the ray from the centre through `p`
///   (`max_{q∈S} u·(q − c) ≤ ‖p − c‖`, `u` the ray's direction): such a `p` is on the
///   boundary of the hull of `S`, extreme in its own direction. Every other point of `S` is
///   marked covered. This replaces the grid's midpoint test, which needs a lattice; it keeps
///   the thesis' intent (the outermost points of the ball stay candidates, so the next balls
///   overlap it) at `O(|S|)` expected work per point. Every point of `S` lies strictly
///   inside the ball (its distance is at most the accepted shell's, below the radius), so
///   marking a point covered never leaves a gap, whatever the test decides.
pub fn build_scattered_cover(
    positions: &[DVec3],
    values: &[f64],
    params: &VolumeCoverParams,
) -> Result<(Cover, VolumeCoverStats), VolumeCoverError> {
    let n = positions.len();
    if values.len() != n {
        return Err(VolumeCoverError::SampleCountMismatch {
            positions: n,
            values: values.len(),
        });
    }
    if n < 2 {
        return Err(VolumeCoverError::TooFewSamples { count: n });
    }
    if u32::try_from(n).is_err() {
        return Err(VolumeCoverError::TooManyVoxels { voxels: n });
    }
    check_params(params)?;
    if let Some(index) = positions.iter().position(|p| !p.is_finite()) {
        return Err(VolumeCoverError::NonFiniteSample {
            index,
            what: "position",
        });
    }
    if let Some(index) = values.iter().position(|v| !v.is_finite()) {
        return Err(VolumeCoverError::NonFiniteSample {
            index,
            what: "value",
        });
    }
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if lo == hi {
        return Err(VolumeCoverError::ConstantVolume { value: lo });
    }
    let threshold = match params.threshold {
        Threshold::Raw(t) => t,
        Threshold::Normalised(t) => lo + t * (hi - lo),
    };
    let object: Vec<bool> = values.iter().map(|&v| v > threshold).collect();
    let object_points = object.iter().filter(|&&o| o).count();
    if object_points == 0 {
        return Err(VolumeCoverError::NoObjectPoint {
            threshold,
            min: lo,
            max: hi,
        });
    }
    let start = Instant::now();
    let index = PointIndex::new(positions).expect("count checked above");
    let spacing = sample_spacing(&index, positions)?;
    let r_min = params.r_min.unwrap_or(spacing);
    let (r_max, thickness) = radius_cap(
        params,
        r_min,
        spacing,
        || max_thickness(positions, &object),
        || bounding_diagonal(positions),
    )?;
    let time_distance_transform = start.elapsed();

    let start = Instant::now();
    let samples = Samples {
        positions,
        values: values.iter().map(|&v| (v - lo) / (hi - lo)).collect(),
        object: &object,
        index: &index,
        unit: spacing,
        r_min,
        r_max,
        tolerance: params.tolerance,
        min_samples: params.min_samples,
        bounding_box: params.variant == VolumeCoverVariant::BoundingBoxLinear,
    };
    let mut stats = VolumeCoverStats {
        value_range: (lo, hi),
        threshold_normalised: (threshold - lo) / (hi - lo),
        object_points,
        r_min,
        r_max,
        thickness,
        sample_spacing: spacing,
        time_distance_transform,
        ..VolumeCoverStats::default()
    };
    let supports = match params.variant {
        VolumeCoverVariant::ObjectQuadratic => samples.cover::<QUADRATIC>(params, &mut stats),
        VolumeCoverVariant::BoundingBoxLinear => samples.cover::<LINEAR>(params, &mut stats),
    };
    let centres: Vec<DVec3> = supports
        .iter()
        .map(|s| positions[s.centre as usize])
        .collect();
    let cover = supports_to_cover(&supports, centres, params, &mut stats)?;
    stats.time_cover = start.elapsed();
    Ok((cover, stats))
}

/// `√3 ×` the median distance from a sample to its nearest other sample.
fn sample_spacing(index: &PointIndex, positions: &[DVec3]) -> Result<f64, VolumeCoverError> {
    // `None`: more than half the samples coincide with another one.
    let median =
        median_nearest_distance(index, positions).ok_or(VolumeCoverError::CoincidentSamples)?;
    Ok(3f64.sqrt() * median)
}

/// The median over `positions` of the distance to the nearest other indexed point (the
/// voxel edge of the equivalent grid for scattered samples); `None` when it is zero or not
/// finite (more than half the points coincide with another, or fewer than two points).
pub fn median_nearest_distance(index: &PointIndex, positions: &[DVec3]) -> Option<f64> {
    let mut nearest: Vec<f64> = positions
        .par_iter()
        .map_init(Vec::new, |out, &p| {
            index.nearest_k_with_distances(p, 2, out);
            out.get(1).map_or(f64::INFINITY, |&(d2, _)| d2.sqrt())
        })
        .collect();
    if nearest.is_empty() {
        return None;
    }
    let mid = nearest.len() / 2;
    let median = *nearest.select_nth_unstable_by(mid, f64::total_cmp).1;
    (median.is_finite() && median > 0.0).then_some(median)
}

/// Twice the largest distance from an object sample to its nearest background sample;
/// `+∞` with no background sample.
fn max_thickness(positions: &[DVec3], object: &[bool]) -> f64 {
    let background: Vec<DVec3> = positions
        .iter()
        .zip(object)
        .filter(|&(_, &o)| !o)
        .map(|(&p, _)| p)
        .collect();
    if background.is_empty() {
        return f64::INFINITY;
    }
    let index = PointIndex::new(&background).expect("fewer points than the input");
    let max = positions
        .par_iter()
        .zip(object)
        .filter(|&(_, &o)| o)
        .map_init(Vec::new, |out, (&p, _)| {
            index.nearest_k_with_distances(p, 1, out);
            out[0].0
        })
        .reduce(|| 0.0, f64::max);
    2.0 * max.sqrt()
}

fn bounding_diagonal(positions: &[DVec3]) -> f64 {
    let (lo, hi) = positions.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    (hi - lo).length()
}

/// The samples and everything shared by the fits.
struct Samples<'a> {
    positions: &'a [DVec3],
    /// Normalised values.
    values: Vec<f64>,
    object: &'a [bool],
    index: &'a PointIndex,
    /// `h`: the unit of the fixed frame (the sample spacing).
    unit: f64,
    r_min: f64,
    r_max: f64,
    tolerance: f64,
    min_samples: usize,
    bounding_box: bool,
}

/// The samples around one centre, gathered lazily by increasing `(distance², index)`, and
/// their shells.
struct Neighbourhood<'s, 'a> {
    samples: &'s Samples<'a>,
    centre: DVec3,
    /// `(distance² in frame d/h, sample index)`, ascending.
    entries: Vec<(f64, u32)>,
    /// Every sample with frame distance² below this is in `entries`.
    complete_below: f64,
    /// Frame distance² of `r_max`, less a relative 1e-9: samples on the sphere are outside
    /// the open ball (as the grid's offset table).
    reach2: f64,
    /// Shells: `(largest distance² of the shell, end index in entries)`.
    shells: Vec<(f64, usize)>,
    scratch: Vec<(f64, u32)>,
}

impl<'s, 'a> Neighbourhood<'s, 'a> {
    fn new(samples: &'s Samples<'a>, centre: DVec3) -> Self {
        let reach = samples.r_max / samples.unit;
        Neighbourhood {
            samples,
            centre,
            entries: Vec::new(),
            complete_below: 0.0,
            reach2: reach * reach * (1.0 - 1e-9),
            shells: Vec::new(),
            scratch: Vec::new(),
        }
    }

    /// Makes `entries` complete up to frame distance² `d2` (at least; capped at `r_max`).
    fn ensure(&mut self, d2: f64) {
        if d2 < self.complete_below {
            return;
        }
        let target = (4.0 * d2).max(4.0 * self.complete_below).max(4.0);
        // The new bound: entries with `previous ≤ fd2 < limit` are added. The k-d tree's
        // world-unit ball is slightly larger than the limit so that no sample below it is
        // missed by rounding.
        let last = target >= self.reach2;
        let limit = if last { self.reach2 } else { target };
        let h = self.samples.unit;
        let previous = self.complete_below;
        self.scratch.clear();
        let centre = self.centre;
        let scratch = &mut self.scratch;
        let slot_order = self.samples.index.order();
        let positions = self.samples.positions;
        self.samples.index.for_each_slot_within(
            centre,
            (limit * (1.0 + 1e-6)).sqrt() * h,
            |slot, _| {
                let i = slot_order[slot];
                let fd2 = ((positions[i as usize] - centre) / h).length_squared();
                if fd2 >= previous && fd2 < limit {
                    scratch.push((fd2, i));
                }
            },
        );
        self.scratch
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        self.entries.extend_from_slice(&self.scratch);
        self.complete_below = if last { f64::INFINITY } else { limit };
    }

    /// Shell `s`, materialising it; `None` past the last shell within `r_max`.
    fn shell(&mut self, s: usize) -> Option<(f64, usize)> {
        while self.shells.len() <= s {
            let start = self.shells.last().map_or(0, |&(_, end)| end);
            while start >= self.entries.len() {
                if self.complete_below.is_infinite() {
                    return None;
                }
                self.ensure(self.complete_below);
            }
            let first = self.entries[start].0;
            self.ensure(first * (1.0 + 2e-9));
            let mut end = start;
            let mut last = first;
            while end < self.entries.len() && self.entries[end].0 <= first * (1.0 + 1e-9) {
                last = self.entries[end].0;
                end += 1;
            }
            self.shells.push((last, end));
        }
        Some(self.shells[s])
    }
}

impl Samples<'_> {
    /// The ball radius for shell `s` of `nb`: halfway to the next shell, within
    /// `[r_min, r_max]` (r_min applies from shell `first_shell` on).
    fn radius_of_shell(&self, nb: &mut Neighbourhood, s: usize, first_shell: usize) -> f64 {
        let here = nb.shell(s).expect("an existing shell").0.sqrt() * self.unit;
        let r = match nb.shell(s + 1) {
            Some((next, _)) => 0.5 * (here + next.sqrt() * self.unit),
            None => self.r_max,
        };
        let r = if s >= first_shell {
            r.max(self.r_min)
        } else {
            r
        };
        r.min(self.r_max).max(here)
    }

    /// Fits the support centred at sample `centre` (a pure function of `centre`).
    fn fit<const N: usize>(&self, centre: usize) -> Support {
        let c = self.positions[centre];
        let shift = self.values[centre];
        let mut nb = Neighbourhood::new(self, c);
        let mut acc = NormalEquations::<N>::new();
        let mut next_entry = 0;
        let extend = |nb: &mut Neighbourhood, acc: &mut NormalEquations<N>, next: &mut usize, s| {
            let end = nb.shell(s).expect("an existing shell").1;
            for &(_, i) in &nb.entries[*next..end] {
                let d = (self.positions[i as usize] - c) / self.unit;
                acc.add(d.to_array(), self.values[i as usize] - shift);
            }
            *next = end;
        };
        // The last shell index that exists; the centre itself is shell 0.
        let exists = |nb: &mut Neighbourhood, s: usize| nb.shell(s).is_some();
        // The smallest ball with min_samples samples.
        let mut floor = 0;
        extend(&mut nb, &mut acc, &mut next_entry, floor);
        while acc.count() < self.min_samples && exists(&mut nb, floor + 1) {
            floor += 1;
            extend(&mut nb, &mut acc, &mut next_entry, floor);
        }
        let floor_acc = acc;
        // The first shell within r_min.
        let rmin2 = (self.r_min / self.unit).powi(2);
        let mut first_shell = 0;
        while exists(&mut nb, first_shell + 1) && nb.shells[first_shell + 1].0 <= rmin2 {
            first_shell += 1;
        }
        let s = floor.max(first_shell);
        extend(&mut nb, &mut acc, &mut next_entry, s);
        let solve = |nb: &mut Neighbourhood, acc: &NormalEquations<N>, s: usize| {
            let r = self.radius_of_shell(nb, s, first_shell);
            acc.solve(self.unit / r)
                .map(|(c, e)| (c, e, r))
                .unwrap_or(([0.0; N], 0.0, r))
        };
        type Good<const N: usize> = (usize, ([f64; N], f64, f64), NormalEquations<N>);
        let bisect = |nb: &mut Neighbourhood, mut good: Good<N>, mut hi: usize| {
            while hi - good.0 > 1 {
                let mid = good.0 + (hi - good.0) / 2;
                let mut trial = good.2;
                let mut trial_next = nb.shells[good.0].1;
                extend(nb, &mut trial, &mut trial_next, mid);
                let res = solve(nb, &trial, mid);
                if res.1 <= self.tolerance {
                    good = (mid, res, trial);
                } else {
                    hi = mid;
                }
            }
            good
        };
        let first = solve(&mut nb, &acc, s);
        let mut good: Good<N> = (s, first, acc);
        if good.1.1 > self.tolerance && s > floor {
            let floor_fit = solve(&mut nb, &floor_acc, floor);
            good = (floor, floor_fit, floor_acc);
            if good.1.1 <= self.tolerance {
                good = bisect(&mut nb, good, s);
            }
        } else if good.1.1 <= self.tolerance {
            let mut bad = None;
            while exists(&mut nb, good.0 + 1) {
                let target = self.radius_of_shell(&mut nb, good.0, first_shell) * 1.5 / self.unit;
                let t2 = target * target;
                let mut probe = good.0 + 1;
                while exists(&mut nb, probe + 1) && nb.shells[probe + 1].0 <= t2 {
                    probe += 1;
                }
                extend(&mut nb, &mut acc, &mut next_entry, probe);
                let res = solve(&mut nb, &acc, probe);
                if res.1 <= self.tolerance {
                    good = (probe, res, acc);
                } else {
                    bad = Some(probe);
                    break;
                }
            }
            if let Some(hi) = bad {
                good = bisect(&mut nb, good, hi);
            }
        }
        let (shell, (coef_n, _, radius), _) = good;
        let mut coef = [0.0; QUADRATIC];
        coef[..N].copy_from_slice(&coef_n);
        let (shell_d2, end) = nb.shells[shell];
        let scale = 1.0 / radius;
        let (mut sum, mut count) = (0.0, 0usize);
        for &(_, i) in &nb.entries[..end] {
            let u = ((self.positions[i as usize] - c) * scale).to_array();
            let r = super::fit::evaluate(&coef_n, u) - (self.values[i as usize] - shift);
            sum += r * r;
            count += 1;
        }
        Support {
            centre: centre as u32,
            radius,
            shell_d2,
            offsets: end,
            coef,
            shift,
            rms: (sum / count.max(1) as f64).sqrt(),
        }
    }

    /// The samples of the support's ball, `(frame distance², index)` ascending (the fit's
    /// sample set, gathered again: the fits run ahead in parallel and keep no lists).
    fn ball(&self, s: &Support, out: &mut Vec<(f64, u32)>) {
        out.clear();
        let c = self.positions[s.centre as usize];
        let h = self.unit;
        let limit = s.shell_d2;
        let order = self.index.order();
        self.index
            .for_each_slot_within(c, (limit * (1.0 + 1e-6)).sqrt() * h, |slot, _| {
                let i = order[slot];
                let d2 = ((self.positions[i as usize] - c) / h).length_squared();
                if d2 <= limit {
                    out.push((d2, i));
                }
            });
        out.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    }

    /// Marks the centre, and every uncovered point of `S` that some point of `S` exceeds
    /// along its own ray from the centre, as covered.
    fn mark_covered(&self, s: &Support, covered: &mut [bool], ball: &mut Vec<(f64, u32)>) {
        covered[s.centre as usize] = true;
        self.ball(s, ball);
        let c = self.positions[s.centre as usize];
        let in_set = |i: u32| self.bounding_box || self.object[i as usize];
        // Farthest first: a point is beaten only by points at least as far as itself.
        let set: Vec<DVec3> = ball
            .iter()
            .rev()
            .filter(|&&(_, i)| in_set(i))
            .map(|&(_, i)| self.positions[i as usize] - c)
            .collect();
        let ids: Vec<u32> = ball
            .iter()
            .rev()
            .filter(|&&(_, i)| in_set(i))
            .map(|&(_, i)| i)
            .collect();
        for (k, (&p, &i)) in set.iter().zip(&ids).enumerate() {
            if covered[i as usize] {
                continue;
            }
            let d2 = p.length_squared();
            if d2 == 0.0 {
                covered[i as usize] = true;
                continue;
            }
            let d = d2.sqrt();
            let u = p / d;
            // Points after k are no farther than p: they cannot beat it along u (except a
            // tie in distance, which cannot be strictly farther along u either).
            let beaten = set[..k].iter().any(|&q| u.dot(q) > d);
            if beaten {
                covered[i as usize] = true;
            }
        }
    }

    fn cover<const N: usize>(
        &self,
        params: &VolumeCoverParams,
        stats: &mut VolumeCoverStats,
    ) -> Vec<Support> {
        let n = self.positions.len();
        let mut order: Vec<u32> = if self.bounding_box {
            (0..n as u32).collect()
        } else {
            (0..n as u32).filter(|&i| self.object[i as usize]).collect()
        };
        stats.candidates = order.len();
        shuffle(&mut order, params.seed);
        let mut supports = Vec::new();
        let mut ball = Vec::new();
        super::covering::covering_loop(
            &order,
            n,
            |c| self.fit::<N>(c),
            stats,
            |s, covered| {
                self.mark_covered(&s, covered, &mut ball);
                supports.push(s);
            },
        );
        if params.elimination != super::Elimination::Off && !self.bounding_box {
            self.eliminate_redundant(supports)
        } else {
            supports
        }
    }

    /// Calls `f` with every object sample (every sample, for the linear variant) strictly
    /// inside the support's ball.
    fn for_each_member(&self, s: &Support, f: &mut dyn FnMut(usize)) {
        let c = self.positions[s.centre as usize];
        let h = self.unit;
        let limit = s.radius * (1.0 - 1e-9) / h;
        let limit2 = limit * limit;
        let order = self.index.order();
        self.index
            .for_each_slot_within(c, (s.shell_d2 * (1.0 + 1e-6)).sqrt() * h, |slot, _| {
                let i = order[slot] as usize;
                let d2 = ((self.positions[i] - c) / h).length_squared();
                if d2 <= s.shell_d2 && d2 < limit2 && (self.bounding_box || self.object[i]) {
                    f(i);
                }
            });
    }

    /// The grid builder's elimination pass, on samples.
    fn eliminate_redundant(&self, supports: Vec<Support>) -> Vec<Support> {
        super::elimination::eliminate_redundant_supports(
            supports,
            self.tolerance,
            self.positions.len(),
            |s, f| self.for_each_member(s, f),
        )
    }
}
