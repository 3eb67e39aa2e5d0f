//! Materials of a CT in Hounsfield units, and which of them is the thin part.
//!
//! A clinical CT holds several materials (air, fat, soft tissue, bone), and the two-class
//! threshold of [`IntensityModel`](crate::IntensityModel) splits the largest contrast, air
//! against everything else: the "thin part" is then the whole body. Hounsfield units are
//! calibrated (air −1000, water 0), so a CT is recognised from its histogram (a peak of air
//! and a peak of soft tissue near water, after smoothing by one voxel) and its materials
//! have known boundaries:
//!
//! * **bone**: above the soft-tissue level + 190 HU (226 HU at a soft-tissue level of
//!   +36 HU, the bone threshold of clinical segmentation tools), halfway from soft tissue to
//!   the least dense (cancellous) bone;
//! * **tissue**: above the midpoint of the air and soft-tissue levels (the skin).
//!
//! The automatic choice takes the first of these whose mask is thin: 90 % of its voxels
//! within [`THIN_DEPTH`] voxels of its surface.
//!
//! The material's mask is then what the skeleton is the mid-surface of, whatever lies inside
//! it: cortical bone (+1200…1500 HU) around a diploë (+400…650 HU) has its intensity ridges
//! on the two cortical tables, not in the middle of the bone. So the volume is *windowed*: the
//! values are clamped to `[below, threshold + (threshold − below)]`, where `below` is the
//! level of the material under the threshold, which makes the material a uniform solid with
//! the threshold at half its contrast; raised with the depth below the material's surface
//! ([`MATERIAL_CREST`]), so that parts of any thickness have a ridge in their middle; and
//! smoothed by [`MATERIAL_SMOOTHING`] voxels.

use rayon::prelude::*;
use sphcover_core::{Volume, VoxelValues, squared_depth_to_background};

use crate::gaussian_filter::gaussian_along;

/// A material mask thinner than this at its 90th percentile of depth (voxels of the smallest
/// edge) is a thin part: the vault of a skull is 2–8 mm thick (depth up to 4), a head is
/// 150 mm across.
pub const THIN_DEPTH: f64 = 6.0;
/// Rise of the windowed material per voxel of depth below its surface, as a fraction of the
/// window. A windowed part is a plateau, and a plateau wider than about four voxels has no
/// ridge in its middle (its Hessian vanishes there); the rise makes it a crest over the
/// medial surface whatever the thickness, and leaves the surface, where the depth is zero,
/// at the threshold. Measured on the generated head CT (clinical grid, seeds 1 and 2, with
/// [`MATERIAL_SMOOTHING`]): holes of over 20 mm perimeter in the vault's sheet 4 and 10
/// without it, 2 and 4 with 0.3; 13 and 13 with 0.2.
pub const MATERIAL_CREST: f64 = 0.3;
/// Smoothing (voxels of the smallest edge) of the windowed volume: it rounds the crest's
/// kink and the voxel steps of the depth. With 1 voxel and more, thin parts fade (the holder
/// arc of the head CT loses 7 % of its sheet at 1, all of it at 1.4).
pub const MATERIAL_SMOOTHING: f64 = 0.5;
/// Bone lies this far above the soft-tissue level (HU): halfway to cancellous bone.
const BONE_ABOVE_SOFT_TISSUE: f64 = 190.0;
/// Histogram bins (HU) of the CT recognition.
const BIN: f64 = 4.0;
/// Half-width (HU) of the band around a peak counted as that material.
const PEAK_BAND: f64 = 48.0;
/// Share of the voxels the air band and the soft-tissue band must each hold.
const MIN_PEAK_SHARE: f64 = 0.01;
/// A soft-tissue peak holds this many times the voxels of the bands 150–250 HU either side
/// of it: partial-volume voxels between air and a bright part spread evenly, tissue peaks.
const PEAK_CONTRAST: f64 = 3.0;

/// A material of CT.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Material {
    /// Bone (and anything as dense: a head holder, implants).
    Bone,
    /// Everything that is not air: skin, the body's outline.
    Tissue,
}

