//! The image-based baseline (thesis §6.3, Fig. 6.18): Gaussian smoothing and non-maximum
//! suppression along the Hessian's smallest eigenvector.
//!
//! The method is described on [`nms_skeleton()`].

use glam::{DMat3, DVec3};
use rayon::prelude::*;
use sphcover_core::{ParameterError, Volume};

use crate::error::SkeletonError;
use crate::gaussian_filter::smoothed_values;
use crate::intensity_model::{IntensityModel, estimate_intensity_model};
use crate::resample::{ResampledGrid, resample_if_anisotropic};
use crate::symmetric_eigen::smallest_eigen;

/// Parameters of [`nms_skeleton`].
#[derive(Clone, Debug, PartialEq)]
pub struct NmsParams {
    /// Gaussian σ in voxels.
    pub sigma: f64,
    /// Object threshold (volume units); `None`: automatic, as the ridge pipeline's (see
    /// [`crate::IntensityModel`]).
    pub threshold: Option<f64>,
    /// Smallest `−λ1` kept, as a fraction of the largest over the candidates.
    pub min_relative_strength: f64,
}

impl Default for NmsParams {
    fn default() -> NmsParams {
        NmsParams {
            sigma: 1.0,
            threshold: None,
            min_relative_strength: 0.05,
        }
    }
}

/// What [`nms_skeleton`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct NmsStats {
    /// Threshold, levels and noise.
    pub intensity: IntensityModel,
    /// Voxels whose smoothed value exceeds the threshold.
    pub candidates: usize,
    /// Ridge points kept.
    pub points: usize,
    /// How the volume was resampled first, as the ridge pipeline does it
    /// ([`crate::SkeletonStats::resampled`]); σ is then in resampled voxels.
    pub resampled: Option<ResampledGrid>,
}

/// Ridge points of `volume` by Gaussian smoothing and non-maximum suppression, in world
/// coordinates.
///
/// The volume is smoothed with a separable Gaussian of standard deviation σ voxels along each
/// grid axis; `∇I` and `∇²I` come from central differences, mapped to world coordinates by
/// the voxel→world linear map `L` (`∇_w = L⁻ᵀ ∇`, `∇²_w = L⁻ᵀ ∇² L⁻¹`). At a voxel whose
/// smoothed value exceeds the threshold, with `λ1 < 0` the smallest Hessian eigenvalue and
/// `e` its eigenvector, the maximum of the quadratic model along `e` lies at
/// `x + t e`, `t = −⟨∇I, e⟩ / λ1`; the voxel keeps it when that offset stays inside the voxel
/// (each voxel-frame component within ½). The output is a point set: one sub-voxel ridge
/// point per kept voxel. Its known failure, which the cover method is meant to fix: one σ
/// cannot suit thin and thick parts at once (too small leaves double ridges on thick plates,
/// too large flattens thin ones).
///
/// A volume whose voxels are more than [`MAX_ANISOTROPY`](crate::MAX_ANISOTROPY) apart is
/// first resampled as [`crate::extract_skeleton`] does it, so both methods see one grid.
pub fn nms_skeleton(
    volume: &Volume,
    params: &NmsParams,
) -> Result<(Vec<DVec3>, NmsStats), SkeletonError> {
    if !(params.sigma.is_finite() && params.sigma > 0.0 && params.sigma <= 64.0) {
        return Err(SkeletonError::InvalidParameter(ParameterError {
            name: "sigma",
            value: params.sigma,
            expected: "must lie in (0, 64] voxels",
        }));
    }
    let resampled = resample_if_anisotropic(volume)?;
    let grid = resampled.as_ref().map_or(volume, |(grid, _)| grid);
    let (points, mut stats) = suppress_non_maxima(grid, params)?;
    stats.resampled = resampled.map(|(_, record)| record);
    Ok((points, stats))
}

