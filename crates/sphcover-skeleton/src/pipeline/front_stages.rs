//! The stages up to the intensity cover of a volume: intensity model, object mask, cover.
//! Scattered samples have their own ([`crate::from_samples`]); both end in a
//! [`CoverStage`].

use sphcover_core::{Cover, Stage, Threshold, Volume, VolumeCoverParams, VolumeCoverStats};

use super::{SkeletonParams, voxel_length};
use crate::error::SkeletonError;
use crate::gaussian_filter::smoothed_values;
use crate::intensity_model::{IntensityModel, OTSU_SMOOTHING, estimate_with_smoothed};
use crate::material::{
    Material, MaterialCandidate, MaterialChoice, MaterialReport, THIN_DEPTH, ct_levels, depth_p90,
    windowed_volume,
};
use crate::object_mask::{ObjectMaskStats, drop_small_object_components};

/// What the stages up to the cover produced, for the stages after it.
pub(crate) struct CoverStage {
    pub material: Option<MaterialReport>,
    pub intensity: IntensityModel,
    pub tolerance: f64,
    pub object_mask: ObjectMaskStats,
    pub cover_stats: VolumeCoverStats,
    /// The length unit of the voxel-based parameters (world units).
    pub voxel: f64,
    pub cover: Cover,
}

/// The intensity cover's parameters: the model's threshold, the tolerance ε, and the
/// caller's radii, kernel and seed.
pub(crate) fn intensity_cover_params(
    params: &SkeletonParams,
    intensity: &IntensityModel,
    tolerance: f64,
) -> VolumeCoverParams {
    VolumeCoverParams {
        threshold: Threshold::Raw(intensity.threshold),
        tolerance,
        r_min: params.r_min,
        r_max: params.r_max,
        kernel: params.kernel,
        seed: params.seed,
        // The sheet needs the dense thesis cover: without its redundant supports the dual
        // complex is too sparse (measured on the phantoms: coverage 0.64–0.81, 8–36 pieces).
        elimination: sphcover_core::Elimination::Off,
        ..VolumeCoverParams::default()
    }
}

/// What the front stages of a volume share.
pub(super) struct VolumeFront<'a> {
    volume: &'a Volume,
    params: &'a SkeletonParams,
    /// The largest factor the volume was resampled by along an axis (1 when it was not).
    resampling_factor: usize,
    material: Option<MaterialReport>,
    /// The volume windowed to the chosen material, when the input is a CT with materials.
    windowed: Option<Volume>,
    intensity: Option<IntensityModel>,
    tolerance: f64,
    /// The (windowed) volume with its noise specks lowered below the threshold, when it had
    /// any.
    cleaned: Option<Volume>,
    object_mask: ObjectMaskStats,
    cover: Option<(Cover, VolumeCoverStats)>,
}

impl<'a> VolumeFront<'a> {
    pub fn new(
        volume: &'a Volume,
        params: &'a SkeletonParams,
        resampling_factor: usize,
    ) -> VolumeFront<'a> {
        VolumeFront {
            volume,
            params,
            resampling_factor,
            material: None,
            windowed: None,
            intensity: None,
            tolerance: 0.0,
            cleaned: None,
            object_mask: ObjectMaskStats::default(),
            cover: None,
        }
    }

    fn intensity(&self) -> &IntensityModel {
        super::built(self.intensity.as_ref(), "intensity model")
    }

    /// The volume the threshold applies to: the input, or its material window.
    fn source(&self) -> &Volume {
        self.windowed.as_ref().unwrap_or(self.volume)
    }

    /// The volume the cover is built on.
    fn volume(&self) -> &Volume {
        self.cleaned.as_ref().unwrap_or_else(|| self.source())
    }

    /// The product of the front stages, once they have all run.
    pub fn finish(self) -> Result<CoverStage, SkeletonError> {
        let voxel = voxel_length(self.volume);
        let (cover, cover_stats) = super::built(self.cover, "cover");
        Ok(CoverStage {
            material: self.material,
            intensity: super::built(self.intensity, "intensity model"),
            tolerance: self.tolerance,
            object_mask: self.object_mask,
            cover_stats,
            voxel,
            cover,
        })
    }
}

/// The front stages of a volume, in order.
pub(super) fn volume_front_stages<'a>() -> Vec<Stage<VolumeFront<'a>, SkeletonError>> {
    vec![
        Stage::new("intensity model", intensity_model),
        Stage::new("object mask", object_mask),
        Stage::new("cover", cover),
    ]
}