impl Material {
    /// The materials in the order the automatic choice tries them.
    pub const ALL: [Material; 2] = [Material::Bone, Material::Tissue];

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Material::Bone => "bone",
            Material::Tissue => "tissue",
        }
    }

    /// The threshold (HU) above which a voxel is this material.
    pub fn threshold(self, levels: &CtLevels) -> f64 {
        match self {
            Material::Bone => levels.soft_tissue + BONE_ABOVE_SOFT_TISSUE,
            Material::Tissue => 0.5 * (levels.air + levels.soft_tissue),
        }
    }
}

/// How the material is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MaterialChoice {
    /// On a CT in Hounsfield units, the first thin material; otherwise the two-class
    /// threshold.
    #[default]
    Auto,
    /// This material; the volume must be a CT in Hounsfield units.
    Given(Material),
    /// No materials: the two-class threshold (or the given one), no window.
    Off,
}

/// The levels (HU) of a CT's air and soft tissue, read from its smoothed histogram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CtLevels {
    /// Median of the air band.
    pub air: f64,
    /// Median of the soft-tissue band.
    pub soft_tissue: f64,
}

impl CtLevels {
    /// The window of a threshold: from the level of the material under it to as far above
    /// it, so that the threshold is at half the windowed contrast; `None` when the threshold
    /// is not above air.
    pub fn window(&self, threshold: f64) -> Option<(f64, f64)> {
        let below = if threshold > self.soft_tissue + PEAK_BAND {
            self.soft_tissue
        } else {
            self.air
        };
        let half = threshold - below;
        (half > 0.0).then_some((below, threshold + half))
    }
}

/// A material tried by the automatic choice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialCandidate {
    /// The material.
    pub material: Material,
    /// Its threshold (HU).
    pub threshold: f64,
    /// 90th percentile of its voxels' depth below its surface (world units); `None` when no
    /// voxel is above the threshold.
    pub depth_p90: Option<f64>,
}

/// What the material stage decided, for the report.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialReport {
    /// The CT's levels.
    pub levels: CtLevels,
    /// The material used (`None` when the caller gave the threshold).
    pub material: Option<Material>,
    /// True when it was chosen automatically.
    pub automatic: bool,
    /// The materials tried, in order, up to the one chosen (empty unless automatic).
    pub candidates: Vec<MaterialCandidate>,
    /// The window the values were clamped to; `None` when nothing was thin and the
    /// two-class threshold was used.
    pub window: Option<(f64, f64)>,
    /// The thin depth limit in world units (`THIN_DEPTH` voxels).
    pub thin_depth: f64,
}

