//! What a scan says about itself before anything is fitted: its sample spacing, its noise
//! level and the samples that lie far from every other (beyond the thesis).
//!
//! The method is described on [`scan_statistics()`].

use rayon::prelude::*;
use sphcover_core::{DVec3, PointIndex};

use crate::pca::Pca;

/// Queries per run of the noise pass (runs are searched in parallel, each search bounded by
/// the query's slot neighbours, see `PointIndex::nearest_k_run_at_slots`).
const NOISE_RUN: usize = 64;

/// Slots on either side of a sample that the isolation test reads before it searches.
const WINDOW: usize = 16;

/// The spacing is a median over about this many samples (at most; see
/// [`ScanStatisticsParams::noise_stride`]).
const SPACING_SAMPLES: usize = 12_500;

/// The noise is a median over about this many samples (at most). Each costs a search for
/// hundreds of neighbours and a plane fit, ten times a spacing query, so the pass costs in
/// proportion to the samples it takes. The medians barely move: on the 100K-point bunny with
/// noise of 0.25% and 0.5% of the diagonal, 3.67e-3 and 5.99e-3 over 12,500 samples,
/// 3.68e-3 and 6.01e-3 over 4,000.
const NOISE_SAMPLES: usize = 4_000;

/// Parameters of [`scan_statistics`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanStatisticsParams {
    /// Neighbours per sample (the sample itself not counted).
    pub k: usize,
    /// A sample is isolated when its mean neighbour distance exceeds this multiple of the
    /// median. 4 rather than a looser 6: with 5% uniform outliers the outliers' own mean
    /// neighbour distance is only about 7 times the surface's spacing, so at 6 a third of
    /// them stayed in, and with noise raising ε they opened the fandisk's surface (F@1% 0.84
    /// against 1.0 at 4). A tenfold density gradient (spacing 3.2 times the median at the
    /// sparse end) stays below 4.
    pub isolation: f64,
    /// Estimate the spacing and the noise from every `noise_stride`-th sample, or from about
    /// 12,500 samples for the spacing and 4,000 for the noise when that is fewer (a median
    /// over that many is already stable).
    pub noise_stride: usize,
    /// The largest patch of the noise estimate, in neighbours per 100,000 samples (at least
    /// this many, at most 1024): more than `k`, because a plane through few neighbours
    /// follows the noise (with 16, σ comes out at half its value on a scan whose noise is
    /// comparable to its spacing), and growing with the sample count so that the fitted
    /// patch keeps its size (with a fixed 48, the noise of a 362K-point scan comes out 28%
    /// lower than that of a 100K-point scan with the same σ). Patches start at 16 samples
    /// and grow only while noise, not geometry, may be what they see (see
    /// [`scan_statistics()`]).
    pub noise_k: usize,
}

impl Default for ScanStatisticsParams {
    /// k = 16, isolation 4, noise from every 8th sample over 48 neighbours.
    fn default() -> Self {
        ScanStatisticsParams {
            k: 16,
            isolation: 4.0,
            noise_stride: 8,
            noise_k: 48,
        }
    }
}

/// The spacing, noise and isolated samples of a scan.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ScanStatistics {
    /// Median of the mean distance to the `k` nearest neighbours, over a subsample spread
    /// over the scan (see [`ScanStatisticsParams::noise_stride`]).
    pub spacing: f64,
    /// Median over (non-isolated) samples of the RMS distance of their own sheet's
    /// neighbours to its plane (see [`scan_statistics()`]).
    pub noise: f64,
    /// Per sample: isolated from the rest of the scan.
    pub isolated: Vec<bool>,
    /// Number of isolated samples.
    pub isolated_count: usize,
    /// The normals face one side: the scan is one view (see [`one_view`]).
    pub one_view: bool,
}