/// [`nms_skeleton`] on the grid as it is.
fn suppress_non_maxima(
    volume: &Volume,
    params: &NmsParams,
) -> Result<(Vec<DVec3>, NmsStats), SkeletonError> {
    let intensity = estimate_intensity_model(volume, params.threshold)?;
    let dims = volume.dims();
    let smooth = smoothed_values(volume, params.sigma, intensity.background_level);
    let inv = volume.affine().matrix3.inverse();
    let inv_t = inv.transpose();
    let [nx, ny, nz] = dims;
    let at = |i: usize, j: usize, k: usize| smooth[i + nx * (j + ny * k)];
    let candidates: Vec<(usize, DVec3, f64)> = (0..volume.len())
        .into_par_iter()
        .with_min_len(4096)
        .filter_map(|idx| {
            let [i, j, k] = volume.ijk(idx);
            if i == 0 || j == 0 || k == 0 || i + 1 >= nx || j + 1 >= ny || k + 1 >= nz {
                return None;
            }
            let c = at(i, j, k);
            if c.is_nan() || c <= intensity.threshold {
                return None;
            }
            let d = |di: i64, dj: i64, dk: i64| {
                at(
                    (i as i64 + di) as usize,
                    (j as i64 + dj) as usize,
                    (k as i64 + dk) as usize,
                )
            };
            let g = DVec3::new(
                0.5 * (d(1, 0, 0) - d(-1, 0, 0)),
                0.5 * (d(0, 1, 0) - d(0, -1, 0)),
                0.5 * (d(0, 0, 1) - d(0, 0, -1)),
            );
            let hxx = d(1, 0, 0) - 2.0 * c + d(-1, 0, 0);
            let hyy = d(0, 1, 0) - 2.0 * c + d(0, -1, 0);
            let hzz = d(0, 0, 1) - 2.0 * c + d(0, 0, -1);
            let hxy = 0.25 * (d(1, 1, 0) - d(1, -1, 0) - d(-1, 1, 0) + d(-1, -1, 0));
            let hxz = 0.25 * (d(1, 0, 1) - d(1, 0, -1) - d(-1, 0, 1) + d(-1, 0, -1));
            let hyz = 0.25 * (d(0, 1, 1) - d(0, 1, -1) - d(0, -1, 1) + d(0, -1, -1));
            let h = DMat3::from_cols(
                DVec3::new(hxx, hxy, hxz),
                DVec3::new(hxy, hyy, hyz),
                DVec3::new(hxz, hyz, hzz),
            );
            let gw = inv_t * g;
            let hw = inv_t * h * inv;
            let eig = smallest_eigen(&hw)?;
            let l1 = eig.values[0];
            if l1.is_nan() || l1 >= 0.0 {
                return None;
            }
            let t = -gw.dot(eig.vector) / l1;
            let offset = inv * (t * eig.vector);
            if offset.abs().max_element() > 0.5 {
                return None;
            }
            Some((idx, volume.voxel_centre([i, j, k]) + t * eig.vector, -l1))
        })
        .collect();
    let candidate_count = smooth.iter().filter(|&&v| v > intensity.threshold).count();
    let max_strength = candidates.iter().map(|c| c.2).fold(0.0, f64::max);
    let points: Vec<DVec3> = candidates
        .iter()
        .filter(|c| c.2 >= params.min_relative_strength * max_strength)
        .map(|c| c.1)
        .collect();
    if points.is_empty() {
        return Err(SkeletonError::EmptyResult {
            stage: "non-maximum suppression",
            hint: "no ridge above the threshold after smoothing; try a smaller sigma",
        });
    }
    let stats = NmsStats {
        intensity,
        candidates: candidate_count,
        points: points.len(),
        resampled: None,
    };
    Ok((points, stats))
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::VoxelValues;

    /// A slab `|z − z0| ≤ 2` voxels rendered with linear partial volume at the faces.
    fn slab(z0: f64) -> Volume {
        let n = 16;
        let values = (0..n * n * n)
            .map(|idx| {
                let k = (idx / (n * n)) as f64;
                let inside = (2.5 - (k - z0).abs()).clamp(0.0, 1.0);
                -1000.0 + 3000.0 * inside
            })
            .collect();
        Volume::axis_aligned(
            [n, n, n],
            VoxelValues::F64(values),
            DVec3::splat(0.5),
            DVec3::ZERO,
        )
        .unwrap()
    }

    #[test]
    fn slab_ridge_is_its_mid_plane() {
        for z0 in [7.0, 7.3, 7.5] {
            let v = slab(z0);
            let (points, stats) = nms_skeleton(&v, &NmsParams::default()).unwrap();
            assert!(stats.points > 100);
            for p in points {
                assert!((p.z - 0.5 * z0).abs() < 0.05, "z0 {z0}: {p}");
            }
        }
    }

    #[test]
    fn bad_sigma_is_refused() {
        let p = NmsParams {
            sigma: 0.0,
            ..NmsParams::default()
        };
        assert!(nms_skeleton(&slab(7.0), &p).is_err());
    }
}