/// The CT levels of `smooth` (values smoothed by about a voxel), or `None` when its histogram
/// has no air peak or no soft-tissue peak: not a CT in Hounsfield units.
pub fn ct_levels(smooth: &[f64]) -> Option<CtLevels> {
    const LO: f64 = -1100.0;
    const HI: f64 = 500.0;
    let bins = ((HI - LO) / BIN) as usize;
    let mut counts = vec![0u64; bins];
    let mut total = 0u64;
    for &v in smooth {
        if v.is_finite() {
            total += 1;
            if (LO..HI).contains(&v) {
                counts[((v - LO) / BIN) as usize] += 1;
            }
        }
    }
    if total == 0 {
        return None;
    }
    let bin_of = |hu: f64| (((hu - LO) / BIN) as usize).min(bins);
    let band = |centre: f64, half: f64| -> u64 {
        counts[bin_of(centre - half)..bin_of(centre + half)]
            .iter()
            .sum()
    };
    let peak = |from: f64, to: f64| -> Option<f64> {
        let (lo, hi) = (bin_of(from), bin_of(to));
        let best = (lo..hi).max_by_key(|&b| (counts[b], std::cmp::Reverse(b)))?;
        Some(LO + (best as f64 + 0.5) * BIN)
    };
    let share = |n: u64| n as f64 / total as f64;
    let air = peak(-1100.0, -800.0)?;
    let soft = peak(-200.0, 200.0)?;
    if share(band(air, PEAK_BAND)) < MIN_PEAK_SHARE || share(band(soft, PEAK_BAND)) < MIN_PEAK_SHARE
    {
        return None;
    }
    let sides = band(soft - 200.0, 50.0).max(band(soft + 200.0, 50.0));
    if (band(soft, 50.0) as f64) < PEAK_CONTRAST * sides as f64 {
        return None;
    }
    let median_near = |centre: f64| {
        let mut near: Vec<f64> = smooth
            .iter()
            .copied()
            .filter(|v| (v - centre).abs() <= PEAK_BAND)
            .collect();
        let mid = near.len() / 2;
        *near.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    Some(CtLevels {
        air: median_near(air),
        soft_tissue: median_near(soft),
    })
}

/// The 90th percentile of the depth (world units) of the voxels whose `smooth` value is above
/// `threshold`, or `None` when there are none.
pub(crate) fn depth_p90(volume: &Volume, smooth: &[f64], threshold: f64) -> Option<f64> {
    let object: Vec<bool> = smooth.par_iter().map(|&v| v > threshold).collect();
    let d2 = squared_depth_to_background(volume, &object);
    let mut depths: Vec<f64> = d2
        .par_iter()
        .zip(&object)
        .filter(|&(_, &o)| o)
        .map(|(&d, _)| d)
        .collect();
    if depths.is_empty() {
        return None;
    }
    let at = (9 * depths.len()) / 10;
    Some(depths.select_nth_unstable_by(at, f64::total_cmp).1.sqrt())
}

/// `volume` clamped to `window`, raised inside the material by [`MATERIAL_CREST`] of the
/// window per voxel of depth, and smoothed by [`MATERIAL_SMOOTHING`] voxels of its smallest
/// edge (fewer voxels along longer edges); non-finite values count as the window's low end.
pub(crate) fn windowed_volume(volume: &Volume, (lo, hi): (f64, f64)) -> Volume {
    let mut data: Vec<f64> = (0..volume.len())
        .into_par_iter()
        .map(|i| {
            let v = volume.value(i);
            if v.is_finite() { v.clamp(lo, hi) } else { lo }
        })
        .collect();
    let size = volume.voxel_size();
    let finest = size.min_element();
    let threshold = 0.5 * (lo + hi);
    let object: Vec<bool> = data.par_iter().map(|&v| v > threshold).collect();
    let d2 = squared_depth_to_background(volume, &object);
    data.par_iter_mut()
        .zip(&d2)
        .for_each(|(v, d)| *v += (hi - lo) * MATERIAL_CREST * d.sqrt() / finest);
    for (axis, edge) in [size.x, size.y, size.z].into_iter().enumerate() {
        data = gaussian_along(
            &data,
            volume.dims(),
            axis,
            MATERIAL_SMOOTHING * finest / edge,
        );
    }
    let values = VoxelValues::F32(data.into_iter().map(|v| v as f32).collect());
    Volume::new(volume.dims(), values, volume.affine())
        .expect("the grid and affine of a valid volume")
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::DVec3;

    /// A smoothed "CT": `air` voxels at −1000, `soft` at +40, `bone` at +900, `spread` evenly
    /// from −1000 to +2000 (partial volume), each with a little jitter.
    fn histogram(air: usize, soft: usize, bone: usize, spread: usize) -> Vec<f64> {
        let jitter = |i: usize| ((i * 7919) % 41) as f64 - 20.0;
        let mut v = Vec::new();
        v.extend((0..air).map(|i| -1000.0 + jitter(i)));
        v.extend((0..soft).map(|i| 40.0 + jitter(i)));
        v.extend((0..bone).map(|i| 900.0 + jitter(i)));
        v.extend((0..spread).map(|i| -1000.0 + 3000.0 * i as f64 / spread as f64));
        v
    }

    #[test]
    fn a_ct_is_recognised_from_its_air_and_soft_tissue() {
        let levels = ct_levels(&histogram(50_000, 40_000, 5_000, 5_000)).unwrap();
        assert!((levels.air + 1000.0).abs() < 3.0, "{levels:?}");
        assert!((levels.soft_tissue - 40.0).abs() < 3.0, "{levels:?}");
        assert!((Material::Bone.threshold(&levels) - 230.0).abs() < 3.0);
        assert!((Material::Tissue.threshold(&levels) + 480.0).abs() < 3.0);
    }

    #[test]
    fn a_part_in_air_is_not_a_ct_with_tissue() {
        // Air and a bright part with its partial-volume voxels spread between: no tissue peak.
        assert_eq!(ct_levels(&histogram(80_000, 0, 10_000, 10_000)), None);
        // Grey values that are not Hounsfield units.
        let grey: Vec<f64> = (0..10_000).map(|i| (i % 100) as f64 * 0.05).collect();
        assert_eq!(ct_levels(&grey), None);
    }

    #[test]
    fn the_window_centres_the_threshold_on_the_material_below() {
        let levels = CtLevels {
            air: -1000.0,
            soft_tissue: 36.0,
        };
        assert_eq!(levels.window(226.0), Some((36.0, 416.0)));
        assert_eq!(levels.window(-482.0), Some((-1000.0, 36.0)));
        assert_eq!(levels.window(-1200.0), None);
    }

    #[test]
    fn a_slab_is_thin_and_a_block_is_not() {
        let dims = [40, 40, 40];
        let slab: Vec<f64> = (0..40 * 40 * 40)
            .map(|i| {
                if (18..22).contains(&(i / 1600)) {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let block: Vec<f64> = (0..40 * 40 * 40)
            .map(|i| {
                let [x, y, z] = [i % 40, (i / 40) % 40, i / 1600];
                if [x, y, z].iter().all(|c| (5..35).contains(c)) {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let volume = Volume::axis_aligned(
            dims,
            VoxelValues::F32(vec![0.0; 40 * 40 * 40]),
            DVec3::splat(0.5),
            DVec3::ZERO,
        )
        .unwrap();
        let slab_depth = depth_p90(&volume, &slab, 0.5).unwrap();
        assert!((slab_depth - 1.0).abs() < 1e-12, "{slab_depth}");
        let block_depth = depth_p90(&volume, &block, 0.5).unwrap();
        assert!(block_depth > THIN_DEPTH * 0.5, "{block_depth}");
        assert_eq!(depth_p90(&volume, &slab, 2.0), None);
    }

    #[test]
    fn a_windowed_slab_has_its_crest_in_the_middle() {
        // A slab of 1500 HU, 9 voxels thick (z = 4 … 12), in soft tissue at 40 HU.
        let dims = [6, 5, 17];
        let values: Vec<f32> = (0..6 * 5 * 17)
            .map(|i| {
                if (4..=12).contains(&(i / 30)) {
                    1500.0
                } else {
                    40.0
                }
            })
            .collect();
        let volume =
            Volume::axis_aligned(dims, VoxelValues::F32(values), DVec3::ONE, DVec3::ZERO).unwrap();
        let w = windowed_volume(&volume, (40.0, 420.0));
        assert_eq!(w.affine(), volume.affine());
        let column: Vec<f64> = (0..17).map(|k| w.value(w.index(2, 2, k))).collect();
        // Symmetric, rising to the middle layer, at the window's low end far outside.
        for k in 0..8 {
            assert!((column[k] - column[16 - k]).abs() < 1e-3, "{column:?}");
            assert!(column[k] <= column[k + 1], "{column:?}");
        }
        assert!(column[3] < column[4] && column[7] < column[8], "{column:?}");
        assert!((column[0] - 40.0).abs() < 1e-3, "{column:?}");
        // The surface (between layers 3 and 4) stays within a quarter window of the
        // threshold, halfway up the window; the mask above it is the slab's.
        let surface = 0.5 * (column[3] + column[4]);
        assert!((surface - 230.0).abs() < 0.25 * 380.0, "{column:?}");
        assert!(column[3] < 230.0 && column[4] > 230.0, "{column:?}");
    }
}