/// Measures `points` (indexed by `index`; method below). Fewer than `k + 1` points give
/// zero spacing and noise and no isolated sample.
///
/// The thesis takes the cover tolerance ε as a user choice and leaves outliers to the graph
/// cut and the confidence of samples (§5.2.4). Both fall short on real scans:
///
/// - With Gaussian noise of standard deviation σ larger than ε no plane fits any support
///   within ε, so the octree refines until every support has to grow to reach its `n_min`
///   samples: on a 100K-point bunny with noise of 0.5% of the diagonal, the cover has over
///   ten times the supports, and the run many times the time and memory, of one with the
///   raised tolerance below (`docs/algorithms.md`, *Surface reconstruction*). The tolerance
///   a scan supports is about the largest residual of its noise, so the pipeline uses
///   `max(ε, 4σ̂)` (when asked to, see `ReconParams::noise_tolerance`), with σ̂ the median
///   over samples of the RMS distance of the samples of their own sheet to its plane.
/// - Geometry must not pass for noise. A plane through a sample's neighbours also fits the
///   other side of a thin wall, the rib across a narrow gap and the other face at an edge:
///   on a housing with 0.7–1.6 mm walls and 1.3 mm gaps, sampled with 200K points, the
///   plain plane residual read 0.78 mm of noise in a noise-free scan. So each sample's
///   patch keeps only the neighbours whose normal lines (`normals`, given or estimated) lie
///   within 60° of its own; splits its offsets from the plane, along the sample's normal or
///   a principal axis, as long as they fall into two clusters (keeping the sample's); and
///   grows from 16 samples towards the largest patch only while the residual is more than
///   an eighth of the patch's radius — noise is seen whole only by patches several σ
///   wide, while flat faces next to features are measured before the features enter. On
///   that housing the estimate is 0 with the normals given or estimated; with noise of
///   0.02 and 0.07 mm at 100K samples (fins about one spacing thick), 0.018 and 0.064.
/// - The confidence of samples (eq. 5.39–5.40) rarely falls below its outlier threshold for
///   uniform outliers (supports centred on a surface have centroid offsets in random
///   directions, so surface samples score about as low as outliers). Uniform outliers are
///   instead plain to see by their isolation: in a 100K-point scan of a unit box with 5%
///   outliers, an outlier's mean distance to its `k` nearest neighbours is 10–20 times the
///   surface samples'. A sample is *isolated* when that distance exceeds `isolation` times
///   the median over the scan ("statistical outlier removal").
pub fn scan_statistics(
    points: &[DVec3],
    normals: Option<&[DVec3]>,
    index: &PointIndex,
    params: &ScanStatisticsParams,
) -> ScanStatistics {
    let n = points.len();
    if n <= params.k.max(3) {
        return ScanStatistics {
            isolated: vec![false; n],
            ..ScanStatistics::default()
        };
    }
    let spacing = median(spacing_values(index, params, n, None));
    let (isolated, isolated_count) = isolated_samples(index, params, spacing);
    let residuals = noise_residuals(points, normals, index, params, n, &isolated, None);
    let one_view =
        normals.is_some_and(|normals| one_view(&view_normals(normals, params, n, &isolated, None)));
    ScanStatistics {
        spacing,
        noise: median(residuals),
        isolated,
        isolated_count,
        one_view,
    }
}

/// Share of the normals that must lie within 90° of their mean direction for a scan to be
/// taken for one view. Every normal of a single range scan faces its scanner; the normals of
/// the generated single views (bunny, housing, fandisk, femur) and of CGAL's two hippo scans
/// all lie within 90° of their mean, while a closed object has about half of them there and
/// a turntable scan with its base unseen (six views) 75–78%.
pub const ONE_VIEW_SHARE: f64 = 0.99;

/// Whether `normals` (unit or zero) face one side: at least [`ONE_VIEW_SHARE`] of them
/// within 90° of their mean direction. A single view never sees a closed object, so surface
/// far from its samples is never a hole to close (see `Trim::Unseen`). Sign-agnostic
/// normals estimated without orientation face one side only by chance; estimated normals
/// are oriented before they get here.
pub fn one_view(normals: &[DVec3]) -> bool {
    let Some(mean) = normals.iter().sum::<DVec3>().try_normalize() else {
        return false;
    };
    let facing = normals.iter().filter(|n| n.dot(mean) > 0.0).count();
    normals.len() >= 16 && facing as f64 >= ONE_VIEW_SHARE * normals.len() as f64
}

