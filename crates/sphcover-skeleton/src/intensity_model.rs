//! Automatic threshold and tolerance from the intensity histogram: a threshold between
//! background and object placed from Otsu's split, the two class levels (the contrast), and the noise level
//! from the background's median absolute deviation.
//!
//! The method is described on [`IntensityModel`].

use sphcover_core::{ParameterError, Volume};

use crate::error::SkeletonError;
use crate::gaussian_filter::smoothed_values;

/// Standard deviation (voxels) of the smoothing before Otsu's method.
pub(crate) const OTSU_SMOOTHING: f64 = 1.0;
/// Bins of the Otsu histogram.
const OTSU_BINS: usize = 1024;
/// `1 / Φ⁻¹(3/4)`: turns a median absolute deviation into a Gaussian standard deviation.
const MAD_TO_STD: f64 = 1.482_602_218_505_602;

/// What the intensity histogram says about a CT volume.
///
/// The automatic threshold works on the volume smoothed by a Gaussian of `OTSU_SMOOTHING`
/// voxels: a thin part is a few percent of the voxels, and on a noisy image (30 % of the
/// contrast) the wide air peak drags Otsu's split deep into its own tail (−460 HU between
/// air at −1000 and material at +2000 on the phantoms), selecting a fifth of the air.
/// Smoothing narrows the peaks (Otsu then splits near −30 HU, still low because of the
/// class imbalance), and `midpoint_threshold` moves the split to half the contrast. The noise is the
/// median absolute deviation of the air *below* its median, which contains no material and
/// no partial-volume voxel, so it is not biased by the object or by the threshold.
///
/// The cover's fit tolerance ε (thesis §3.4.2, an RMS residual) must exceed the noise, or
/// every support shrinks to its smallest ball: the RMS of a least-squares fit to pure noise
/// of standard deviation `s` is about `s`. So ε is the root sum of squares of the noise and
/// a model tolerance proportional to the contrast (5 % of it by default, the thesis value on
/// noise-free data).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntensityModel {
    /// Smallest and largest finite value.
    pub value_range: (f64, f64),
    /// Object voxels are those with a value above this (volume units).
    pub threshold: f64,
    /// True when the threshold was chosen automatically (around Otsu's split) rather than
    /// given by the caller.
    pub automatic_threshold: bool,
    /// Median of the voxels at or below the threshold.
    pub background_level: f64,
    /// Median of the voxels above the threshold.
    pub object_level: f64,
    /// Noise standard deviation estimated from the background (volume units).
    pub noise_std: f64,
    /// Voxels above the threshold.
    pub object_voxels: usize,
}

impl IntensityModel {
    /// `object_level − background_level`.
    pub fn contrast(&self) -> f64 {
        self.object_level - self.background_level
    }

    /// The fit tolerance ε in the cover's normalised units (fractions of the value range):
    /// `√(noise² + (model_fraction · contrast)²) / range`.
    pub fn tolerance(&self, model_fraction: f64) -> f64 {
        let model = model_fraction * self.contrast().abs();
        let range = self.value_range.1 - self.value_range.0;
        (self.noise_std.hypot(model) / range).max(1e-6)
    }
}

/// Estimates the [`IntensityModel`] of `volume`, with the caller's threshold or Otsu's.
pub fn estimate_intensity_model(
    volume: &Volume,
    threshold: Option<f64>,
) -> Result<IntensityModel, SkeletonError> {
    estimate_with_smoothed(volume, threshold, None)
}

/// [`estimate_intensity_model`], reusing `smooth` (the volume smoothed by `OTSU_SMOOTHING`
/// voxels with non-finite values at the lowest value) when the caller has it already.
pub(crate) fn estimate_with_smoothed(
    volume: &Volume,
    threshold: Option<f64>,
    smooth: Option<&[f64]>,
) -> Result<IntensityModel, SkeletonError> {
    let (lo, hi) = volume.value_range().ok_or(SkeletonError::NoFiniteValue)?;
    let automatic = || match smooth {
        Some(smooth) => midpoint_threshold(smooth, lo, hi),
        None => midpoint_threshold(&smoothed_values(volume, OTSU_SMOOTHING, lo), lo, hi),
    };
    model_from_values(
        (0..volume.len()).map(|i| volume.value(i)),
        (lo, hi),
        threshold,
        automatic,
    )
}

