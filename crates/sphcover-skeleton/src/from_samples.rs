//! The skeletal sheet of scattered samples with values (points off any grid, each carrying
//! an intensity), which image-based ridge detection cannot take: the intensity cover is
//! built on the samples themselves ([`build_scattered_cover`], thesis §3.4.2 without the
//! lattice), and every later stage is the volume pipeline's.

use std::time::Instant;

use rayon::prelude::*;
use sphcover_core::volume_cover::median_nearest_distance;
use sphcover_core::{DVec3, PointIndex, TriMesh, VolumeCoverError, build_scattered_cover};

use crate::error::SkeletonError;
use crate::intensity_model::{OTSU_SMOOTHING, estimate_sample_intensity_model};
use crate::object_mask::{ObjectMaskStats, lower_specks};
use crate::pipeline::{
    CoverStage, SkeletonParams, SkeletonStats, SkeletonTimings, check_params,
    intensity_cover_params, sheet_from_cover,
};

/// The automatic tolerance's model part on scattered samples, relative to a volume's
/// ([`SkeletonParams::model_tolerance`]). A cover of irregular samples at the volume's ε has
/// a third fewer supports than a grid's (jittered samples let larger balls pass the RMS
/// test), and its dual complex is then too sparse to carry the sheet everywhere. Measured on
/// seven in ten voxels of the curved plate, the plate with a hole and the wedge (10 %
/// noise), and on jittered samples of a flat plate: at factor 1, 2 / 2 / 1 / 1–3 components
/// and coverage 0.94–0.99; at 0.7, 1 / 1 / 1 / 1–2; at 0.5, one component with the true
/// Euler characteristic everywhere and coverage ≥ 0.996, at 1.6× the supports.
pub const SAMPLE_MODEL_TOLERANCE_FACTOR: f64 = 0.5;

/// Extracts the skeletal sheet of the thin object sampled by `positions` with intensity
/// `values` (one per position), as [`crate::extract_skeleton`] does for a volume.
///
/// The lengths [`SkeletonParams`] gives in voxels are in units of the median distance from
/// a sample to its nearest neighbour (the voxel edge of the equivalent grid, see
/// [`VolumeCoverStats::sample_spacing`](sphcover_core::VolumeCoverStats::sample_spacing)).
/// The automatic tolerance is tighter than a volume's (see
/// [`SAMPLE_MODEL_TOLERANCE_FACTOR`]). The volume pipeline's grid steps have scattered
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
/// let (sheet, stats) = extract_skeleton_from_samples(&positions, &values, &SkeletonParams::default())?;
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
) -> Result<(TriMesh, SkeletonStats), SkeletonError> {
    check_params(params)?;
    if positions.len() != values.len() {
        return Err(VolumeCoverError::SampleCountMismatch {
            positions: positions.len(),
            values: values.len(),
        }
        .into());
    }
    let mut timings = SkeletonTimings::default();

    let start = Instant::now();
    let index = PointIndex::new(positions).map_err(|_| VolumeCoverError::TooManyVoxels {
        voxels: positions.len(),
    })?;
    // 1 when more than half the samples coincide: the cover refuses them.
    let spacing = median_nearest_distance(&index, positions).unwrap_or(1.0);
    let smooth = smoothed_sample_values(&index, positions, values, OTSU_SMOOTHING * spacing);
    let intensity = estimate_sample_intensity_model(values, &smooth, params.threshold)?;
    let tolerance = params.tolerance.unwrap_or_else(|| {
        intensity.tolerance(SAMPLE_MODEL_TOLERANCE_FACTOR * params.model_tolerance)
    });
    timings.intensity_model = start.elapsed();

    let start = Instant::now();
    let noisy = intensity.noise_std > params.smooth_mask_noise * intensity.contrast().abs();
    let (values, object_mask) = drop_sample_specks(
        &index,
        positions,
        values,
        intensity.threshold,
        params.min_object_fraction,
        noisy.then_some(smooth.as_slice()),
        SPECK_NEIGHBOUR_DISTANCE * spacing,
    );
    drop(smooth);
    timings.object_mask = start.elapsed();

    let start = Instant::now();
    let cover_params = intensity_cover_params(params, &intensity, tolerance);
    let (cover, cover_stats) = build_scattered_cover(positions, &values, &cover_params)?;
    drop(values);
    timings.cover = start.elapsed();
    let front = CoverStage {
        intensity,
        tolerance,
        object_mask,
        // The spacing is the voxel diagonal of the equivalent cubic grid.
        voxel: cover_stats.sample_spacing / 3f64.sqrt(),
        cover: cover_stats,
        timings,
    };
    sheet_from_cover(cover, front, params)
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