/// The normals [`one_view`] reads: those of every `noise_stride`-th sample (by index, the
/// stride set by the `population` of the whole scan, as for the noise) that is not isolated
/// and is marked in `own` (all without).
pub(crate) fn view_normals(
    normals: &[DVec3],
    params: &ScanStatisticsParams,
    population: usize,
    isolated: &[bool],
    own: Option<&[bool]>,
) -> Vec<DVec3> {
    let stride = params.noise_stride.max(population / NOISE_SAMPLES).max(1);
    (0..normals.len())
        .step_by(stride)
        .filter(|&i| !isolated[i] && own.is_none_or(|own| own[i]) && normals[i].is_finite())
        .map(|i| normals[i])
        .collect()
}

/// The mean neighbour distances whose median is the spacing: every `stride`-th slot of
/// `index`, with the stride set by the `population` of the whole scan (a part of it takes
/// its share of the subsample), of the samples marked in `own` (all without).
pub(crate) fn spacing_values(
    index: &PointIndex,
    params: &ScanStatisticsParams,
    population: usize,
    own: Option<&[bool]>,
) -> Vec<f64> {
    let k = params.k.max(3);
    if index.slot_points().len() <= k {
        return Vec::new();
    }
    // The spacing is a median, which a stratified subsample pins down (every `stride`-th
    // slot: the slots follow the tree, so the subsample is spread over the whole scan); only
    // the isolation test needs every sample.
    let stride = params.noise_stride.max(population / SPACING_SAMPLES).max(1);
    let slots = index.slot_points();
    let order = index.order();
    (0..slots.len())
        .into_par_iter()
        .step_by(stride)
        .with_min_len(64)
        .filter(|&s| own.is_none_or(|own| own[order[s] as usize]))
        .map_init(Vec::new, |buf, s| {
            mean_neighbour_distance(index, slots[s], k, buf)
        })
        .collect()
}

/// Which samples of `index` are isolated at `spacing`, and how many.
pub(crate) fn isolated_samples(
    index: &PointIndex,
    params: &ScanStatisticsParams,
    spacing: f64,
) -> (Vec<bool>, usize) {
    let k = params.k.max(3);
    let slots = index.slot_points();
    let n = index.input_len();
    if slots.len() <= k {
        return (vec![false; n], 0);
    }
    let limit = params.isolation * spacing;
    // A sample has `k` other samples within `limit` among its neighbours in slot order
    // (the same tree leaf or the next) almost always; then its mean distance to its `k`
    // nearest is below `limit` too and no search is needed. The margin keeps that true
    // through the rounding of the mean.
    let sure = limit * (1.0 - 1e-9);
    let sure2 = sure * sure;
    let slot_isolated: Vec<bool> = (0..slots.len())
        .into_par_iter()
        .with_min_len(1024)
        .map_init(Vec::new, |buf, s| {
            if spacing <= 0.0 {
                return false;
            }
            let x = slots[s];
            let window = s.saturating_sub(WINDOW)..(s + WINDOW + 1).min(slots.len());
            let close = window
                .filter(|&t| t != s && (slots[t] - x).length_squared() < sure2)
                .take(k)
                .count();
            close < k && mean_neighbour_distance(index, x, k, buf) > limit
        })
        .collect();
    // Non-finite samples are not indexed; they are never isolated.
    let mut isolated = vec![false; n];
    for (&i, &o) in index.order().iter().zip(&slot_isolated) {
        isolated[i as usize] = o;
    }
    let isolated_count = slot_isolated.iter().filter(|&&i| i).count();
    (isolated, isolated_count)
}