/// Estimates the [`IntensityModel`] of scattered samples' `values`, with the caller's
/// threshold or `midpoint_threshold` of the `smooth`ed values (the samples' counterpart of
/// the volume's smoothing by `OTSU_SMOOTHING` voxels).
pub fn estimate_sample_intensity_model(
    values: &[f64],
    smooth: &[f64],
    threshold: Option<f64>,
) -> Result<IntensityModel, SkeletonError> {
    let (lo, hi) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold(None, |range: Option<(f64, f64)>, &v| {
            Some(range.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))))
        })
        .ok_or(SkeletonError::NoFiniteValue)?;
    let automatic = || midpoint_threshold(smooth, lo, hi);
    model_from_values(values.iter().copied(), (lo, hi), threshold, automatic)
}

/// The class levels and the noise of `values` split at the caller's threshold, or at
/// `automatic()` when none is given.
fn model_from_values(
    values: impl Iterator<Item = f64>,
    (lo, hi): (f64, f64),
    threshold: Option<f64>,
    automatic: impl FnOnce() -> f64,
) -> Result<IntensityModel, SkeletonError> {
    if lo == hi {
        return Err(SkeletonError::ConstantVolume { value: lo });
    }
    let (threshold, automatic_threshold) = match threshold {
        Some(t) if t.is_nan() => {
            return Err(SkeletonError::InvalidParameter(ParameterError {
                name: "threshold",
                value: t,
                expected: "must be a number",
            }));
        }
        Some(t) => (t, false),
        None => (automatic(), true),
    };
    let mut background = Vec::new();
    let mut object = Vec::new();
    for v in values.filter(|v| v.is_finite()) {
        if v > threshold {
            object.push(v);
        } else {
            background.push(v);
        }
    }
    if object.is_empty() {
        return Err(SkeletonError::ThresholdSelectsNothing {
            threshold,
            min: lo,
            max: hi,
        });
    }
    if background.is_empty() {
        return Err(SkeletonError::ThresholdSelectsEverything {
            threshold,
            min: lo,
            max: hi,
        });
    }
    let background_level = median(&mut background);
    let object_level = median(&mut object);
    let mut deviations: Vec<f64> = background
        .iter()
        .filter(|&&v| v < background_level)
        .map(|v| background_level - v)
        .collect();
    if deviations.is_empty() {
        deviations.push(0.0);
    }
    let noise_std = MAD_TO_STD * median(&mut deviations);
    Ok(IntensityModel {
        value_range: (lo, hi),
        threshold,
        automatic_threshold,
        background_level,
        object_level,
        noise_std,
        object_voxels: object.len(),
    })
}

/// The automatic threshold: halfway between the background level (median of the smoothed
/// values below Otsu's split) and the object level (upper quartile of those above it).
///
/// Otsu's split alone is pulled towards the air peak when the part is a few percent of the
/// volume; the upper quartile of the upper class sits on the part's plateau instead of its
/// partial-volume shell, so the midpoint lands near half the contrast, where the rendered
/// surface of a blurred solid lies.
pub(crate) fn midpoint_threshold(smooth: &[f64], lo: f64, hi: f64) -> f64 {
    let split = otsu_threshold(smooth, lo, hi);
    let (mut below, mut above): (Vec<f64>, Vec<f64>) = smooth
        .iter()
        .filter(|v| v.is_finite())
        .partition(|&&v| v <= split);
    if below.is_empty() || above.is_empty() {
        return split;
    }
    let background = median(&mut below);
    let q = (3 * above.len()) / 4;
    let object = *above.select_nth_unstable_by(q, f64::total_cmp).1;
    0.5 * (background + object)
}

