//! The radius range of the supports: `r_max` from the object's thickness (the exact
//! distance transform), capped; see "Radii" in the notes of the `volume_cover` module.
//!
//! It runs once, before the covering, and its time is reported on its own; the scattered
//! builder shares the cap with a thickness of its own.

use crate::ParameterError;
use glam::DVec3;
use rayon::prelude::*;

use super::distance_transform;
use super::{VolumeCoverError, VolumeCoverParams};
use crate::volume::Volume;

/// Squared distance (world units²) from every voxel centre of `volume` to the nearest voxel
/// centre outside `object` (one flag per voxel): the squared depth of each object voxel,
/// exact on axis-aligned grids of any voxel size (Felzenszwalb and Huttenlocher's separable
/// transform); 0 outside the object, `+∞` everywhere when there is no background voxel.
///
/// ```
/// use sphcover_core::{DVec3, Volume, VoxelValues, squared_depth_to_background};
///
/// // A slab 5 voxels thick (z = 2 … 6) in a 4 × 4 × 9 grid of 0.5 × 0.5 × 1 voxels.
/// let values = VoxelValues::F32(vec![0.0; 4 * 4 * 9]);
/// let volume = Volume::axis_aligned([4, 4, 9], values, DVec3::new(0.5, 0.5, 1.0), DVec3::ZERO)?;
/// let object: Vec<bool> = (0..volume.len()).map(|i| (2..=6).contains(&volume.ijk(i)[2])).collect();
/// let d2 = squared_depth_to_background(&volume, &object);
/// // The middle layer is 3 slices (3 world units) from the nearest background voxel.
/// assert_eq!(d2[volume.index(1, 1, 4)], 9.0);
/// assert_eq!(d2[volume.index(1, 1, 0)], 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn squared_depth_to_background(volume: &Volume, object: &[bool]) -> Vec<f64> {
    let size = volume.voxel_size();
    distance_transform::squared_distance_to_background(
        volume.dims(),
        [size.x, size.y, size.z],
        |i| !object[i],
    )
}

/// Twice the largest distance from an object voxel to a background voxel centre (`d2` from
/// [`squared_depth_to_background`]); `+∞` with no background voxel.
pub(super) fn max_thickness(d2: &[f64], object: &[bool]) -> f64 {
    let max = d2
        .par_iter()
        .zip(object)
        .filter(|&(_, &o)| o)
        .map(|(&d, _)| d)
        .reduce(|| 0.0, f64::max);
    2.0 * max.sqrt()
}

/// `r_max` and the object thickness it came from: the given `r_max`, or else the largest
/// thickness (half the sample extent `diagonal` when no background sample bounds the object),
/// capped at `max_radius_voxels` sample spacings and raised to `r_min`. Both builders use it.
pub(super) fn radius_cap(
    params: &VolumeCoverParams,
    r_min: f64,
    spacing: f64,
    thickness: impl FnOnce() -> f64,
    diagonal: impl FnOnce() -> f64,
) -> Result<(f64, Option<f64>), VolumeCoverError> {
    let (r_max, thickness) = match params.r_max {
        Some(r) => (r, None),
        None => {
            let t = thickness();
            let r = if t.is_finite() { t } else { 0.5 * diagonal() };
            let cap = params.max_radius_voxels * spacing;
            (r.min(cap).max(r_min), t.is_finite().then_some(t))
        }
    };
    if r_max < r_min {
        return Err(VolumeCoverError::InvalidParameter(ParameterError {
            name: "r_max",
            value: r_max,
            expected: "must be at least r_min",
        }));
    }
    Ok((r_max, thickness))
}

pub(super) fn grid_diagonal(volume: &Volume) -> f64 {
    let [nx, ny, nz] = volume.dims();
    let far = DVec3::new(nx as f64 - 1.0, ny as f64 - 1.0, nz as f64 - 1.0);
    (volume.affine().matrix3 * far).length()
}
