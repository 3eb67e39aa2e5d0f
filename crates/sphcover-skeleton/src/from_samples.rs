//! The skeletal sheet of scattered samples with values (points off any grid, each carrying
//! an intensity), which image-based ridge detection cannot take: the intensity cover is
//! built on the samples themselves ([`build_scattered_cover`], thesis §3.4.2 without the
//! lattice), and every later stage is the volume pipeline's.

use rayon::prelude::*;
use sphcover_core::{
    Cover, DVec3, PointIndex, Stage, StageProgress, StopRequest, TriMesh, VolumeCoverError,
    VolumeCoverStats, build_scattered_cover, median_nearest_distance, run_stages_until,
};

use crate::error::SkeletonError;
use crate::intensity_model::{IntensityModel, OTSU_SMOOTHING, estimate_sample_intensity_model};
use crate::object_mask::{ObjectMaskStats, lower_specks};
use crate::pipeline::{
    CoverStage, SkeletonParams, SkeletonStats, check_params, intensity_cover_params, offset,
    sheet_from_cover, sheet_stage_list,
};

/// The automatic tolerance's model part on scattered samples, relative to a volume's
/// ([`SkeletonParams::model_tolerance`]). A cover of irregular samples at the volume's ε has
/// a third fewer supports than a grid's (jittered samples let larger balls pass the RMS
/// test), and its dual complex is then too sparse to carry the sheet everywhere. Measured on
/// seven in ten voxels of the curved plate, the plate with a hole and the wedge (10 %
/// noise), and on jittered samples of a flat plate: at factor 1, 2 / 2 / 1 / 1–3 components
/// and coverage 0.94–0.99; at 0.7, 1 / 1 / 1 / 1–2; at 0.5, one component with the true
/// Euler characteristic everywhere and coverage ≥ 0.996, at 1.6× the supports.
pub(crate) const SAMPLE_MODEL_TOLERANCE_FACTOR: f64 = 0.5;

/// Extracts the skeletal sheet of the thin object sampled by `positions` with intensity
/// `values` (one per position), as [`crate::extract_skeleton`] does for a volume, with the
/// same stages ([`crate::stage_names`]) and `progress`.
///
/// The lengths [`SkeletonParams`] gives in voxels are in units of the median distance from
/// a sample to its nearest neighbour (the voxel edge of the equivalent grid, see
/// [`VolumeCoverStats::sample_spacing`](sphcover_core::VolumeCoverStats::sample_spacing)).
/// The automatic tolerance is tighter than a volume's (see
/// `SAMPLE_MODEL_TOLERANCE_FACTOR`). The volume pipeline's grid steps have scattered
/// counterparts: the Gaussian smoothing (before the automatic threshold, and for the
/// smoothed object mask on noisy data) is a Gaussian-weighted mean over the samples within
/// three standard deviations, and the 26-neighbourhood of the speck test is the sample
/// pairs closer than a voxel diagonal.
///
/// ```
/// use sphcover_core::DVec3;
/// use sphcover_skeleton::{SkeletonParams, extract_skeleton_from_samples};
///
/// // Jittered samples of a plate 4 units thick (z = 6 … 10), its faces blurred over about
/// // one unit, as a scanner without a grid (or a resampled mesh) might deliver them.
/// let mut positions = Vec::new();
/// let mut values = Vec::new();
/// let mut state = 7u64;
/// let mut jitter = || {
///     state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
///     ((state >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 0.6
/// };
/// for k in 0..16 {
///     for j in 0..24 {
///         for i in 0..24 {
///             let p = DVec3::new(i as f64 + jitter(), j as f64 + jitter(), k as f64 + jitter());
///             let inside = 2.0 - (p.z - 8.0).abs();
///             positions.push(p);
///             values.push(500.0 * (1.0 + (inside / 0.8).tanh()));
///         }
///     }
/// }
/// let (sheet, stats) = extract_skeleton_from_samples(&positions, &values, &SkeletonParams::default(), &|_| {})?;
/// assert_eq!(stats.components, 1);
/// // The sheet lies on the plate's mid-plane z = 8, within a tenth of the spacing on average.
/// let n = sheet.vertices.len() as f64;
/// assert!(sheet.vertices.iter().map(|v| (v.z - 8.0).abs()).sum::<f64>() / n < 0.1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn extract_skeleton_from_samples(
    positions: &[DVec3],
    values: &[f64],
    params: &SkeletonParams,
    progress: &(dyn Fn(StageProgress) + Sync),
) -> Result<(TriMesh, SkeletonStats), SkeletonError> {
    extract_skeleton_from_samples_until(positions, values, params, progress, &StopRequest::new())
}