/// Otsu's threshold over a histogram of the finite values in `[lo, hi]`: the bin edge that
/// maximises the between-class variance. Counts are integers, so the result does not depend
/// on summation order.
pub fn otsu_threshold(values: &[f64], lo: f64, hi: f64) -> f64 {
    let mut counts = vec![0u64; OTSU_BINS];
    let scale = OTSU_BINS as f64 / (hi - lo);
    for &v in values {
        if v.is_finite() {
            let bin = (((v - lo) * scale).max(0.0) as usize).min(OTSU_BINS - 1);
            counts[bin] += 1;
        }
    }
    let total: u64 = counts.iter().sum();
    let weighted_total: f64 = counts
        .iter()
        .enumerate()
        .map(|(b, &c)| b as f64 * c as f64)
        .sum();
    let (mut below, mut weighted_below) = (0u64, 0.0);
    let (mut best, mut best_bin) = (-1.0, OTSU_BINS / 2);
    for (b, &c) in counts.iter().enumerate().take(OTSU_BINS - 1) {
        below += c;
        weighted_below += b as f64 * c as f64;
        let above = total - below;
        if below == 0 || above == 0 {
            continue;
        }
        let mean_below = weighted_below / below as f64;
        let mean_above = (weighted_total - weighted_below) / above as f64;
        let between = below as f64 * above as f64 * (mean_above - mean_below).powi(2);
        if between > best {
            best = between;
            best_bin = b;
        }
    }
    lo + (best_bin + 1) as f64 / scale
}

/// The median (upper median for even lengths); reorders `values`.
fn median(values: &mut [f64]) -> f64 {
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::{DVec3, VoxelValues};

    fn two_level(n: usize, object_every: usize, noise: impl Fn(usize) -> f64) -> Volume {
        let values = (0..n * n * n)
            .map(|i| {
                let base = if i % object_every == 0 {
                    2000.0
                } else {
                    -1000.0
                };
                base + noise(i)
            })
            .collect();
        Volume::axis_aligned([n, n, n], VoxelValues::F64(values), DVec3::ONE, DVec3::ZERO).unwrap()
    }

    #[test]
    fn otsu_separates_two_levels() {
        let v = two_level(10, 7, |_| 0.0);
        let m = estimate_intensity_model(&v, None).unwrap();
        assert!(m.threshold > -1000.0 && m.threshold < 2000.0);
        assert_eq!(m.object_voxels, (0..1000).filter(|i| i % 7 == 0).count());
        assert_eq!(m.contrast(), 3000.0);
        assert_eq!(m.noise_std, 0.0);
    }

    #[test]
    fn noise_estimate_follows_the_noise() {
        // A deterministic pattern −100, 0, 0, +100: the air below its median deviates by 100.
        let v = two_level(12, 9, |i| [-100.0, 0.0, 0.0, 100.0][(i / 3) % 4]);
        let m = estimate_intensity_model(&v, None).unwrap();
        assert!(
            (m.noise_std - 100.0 * MAD_TO_STD).abs() < 1e-9,
            "{}",
            m.noise_std
        );
    }

    #[test]
    fn thresholds_selecting_nothing_or_everything_are_refused() {
        let v = two_level(6, 5, |_| 0.0);
        assert!(matches!(
            estimate_intensity_model(&v, Some(5000.0)),
            Err(SkeletonError::ThresholdSelectsNothing { .. })
        ));
        assert!(matches!(
            estimate_intensity_model(&v, Some(-5000.0)),
            Err(SkeletonError::ThresholdSelectsEverything { .. })
        ));
        assert!(matches!(
            estimate_intensity_model(&v, Some(f64::NAN)),
            Err(SkeletonError::InvalidParameter(_))
        ));
    }
}