/// The residuals whose median is the noise: every `noise_stride`-th sample (by index, the
/// stride set by the `population` of the whole scan) that is not isolated and is marked in
/// `own` (all without).
pub(crate) fn noise_residuals(
    points: &[DVec3],
    normals: Option<&[DVec3]>,
    index: &PointIndex,
    params: &ScanStatisticsParams,
    population: usize,
    isolated: &[bool],
    own: Option<&[bool]>,
) -> Vec<f64> {
    let n = points.len();
    let k = params.k.max(3);
    if n <= k {
        return Vec::new();
    }
    let noise_k = (params.noise_k as f64 * population as f64 / 100_000.0)
        .clamp(params.noise_k.max(k) as f64, 1024.0) as usize;
    // The subsample is fixed by the caller's order (every `noise_stride`-th sample); it is
    // queried in slot order for locality, which leaves the median unchanged.
    let noise_stride = params.noise_stride.max(population / NOISE_SAMPLES).max(1);
    let mut slot_of = vec![u32::MAX; n];
    for (s, &i) in index.order().iter().enumerate() {
        slot_of[i as usize] = s as u32;
    }
    // Non-finite points are not indexed (they have no plane): left out.
    let mut queries: Vec<u32> = (0..n)
        .step_by(noise_stride)
        .filter(|&i| !isolated[i] && slot_of[i] != u32::MAX && own.is_none_or(|own| own[i]))
        .map(|i| slot_of[i])
        .collect();
    queries.sort_unstable();
    // The noise pass asks for hundreds of neighbours (up to 1024), where inserting each
    // found point into a sorted list costs O(k): searches bounded by the query's slot
    // neighbours collect a ball and select instead (exact, so the median does not move).
    // For the spacing pass (17 neighbours) such runs are no faster than single queries.
    let order = index.order();
    queries
        .par_chunks(NOISE_RUN)
        .flat_map_iter(|run| {
            let mut found = Vec::with_capacity(run.len());
            let mut sheet = SheetNoise::default();
            index.nearest_k_run_at_slots(run, noise_k + 1, |q, near| {
                let query = order[run[q] as usize] as usize;
                found.push(sheet.measure(points, normals, query, near));
            });
            found.into_iter().flatten()
        })
        .collect()
}

/// Mean distance from `x` to its `k` nearest samples other than itself (the nearest, at
/// distance 0, is taken to be `x`; a duplicate of `x` counts once).
fn mean_neighbour_distance(
    index: &PointIndex,
    x: DVec3,
    k: usize,
    buf: &mut Vec<(f64, u32)>,
) -> f64 {
    index.nearest_k_with_distances(x, k + 1, buf);
    let sum: f64 = buf.iter().skip(1).map(|&(d2, _)| d2.sqrt()).sum();
    sum / (buf.len().max(2) - 1) as f64
}

/// The smallest patch of the noise ladder, in samples (the query included).
const LADDER_START: usize = 16;

/// A patch measures noise rather than geometry once its radius is at least this many times
/// its residual: noise of standard deviation σ is seen whole only by patches several σ
/// wide, while curvature and edges make the residual grow with the patch.
const PATCH_TO_RESIDUAL: f64 = 8.0;

/// The share of a patch's residual variance above which its offsets from the plane are two
/// sheets (a thin wall's faces, ribs across a gap) rather than one noisy sheet. Splitting a
/// Gaussian in two explains 64% of its variance (1 − 2/π), a uniform spread 75%; two sheets
/// `t` apart with noise σ explain `t² / (t² + 4σ²)`, above 90% once `t > 6σ`.
const TWO_SHEETS: f64 = 0.9;

/// Neighbours whose normal lines make a larger angle with the query's (60°) lie on another
/// face: a perpendicular face at an edge, a fin's tip.
const SAME_FACE: f64 = 0.5;

/// Fewest samples a patch needs for a residual.
const MIN_PATCH: usize = 8;

