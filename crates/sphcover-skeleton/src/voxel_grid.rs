//! What the pipeline asks of a volume's voxel grid, checked from its header before any voxel
//! is read: the cover and the ridge work in world coordinates, but the lengths given in
//! voxels (`sigma`, the tolerance) and the separable Gaussian filter take the grid's axes to
//! be the world's and its voxels to be near cubes.

use sphcover_core::{DMat3, DVec3};
use thiserror::Error;

/// Largest ratio of voxel edge lengths processed: mildly anisotropic voxels (a CT's slice
/// spacing a little off its pixel size) are fine, but beyond this a voxel is a needle and the
/// local quadratic fits lose the thin direction.
pub const MAX_ANISOTROPY: f64 = 2.0;
/// Relative difference of voxel edge lengths accepted as cubic without a remark.
const CUBIC_TOLERANCE: f64 = 1e-3;
/// Largest off-axis component (relative to the column's largest) of an axis-aligned affine.
const AXIS_TOLERANCE: f64 = 1e-6;

/// A grid the pipeline refuses; the remedy is to resample the volume.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum VoxelGridError {
    /// Edge lengths more than [`MAX_ANISOTROPY`] apart.
    #[error(
        "voxels of {:.6} x {:.6} x {:.6} are too anisotropic (more than {MAX_ANISOTROPY}:1); resample to near-cubic voxels first",
        size.x, size.y, size.z
    )]
    Anisotropic {
        /// The voxel's edge lengths.
        size: DVec3,
    },
    /// A voxel axis that is not along one world axis.
    #[error("the voxel axes are oblique to the world axes; resample to an axis-aligned grid first")]
    Oblique,
}

/// Voxels accepted though not cubic: worth a warning.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
#[error(
    "voxels of {:.6} x {:.6} x {:.6} are not cubic; the sheet is computed in world coordinates, lengths given in voxels use their geometric mean",
    size.x, size.y, size.z
)]
pub struct NonCubicVoxels {
    /// The voxel's edge lengths.
    pub size: DVec3,
}

/// Checks a grid of voxels `size` long along the voxel-to-world axes `axes` (the columns of
/// the affine's linear part). Accepted, it says when the voxels are not cubic (lengths given
/// in voxels then use their geometric mean).
pub fn check_voxel_grid(
    size: DVec3,
    axes: DMat3,
) -> Result<Option<NonCubicVoxels>, VoxelGridError> {
    let (lo, hi) = (size.min_element(), size.max_element());
    if hi > MAX_ANISOTROPY * lo {
        return Err(VoxelGridError::Anisotropic { size });
    }
    for column in [axes.x_axis, axes.y_axis, axes.z_axis] {
        let big = column.abs().max_element();
        let along = column
            .abs()
            .to_array()
            .iter()
            .filter(|&&c| c > AXIS_TOLERANCE * big)
            .count();
        if along != 1 {
            return Err(VoxelGridError::Oblique);
        }
    }
    Ok((hi - lo > CUBIC_TOLERANCE * hi).then_some(NonCubicVoxels { size }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_cubic_axis_aligned_grids_pass_and_others_are_refused() {
        let diagonal = |s: DVec3| DMat3::from_diagonal(s);
        let cube = DVec3::splat(0.5);
        assert_eq!(check_voxel_grid(cube, diagonal(cube)), Ok(None));
        // Axes may be flipped and permuted (LPS/RAS, sagittal stacks).
        let permuted = DMat3::from_cols(DVec3::Y * -0.5, DVec3::X * 0.5, DVec3::Z * 0.5);
        assert_eq!(check_voxel_grid(cube, permuted), Ok(None));
        let slab = DVec3::new(0.5, 0.5, 0.9);
        assert_eq!(
            check_voxel_grid(slab, diagonal(slab)),
            Ok(Some(NonCubicVoxels { size: slab }))
        );
        let needle = DVec3::new(0.5, 0.5, 1.2);
        assert_eq!(
            check_voxel_grid(needle, diagonal(needle)),
            Err(VoxelGridError::Anisotropic { size: needle })
        );
        let turned = DMat3::from_rotation_z(0.1) * diagonal(cube);
        assert_eq!(check_voxel_grid(cube, turned), Err(VoxelGridError::Oblique));
    }
}