/// [`extract_skeleton_from_samples`], ending with [`SkeletonError::Stopped`] before the first
/// stage that starts after `stop` was requested.
pub fn extract_skeleton_from_samples_until(
    positions: &[DVec3],
    values: &[f64],
    params: &SkeletonParams,
    progress: &(dyn Fn(StageProgress) + Sync),
    stop: &StopRequest,
) -> Result<(TriMesh, SkeletonStats), SkeletonError> {
    check_params(params)?;
    if positions.len() != values.len() {
        return Err(VolumeCoverError::SampleCountMismatch {
            positions: positions.len(),
            values: values.len(),
        }
        .into());
    }
    let front: [Stage<SampleFront<'_>, SkeletonError>; 3] = [
        Stage::new("intensity model", intensity_model),
        Stage::new("object mask", object_mask),
        Stage::new("cover", cover),
    ];
    let count = front.len() + sheet_stage_list(params).len();
    let mut ctx = SampleFront {
        positions,
        values,
        params,
        index: None,
        spacing: 1.0,
        smooth: Vec::new(),
        intensity: None,
        tolerance: 0.0,
        lowered: None,
        object_mask: ObjectMaskStats::default(),
        cover: None,
    };
    let times = run_stages_until(&mut ctx, &front, &offset(progress, 0, count), stop)?;
    let (cover, cover_stats) = built(ctx.cover, "cover");
    let front = CoverStage {
        material: None,
        intensity: built(ctx.intensity, "intensity model"),
        tolerance: ctx.tolerance,
        object_mask: ctx.object_mask,
        // The spacing is the voxel diagonal of the equivalent cubic grid.
        voxel: cover_stats.sample_spacing / 3f64.sqrt(),
        cover_stats,
        cover,
    };
    sheet_from_cover(front, None, None, false, times, params, progress, stop)
}

/// What the front stages of scattered samples share.
struct SampleFront<'a> {
    positions: &'a [DVec3],
    values: &'a [f64],
    params: &'a SkeletonParams,
    index: Option<PointIndex>,
    /// Median distance from a sample to its nearest neighbour.
    spacing: f64,
    /// The values smoothed over about a spacing, until the object mask is made.
    smooth: Vec<f64>,
    intensity: Option<IntensityModel>,
    tolerance: f64,
    /// The values with the specks lowered to the threshold.
    lowered: Option<Vec<f64>>,
    object_mask: ObjectMaskStats,
    cover: Option<(Cover, VolumeCoverStats)>,
}

/// An intermediate that an earlier front stage builds.
fn built<T>(slot: Option<T>, what: &str) -> T {
    slot.unwrap_or_else(|| panic!("the front stages build the {what} before it is used"))
}

/// The samples' spacing and smoothed values; the threshold (Otsu's on the smoothed values
/// unless given), the noise and the fit tolerance ε.
fn intensity_model(ctx: &mut SampleFront<'_>) -> Result<(), SkeletonError> {
    let (positions, values, params) = (ctx.positions, ctx.values, ctx.params);
    let index = PointIndex::new(positions).map_err(|_| VolumeCoverError::TooManyVoxels {
        voxels: positions.len(),
    })?;
    // 1 when more than half the samples coincide: the cover refuses them.
    ctx.spacing = median_nearest_distance(&index, positions).unwrap_or(1.0);
    ctx.smooth = smoothed_sample_values(&index, positions, values, OTSU_SMOOTHING * ctx.spacing);
    let intensity = estimate_sample_intensity_model(values, &ctx.smooth, params.threshold)?;
    ctx.tolerance = params.tolerance.unwrap_or_else(|| {
        intensity.tolerance(SAMPLE_MODEL_TOLERANCE_FACTOR * params.model_tolerance)
    });
    ctx.intensity = Some(intensity);
    ctx.index = Some(index);
    Ok(())
}