/// The noise measured around one sample: the RMS distance of the samples of its own sheet
/// to their plane, over the smallest patch that sees noise as noise (buffers reused across
/// queries).
///
/// Thin walls, ribs across narrow gaps and sharp edges put samples of other faces into a
/// sample's neighbourhood, and a plane through all of them reads the geometry as noise (a
/// wall of thickness `t` gives a residual of about `t / 2`). Three things keep them apart:
/// neighbours facing another way are left out when the scan has normals; the patch grows
/// from 16 samples only while its residual is large against its radius (so flat regions
/// next to features are measured before the features enter the patch); and offsets from the
/// plane that fall into two clusters are split, the query's cluster kept.
#[derive(Debug, Default)]
struct SheetNoise {
    /// The query, then its neighbours on the same side, nearest first.
    patch: Vec<DVec3>,
    /// Their distances from the query.
    distance: Vec<f64>,
    /// Signed offsets from the patch's plane with their patch positions, sorted.
    offsets: Vec<(f64, usize)>,
    /// The query's sheet, when the patch holds two.
    sheet: Vec<DVec3>,
}

impl SheetNoise {
    /// The noise at sample `query` from its neighbours `near` (`(distance², index)`, nearest
    /// first); `None` when no plane is determined.
    fn measure(
        &mut self,
        points: &[DVec3],
        normals: Option<&[DVec3]>,
        query: usize,
        near: &[(f64, u32)],
    ) -> Option<f64> {
        self.patch.clear();
        self.distance.clear();
        self.patch.push(points[query]);
        self.distance.push(0.0);
        for &(d2, j) in near {
            let j = j as usize;
            let other_face = normals.is_some_and(|n| n[j].dot(n[query]).abs() <= SAME_FACE);
            if j != query && !other_face {
                self.patch.push(points[j]);
                self.distance.push(d2.sqrt());
            }
        }
        let len = self.patch.len();
        if len < MIN_PATCH {
            return None;
        }
        let mut size = LADDER_START.min(len);
        loop {
            let residual = self.sheet_residual(size, normals.map(|n| n[query]))?;
            if size == len || residual * PATCH_TO_RESIDUAL <= self.distance[size - 1] {
                return Some(residual);
            }
            size = (2 * size).min(len);
        }
    }

    /// The RMS distance to the plane of the first `size` samples of the patch, or of the
    /// query's sheet among them: while the offsets from the plane fall into two clusters,
    /// the query's cluster is kept and fitted again (a stack of fins or ribs holds several
    /// sheets, which come apart one split at a time).
    fn sheet_residual(&mut self, size: usize, across: Option<DVec3>) -> Option<f64> {
        self.sheet.clear();
        self.sheet.extend_from_slice(&self.patch[..size]);
        // The query stays at position 0 of `sheet`.
        loop {
            let pca = Pca::of(&self.sheet)?;
            let normal = pca.normal()?;
            let residual = |sheet: &[DVec3]| {
                let sum: f64 = sheet
                    .iter()
                    .map(|&p| (p - pca.centroid).dot(normal).powi(2))
                    .sum();
                (sum / sheet.len() as f64).sqrt()
            };
            // Sheets are told apart along the query's normal or a principal axis, whichever
            // separates them best: in a patch not much wider than a wall is thick, the axis of
            // least variance can lie along the wall rather than across it, and a normal
            // estimated from such a patch is tilted.
            let mut best: Option<(f64, DVec3)> = None;
            for direction in across.into_iter().chain(pca.axes) {
                let offsets = self
                    .sheet
                    .iter()
                    .map(|&p| (p - pca.centroid).dot(direction));
                let (explained, _) = best_split(&mut self.offsets, offsets);
                if explained > best.map_or(TWO_SHEETS, |b| b.0) {
                    best = Some((explained, direction));
                }
            }
            let Some((_, direction)) = best else {
                return Some(residual(&self.sheet));
            };
            let offsets = self
                .sheet
                .iter()
                .map(|&p| (p - pca.centroid).dot(direction));
            let split = best_split(&mut self.offsets, offsets).1;
            let query_below = self.offsets[..split].iter().any(|&(_, i)| i == 0);
            let side = if query_below {
                &mut self.offsets[..split]
            } else {
                &mut self.offsets[split..]
            };
            // The query first, so that it can be found again after the next split.
            side.sort_unstable_by_key(|&(_, i)| i);
            let kept: Vec<DVec3> = side.iter().map(|&(_, i)| self.sheet[i]).collect();
            self.sheet.clear();
            self.sheet.extend(kept);
        }
    }
}