/// The material (on a CT in Hounsfield units) and its window, then the histogram, threshold
/// (the material's, the caller's or the two-class one) and noise; the fit tolerance ε.
fn intensity_model(ctx: &mut VolumeFront<'_>) -> Result<(), SkeletonError> {
    let (threshold, smooth) = choose_material(ctx)?;
    let mut intensity = estimate_with_smoothed(ctx.source(), threshold, smooth.as_deref())?;
    if ctx
        .material
        .as_ref()
        .is_some_and(|m| m.automatic && m.material.is_some())
    {
        intensity.automatic_threshold = true;
    }
    ctx.tolerance = ctx
        .params
        .tolerance
        .unwrap_or_else(|| intensity.tolerance(ctx.params.model_tolerance));
    ctx.intensity = Some(intensity);
    Ok(())
}

/// Noise specks above the threshold dropped; on noisy volumes, object voxels must also
/// exceed the threshold in the volume smoothed by one voxel.
fn object_mask(ctx: &mut VolumeFront<'_>) -> Result<(), SkeletonError> {
    let intensity = ctx.intensity();
    let bound = ctx.params.smooth_mask_noise / ctx.resampling_factor as f64;
    let smooth = (intensity.noise_std > bound * intensity.contrast().abs())
        .then(|| smoothed_values(ctx.source(), 1.0, intensity.value_range.0));
    let (cleaned, mask) = drop_small_object_components(
        ctx.source(),
        intensity.threshold,
        ctx.params.min_object_fraction,
        smooth.as_deref(),
    );
    ctx.cleaned = cleaned;
    ctx.object_mask = mask;
    Ok(())
}

/// The intensity cover (thesis §3.4.2): quadratic local fits, automatic radii.
fn cover(ctx: &mut VolumeFront<'_>) -> Result<(), SkeletonError> {
    let cover_params = intensity_cover_params(ctx.params, ctx.intensity(), ctx.tolerance);
    ctx.cover = Some(sphcover_core::build_volume_cover(
        ctx.volume(),
        &cover_params,
    )?);
    Ok(())
}

/// On a CT in Hounsfield units (see [`crate::material`]), the material's threshold and
/// window: the caller's threshold, the given material's, or the first thin material's.
/// Returns the threshold for the intensity model (`None`: its two-class threshold), and the
/// smoothed input for that threshold when the volume is the input (not a CT).
fn choose_material(
    ctx: &mut VolumeFront<'_>,
) -> Result<(Option<f64>, Option<Vec<f64>>), SkeletonError> {
    let (params, volume) = (ctx.params, ctx.volume);
    if params.material == MaterialChoice::Off {
        return Ok((params.threshold, None));
    }
    let (lo, _) = volume.value_range().ok_or(SkeletonError::NoFiniteValue)?;
    let smooth = smoothed_values(volume, OTSU_SMOOTHING, lo);
    let Some(levels) = ct_levels(&smooth) else {
        return match params.material {
            MaterialChoice::Given(m) => Err(SkeletonError::NotHounsfield { material: m.name() }),
            _ => Ok((params.threshold, Some(smooth))),
        };
    };
    let thin_depth = THIN_DEPTH * volume.voxel_size().min_element();
    let mut candidates = Vec::new();
    let (material, automatic) = match (params.threshold, params.material) {
        (Some(_), _) => (None, false),
        (None, MaterialChoice::Given(m)) => (Some(m), false),
        (None, _) => {
            let thin = Material::ALL.into_iter().find(|&m| {
                let threshold = m.threshold(&levels);
                let depth = depth_p90(volume, &smooth, threshold);
                candidates.push(MaterialCandidate {
                    material: m,
                    threshold,
                    depth_p90: depth,
                });
                depth.is_some_and(|d| d <= thin_depth)
            });
            (thin, true)
        }
    };
    let threshold = params
        .threshold
        .or_else(|| material.map(|m| m.threshold(&levels)));
    let window = threshold.and_then(|t| levels.window(t));
    if let Some(window) = window {
        ctx.windowed = Some(windowed_volume(volume, window));
    }
    ctx.material = Some(MaterialReport {
        levels,
        material,
        automatic,
        candidates,
        window,
        thin_depth,
    });
    // A material's threshold is given to the intensity model; without one, the two-class
    // threshold is of the input, whose smoothing is at hand.
    let smooth = (ctx.windowed.is_none()).then_some(smooth);
    Ok((threshold, smooth))
}