/// Specks above the threshold lowered to it (the volume pipeline's object mask).
fn object_mask(ctx: &mut SampleFront<'_>) -> Result<(), SkeletonError> {
    let intensity = built(ctx.intensity.as_ref(), "intensity model");
    let index = built(ctx.index.as_ref(), "sample index");
    let noisy = intensity.noise_std > ctx.params.smooth_mask_noise * intensity.contrast().abs();
    let (values, object_mask) = drop_sample_specks(
        index,
        ctx.positions,
        ctx.values,
        intensity.threshold,
        ctx.params.min_object_fraction,
        noisy.then_some(ctx.smooth.as_slice()),
        SPECK_NEIGHBOUR_DISTANCE * ctx.spacing,
    );
    ctx.smooth = Vec::new();
    ctx.lowered = Some(values);
    ctx.object_mask = object_mask;
    Ok(())
}

/// The intensity cover of the samples (thesis §3.4.2 without the lattice).
fn cover(ctx: &mut SampleFront<'_>) -> Result<(), SkeletonError> {
    let intensity = built(ctx.intensity.as_ref(), "intensity model");
    let cover_params = intensity_cover_params(ctx.params, intensity, ctx.tolerance);
    let values = built(ctx.lowered.take(), "object mask");
    ctx.cover = Some(build_scattered_cover(
        ctx.positions,
        &values,
        &cover_params,
    )?);
    Ok(())
}

/// Samples closer than this many spacings are neighbours when the object's samples are
/// split into connected pieces: the diagonal of a voxel, as the 26-neighbourhood of a grid.
const SPECK_NEIGHBOUR_DISTANCE: f64 = 1.75;

/// Each sample's value replaced by the Gaussian-weighted mean (standard deviation `sigma`,
/// truncated at 3σ) of the finite values around it: the scattered counterpart of the
/// volume's smoothing before Otsu's method and of its smoothed mask.
fn smoothed_sample_values(
    index: &PointIndex,
    positions: &[DVec3],
    values: &[f64],
    sigma: f64,
) -> Vec<f64> {
    let scale = -0.5 / (sigma * sigma);
    positions
        .par_iter()
        .zip(values)
        .map(|(&p, &v)| {
            if !p.is_finite() {
                return v;
            }
            let (mut sum, mut weight) = (0.0, 0.0);
            index.for_each_within(p, 3.0 * sigma, |j, q| {
                let value = values[j as usize];
                if value.is_finite() {
                    let w = (scale * p.distance_squared(q)).exp();
                    sum += w * value;
                    weight += w;
                }
            });
            if weight > 0.0 { sum / weight } else { v }
        })
        .collect()
}

/// The samples' counterpart of [`crate::drop_small_object_components`]: samples above
/// `threshold` whose smoothed value is not (when `smooth` is given), and the pieces of the
/// object (samples within `neighbour` of each other) holding fewer than `min_fraction` of the
/// largest piece's samples, are lowered to the threshold.
fn drop_sample_specks(
    index: &PointIndex,
    positions: &[DVec3],
    values: &[f64],
    threshold: f64,
    min_fraction: f64,
    smooth: Option<&[f64]>,
    neighbour: f64,
) -> (Vec<f64>, ObjectMaskStats) {
    let neighbours = |i: usize, visit: &mut dyn FnMut(usize)| {
        index.for_each_within(positions[i], neighbour, |j, _| visit(j as usize));
    };
    let (lowered, stats) = lower_specks(
        values.len(),
        |i| values[i],
        threshold,
        min_fraction,
        smooth,
        neighbours,
    );
    (lowered.unwrap_or_else(|| values.to_vec()), stats)
}