/// The best split of `offsets` into two sheets: the share of their variance it explains and
/// the count of offsets below it. A split after `i` of `n` sorted offsets explains
/// `i·(n − i)/n · (m₁ − m₂)²` of their sum of squared deviations; each side must hold at
/// least 3 and an eighth of them (0 explained when no split is allowed). `buffer` is left
/// holding the offsets sorted, with their positions.
fn best_split(buffer: &mut Vec<(f64, usize)>, offsets: impl Iterator<Item = f64>) -> (f64, usize) {
    buffer.clear();
    buffer.extend(offsets.enumerate().map(|(i, d)| (d, i)));
    let size = buffer.len();
    let smallest = (size / 8).max(3);
    let n = size as f64;
    let sum: f64 = buffer.iter().map(|&(d, _)| d).sum();
    let total = buffer.iter().map(|&(d, _)| d * d).sum::<f64>() - sum * sum / n;
    if total <= 0.0 || size < 2 * smallest {
        return (0.0, 0);
    }
    buffer.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best = (0.0, 0);
    let mut below = 0.0;
    for i in 1..size {
        below += buffer[i - 1].0;
        if i < smallest || size - i < smallest {
            continue;
        }
        let (a, b) = (i as f64, n - i as f64);
        let gap = below / a - (sum - below) / b;
        let explained = a * b / n * gap * gap;
        if explained > best.0 {
            best = (explained, i);
        }
    }
    (best.0 / total, best.1)
}

/// The median (upper median for an even count); 0 for no values.
pub(crate) fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::normals::{NormalParams, estimate_normals};
    use sphcover_evaluation::{add_position_noise, add_uniform_outliers, sphere};

    #[test]
    fn noise_is_measured_and_isolated_points_found() {
        let mut cloud = sphere(DVec3::ZERO, 0.4, 20_000);
        let clean = {
            let index = PointIndex::new(&cloud.positions).unwrap();
            scan_statistics(
                &cloud.positions,
                None,
                &index,
                &ScanStatisticsParams::default(),
            )
        };
        // Curvature alone: the sagitta of 48-neighbour patches of a radius-0.4 sphere.
        assert!(clean.noise < 1e-3, "clean noise {}", clean.noise);
        assert_eq!(clean.isolated_count, 0);

        add_position_noise(&mut cloud, 0.004, 1);
        add_uniform_outliers(&mut cloud, 400, DVec3::splat(-0.5), DVec3::splat(0.5), 2);
        let index = PointIndex::new(&cloud.positions).unwrap();
        let stats = scan_statistics(
            &cloud.positions,
            None,
            &index,
            &ScanStatisticsParams::default(),
        );
        // RMS residual of isotropic noise σ about a fitted plane: about σ.
        assert!(
            (stats.noise / 0.004 - 1.0).abs() < 0.2,
            "noise {} for σ = 0.004",
            stats.noise
        );
        // Every outlier farther from the surface than the isolation distance (4 × the
        // spacing) plus the neighbourhood's own reach is found.
        let far = |i: usize| (cloud.positions[i].length() - 0.4).abs() > 10.0 * stats.spacing;
        let far_outliers: Vec<usize> = (20_000..cloud.len()).filter(|&i| far(i)).collect();
        let missed = far_outliers.iter().filter(|&&i| !stats.isolated[i]).count();
        assert!(
            far_outliers.len() > 100,
            "{} far outliers",
            far_outliers.len()
        );
        assert_eq!(
            missed,
            0,
            "missed {missed} of {} far outliers",
            far_outliers.len()
        );
        let false_alarms = stats.isolated[..20_000].iter().filter(|&&o| o).count();
        assert!(false_alarms <= 20, "{false_alarms} surface samples flagged");
    }

    /// A uniform sample of the thin-walled housing (fins 0.7 mm, ribs 1.0 mm with gaps of
    /// 1.3 mm, walls 1.6 mm), with Gaussian noise `sigma` (mm): positions and normals.
    fn housing_sample(count: usize, sigma: f64) -> (Vec<DVec3>, Vec<DVec3>) {
        use rand::SeedableRng;
        use sphcover_evaluation::surface_sampling::SurfaceSampler;
        let mesh = sphcover_evaluation::thin_walled_part::thin_walled_housing()
            .solid
            .boundary_mesh();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let samples = SurfaceSampler::new(&mesh).unwrap().samples(count, &mut rng);
        let mut cloud =
            sphcover_core::PointCloud::from_positions(samples.iter().map(|s| s.position).collect());
        let normals = samples.iter().map(|s| s.normal).collect();
        if sigma > 0.0 {
            add_position_noise(&mut cloud, sigma, 9);
        }
        (cloud.positions, normals)
    }

    #[test]
    fn thin_walls_gaps_and_edges_are_not_noise() {
        // Every 100K-point neighbourhood of 48 samples (2.6 mm across) holds another face:
        // the other side of a fin or rib, the rib across a gap, a perpendicular face at an
        // edge. A plane through them all reads 0.3 mm of noise, about half a fin.
        let params = ScanStatisticsParams::default();
        let fin = 0.7;
        let (points, exact) = housing_sample(200_000, 0.0);
        let index = PointIndex::new(&points).unwrap();
        let estimated = estimate_normals(&points, &NormalParams::default())
            .unwrap()
            .normals;
        for (normals, which) in [(exact, "exact"), (estimated, "estimated")] {
            let stats = scan_statistics(&points, Some(&normals), &index, &params);
            assert!(
                stats.noise < 0.1 * fin,
                "{which} normals: noise {} mm",
                stats.noise
            );
        }
        // Noise on thin walls is measured as noise, the walls left out (at half the density,
        // where fins are about one sample spacing thick).
        for sigma in [0.02, 0.07] {
            let (points, exact) = housing_sample(100_000, sigma);
            let index = PointIndex::new(&points).unwrap();
            let stats = scan_statistics(&points, Some(&exact), &index, &params);
            assert!(
                (stats.noise / sigma - 1.0).abs() < 0.15,
                "noise {} mm for σ = {sigma} mm",
                stats.noise
            );
        }
    }

    /// Mean distance to the `k` nearest other samples, selected among all distances.
    fn brute_mean_distance(points: &[DVec3], i: usize, k: usize) -> f64 {
        let mut d: Vec<f64> = points.iter().map(|&q| (q - points[i]).length()).collect();
        d.select_nth_unstable_by(k, f64::total_cmp);
        d[..=k].iter().sum::<f64>() / k as f64
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]

        /// The shortcut through neighbouring slots flags exactly the samples whose mean
        /// distance to their `k` nearest exceeds `isolation ×` the spacing, with duplicates,
        /// clusters and lone samples mixed.
        #[test]
        fn isolated_samples_match_the_definition(
            surface in 40usize..2500,
            outliers in 0usize..60,
            duplicates in 0usize..20,
            clusters in proptest::collection::vec((0usize..8, 0.35f64..0.5, 8usize..18), 0..4),
            isolation in 1.5f64..6.0,
            seed in 0u64..1000,
        ) {
            let mut cloud = sphere(DVec3::ZERO, 0.3, surface);
            add_position_noise(&mut cloud, 0.002, seed);
            add_uniform_outliers(&mut cloud, outliers, DVec3::splat(-0.5), DVec3::splat(0.5), seed + 1);
            let mut points = cloud.positions;
            for j in 0..duplicates {
                points.push(points[(j * 7 + seed as usize) % points.len()]);
            }
            // Small tight clusters in the corners, away from the sphere: their samples have
            // close neighbours, yet about `k` or fewer.
            for (c, &(corner, at, size)) in clusters.iter().enumerate() {
                let sign = |bit: usize| if corner >> bit & 1 == 1 { at } else { -at };
                let mut cluster = sphere(DVec3::new(sign(0), sign(1), sign(2)), 0.01, size);
                add_position_noise(&mut cluster, 0.005, seed + 2 + c as u64);
                points.extend(cluster.positions);
            }
            let index = PointIndex::new(&points).unwrap();
            let params = ScanStatisticsParams { isolation, ..ScanStatisticsParams::default() };
            let stats = scan_statistics(&points, None, &index, &params);
            let limit = isolation * stats.spacing;
            for i in 0..points.len() {
                let mean = brute_mean_distance(&points, i, params.k);
                if (mean - limit).abs() <= 1e-9 * limit {
                    continue; // a tie up to rounding
                }
                proptest::prop_assert_eq!(stats.isolated[i], mean > limit, "sample {} mean {} limit {}", i, mean, limit);
            }
            proptest::prop_assert_eq!(stats.isolated_count, stats.isolated.iter().filter(|&&o| o).count());
        }
    }

    #[test]
    fn tiny_scans_have_no_statistics() {
        let points = vec![DVec3::ZERO, DVec3::X, DVec3::Y];
        let index = PointIndex::new(&points).unwrap();
        let stats = scan_statistics(&points, None, &index, &ScanStatisticsParams::default());
        assert_eq!(
            (stats.spacing, stats.noise, stats.isolated.len()),
            (0.0, 0.0, 3)
        );
    }

    #[test]
    fn one_view_is_told_by_the_normals_facing_one_side() {
        let cloud = sphere(DVec3::ZERO, 0.4, 4000);
        let normals = cloud.normals.clone().unwrap();
        let index = PointIndex::new(&cloud.positions).unwrap();
        let params = ScanStatisticsParams::default();
        // A closed sphere: half of its normals face any side.
        assert!(!scan_statistics(&cloud.positions, Some(&normals), &index, &params).one_view);
        // What one camera on +z sees of it.
        let seen: Vec<usize> = (0..cloud.len()).filter(|&i| normals[i].z > 0.1).collect();
        let points: Vec<DVec3> = seen.iter().map(|&i| cloud.positions[i]).collect();
        let facing: Vec<DVec3> = seen.iter().map(|&i| normals[i]).collect();
        let index = PointIndex::new(&points).unwrap();
        assert!(scan_statistics(&points, Some(&facing), &index, &params).one_view);
        // Without normals nothing is known; neither from a handful.
        assert!(!scan_statistics(&points, None, &index, &params).one_view);
        assert!(!one_view(&facing[..10]));
    }

    proptest::proptest! {
        #[test]
        fn one_view_does_not_depend_on_the_frame_or_the_sign_of_the_normals(
            axis in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
            angle in 0.0f64..std::f64::consts::TAU,
            spread in 0.2f64..2.5,
            seed in 0u64..1000,
        ) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            // Normals within `spread` radians of +z: one side up to π/2.
            let normals: Vec<DVec3> = (0..500)
                .map(|_| {
                    let (polar, azimuth) =
                        (rng.random::<f64>() * spread, rng.random::<f64>() * std::f64::consts::TAU);
                    DVec3::new(polar.sin() * azimuth.cos(), polar.sin() * azimuth.sin(), polar.cos())
                })
                .collect();
            let expected = one_view(&normals);
            if spread < 1.5 {
                proptest::prop_assert!(expected);
            }
            let rotation = glam::DQuat::from_axis_angle(
                DVec3::new(axis.0, axis.1, axis.2).try_normalize().unwrap_or(DVec3::X),
                angle,
            );
            let turned: Vec<DVec3> = normals.iter().map(|&n| rotation * n).collect();
            proptest::prop_assert_eq!(one_view(&turned), expected);
            let flipped: Vec<DVec3> = normals.iter().map(|&n| -n).collect();
            proptest::prop_assert_eq!(one_view(&flipped), expected);
        }
    }
}
