//! What the pipeline asks of a volume's voxel grid, checked from its header before any voxel
//! is read: the cover and the ridge work in world coordinates, but the lengths given in
//! voxels (`sigma`, the tolerance) and the separable Gaussian filter take the grid's axes to
//! be the world's and its voxels to be near cubes. Grids whose slices are a few times their
//! pixels (clinical CT) are first resampled along the coarse axes ([`crate::resample_volume`]).

use std::fmt;

use sphcover_core::{DMat3, DVec3};
use thiserror::Error;

/// Largest ratio of voxel edge lengths processed directly: mildly anisotropic voxels (a CT's
/// slice spacing a little off its pixel size, 1.5 mm on 0.96 mm pixels) are fine, but beyond
/// this a voxel is a needle and the local quadratic fits lose the thin direction. More
/// anisotropic grids are resampled to within it first. On the small perforations (3-voxel
/// plate, `small_perforations` example) with every second slice, processing the 2:1 grid as
/// it was left 0.020–0.050 of spurious area at 10% noise and 0.081–0.186 at 30%; resampled
/// to 1:1, 0.003–0.005 and 0.047–0.057. Lower limits refine 5:1 grids by 4 instead of 3,
/// which on the 5:1 head CT phantom left more and larger vault holes (34 over 20 mm, the
/// largest 219 mm, against 32 and 94 mm).
pub const MAX_ANISOTROPY: f64 = 1.75;
/// Largest ratio of the input's voxel edge lengths at which the resampled grid still stands
/// for measurements (see [`measured_after_resampling`]).
const MAX_MEASURED_ANISOTROPY: f64 = 2.0;
/// Largest ratio of voxel edge lengths accepted with resampling. Clinical CT goes up to about
/// 5:1 (0.96 mm pixels, 4.8 mm slices); beyond 8:1 a plate a few pixels thick falls between
/// slices, so interpolation has nothing to restore, and the resampled grid grows by the ratio.
pub const MAX_RESAMPLED_ANISOTROPY: f64 = 8.0;
/// Relative difference of voxel edge lengths accepted as cubic without a remark.
const CUBIC_TOLERANCE: f64 = 1e-3;
/// Relative slack of the anisotropy limits: header voxel sizes are single precision, so a
/// ratio meant to be exactly 2 or 8 may come out a few ulps above it.
const RATIO_TOLERANCE: f64 = 1e-6;
/// Largest off-axis component (relative to the column's largest) of an axis-aligned affine.
const AXIS_TOLERANCE: f64 = 1e-6;

/// A grid the pipeline refuses; the remedy is to resample the volume.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum VoxelGridError {
    /// Edge lengths more than [`MAX_RESAMPLED_ANISOTROPY`] apart.
    #[error(
        "voxels of {:.6} x {:.6} x {:.6} are too anisotropic (more than {MAX_RESAMPLED_ANISOTROPY}:1); resample to voxels at most {MAX_ANISOTROPY}:1 first",
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

/// How a grid more anisotropic than [`MAX_ANISOTROPY`] is resampled before the pipeline runs
/// on it: each voxel axis `a` is divided by the integer `factors[a]`, the smallest that
/// brings its edge within [`MAX_ANISOTROPY`] times the finest edge (1 for axes already
/// within it). The first and last samples stay at the first and last voxel centres, so an
/// axis of `n` voxels gets `(n − 1)·factor + 1`. Its `Display` is the note to show a user.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resampling {
    /// The voxel's edge lengths before resampling.
    pub size: DVec3,
    /// The factor along each voxel axis (`i`, `j`, `k`), at least 1.
    pub factors: [usize; 3],
}

impl Resampling {
    /// The resampling a grid of voxels `size` long needs, `None` when every edge is within
    /// [`MAX_ANISOTROPY`] of the finest (the grid is processed as it is). Edges must be
    /// positive and finite.
    pub fn of(size: DVec3) -> Option<Resampling> {
        let lo = size.min_element();
        let limit = MAX_ANISOTROPY * (1.0 + RATIO_TOLERANCE) * lo;
        let factors = size
            .to_array()
            .map(|s| ((s / limit).ceil() as usize).max(1));
        (factors != [1; 3]).then_some(Resampling { size, factors })
    }

    /// The voxel's edge lengths after resampling.
    pub fn voxel_size(&self) -> DVec3 {
        self.size / DVec3::from_array(self.factors.map(|f| f.max(1) as f64))
    }

    /// The grid dimensions after resampling a grid of `dims` voxels (saturating at
    /// `usize::MAX`).
    pub fn dims(&self, dims: [usize; 3]) -> [usize; 3] {
        std::array::from_fn(|a| {
            dims[a]
                .saturating_sub(1)
                .saturating_mul(self.factors[a].max(1))
                .saturating_add(1)
        })
    }
}

impl fmt::Display for Resampling {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.size;
        write!(
            f,
            "voxels of {:.6} x {:.6} x {:.6} are more than {MAX_ANISOTROPY}:1 anisotropic; resampled",
            s.x, s.y, s.z
        )?;
        let new = self.voxel_size().to_array();
        let axes = (0..3).filter(|&a| self.factors[a] > 1);
        for (n, a) in axes.enumerate() {
            write!(
                f,
                "{} by {} along voxel axis {} (spacing {:.6} -> {:.6})",
                if n == 0 { "" } else { "," },
                self.factors[a],
                ["i", "j", "k"][a],
                self.size[a],
                new[a]
            )?;
        }
        write!(f, " with cubic (Catmull-Rom) interpolation")
    }
}

/// Whether a grid of voxels `size` long, resampled, can still be read as measurements (by
/// the perforation repair): up to 2:1, every point lies within one pixel of a measured slice;
/// on a 3:1 head CT, bone running along 2.9 mm slices read as air between them.
pub(crate) fn measured_after_resampling(size: DVec3) -> bool {
    anisotropy_at_most(size, MAX_MEASURED_ANISOTROPY)
}

/// Whether voxels of `size` are at most [`MAX_RESAMPLED_ANISOTROPY`] apart.
pub(crate) fn resamplable(size: DVec3) -> bool {
    anisotropy_at_most(size, MAX_RESAMPLED_ANISOTROPY)
}

/// Whether the longest edge of voxels `size` is at most `ratio` times the shortest (with
/// [`RATIO_TOLERANCE`]).
fn anisotropy_at_most(size: DVec3, ratio: f64) -> bool {
    size.max_element() <= ratio * (1.0 + RATIO_TOLERANCE) * size.min_element()
}

/// What [`check_voxel_grid`] says about a grid it accepts.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VoxelGridCheck {
    /// Set when the voxels are more than [`MAX_ANISOTROPY`] apart: the pipeline resamples
    /// the volume first.
    pub resampling: Option<Resampling>,
    /// Set when the voxels the pipeline processes (after any resampling) are not cubic.
    pub non_cubic: Option<NonCubicVoxels>,
}

/// Checks a grid of voxels `size` long along the voxel-to-world axes `axes` (the columns of
/// the affine's linear part). Accepted, it says whether the pipeline resamples the grid
/// first (voxels more than [`MAX_ANISOTROPY`] apart), and whether the voxels it processes
/// are not cubic (lengths given in voxels then use their geometric mean). Refused: voxels
/// more than [`MAX_RESAMPLED_ANISOTROPY`] apart, and axes oblique to the world's.
pub fn check_voxel_grid(size: DVec3, axes: DMat3) -> Result<VoxelGridCheck, VoxelGridError> {
    if !resamplable(size) {
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
    let resampling = Resampling::of(size);
    let processed = resampling.map_or(size, |r| r.voxel_size());
    let (lo, hi) = (processed.min_element(), processed.max_element());
    Ok(VoxelGridCheck {
        resampling,
        non_cubic: (hi - lo > CUBIC_TOLERANCE * hi).then_some(NonCubicVoxels { size: processed }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diagonal(s: DVec3) -> DMat3 {
        DMat3::from_diagonal(s)
    }

    #[test]
    fn near_cubic_axis_aligned_grids_pass_and_others_are_refused() {
        let cube = DVec3::splat(0.5);
        assert_eq!(
            check_voxel_grid(cube, diagonal(cube)),
            Ok(VoxelGridCheck::default())
        );
        // Axes may be flipped and permuted (LPS/RAS, sagittal stacks).
        let permuted = DMat3::from_cols(DVec3::Y * -0.5, DVec3::X * 0.5, DVec3::Z * 0.5);
        assert_eq!(
            check_voxel_grid(cube, permuted),
            Ok(VoxelGridCheck::default())
        );
        let slab = DVec3::new(0.5, 0.5, 0.8);
        assert_eq!(
            check_voxel_grid(slab, diagonal(slab)),
            Ok(VoxelGridCheck {
                resampling: None,
                non_cubic: Some(NonCubicVoxels { size: slab }),
            })
        );
        let turned = DMat3::from_rotation_z(0.1) * diagonal(cube);
        assert_eq!(check_voxel_grid(cube, turned), Err(VoxelGridError::Oblique));
    }

    #[test]
    fn grids_up_to_8_to_1_are_resampled_and_coarser_ones_refused() {
        let check = |size: DVec3| check_voxel_grid(size, diagonal(size));
        let resampled = |size: DVec3| check(size).map(|c| c.resampling.map(|r| r.factors));
        // 2:1 needs 2 (1:1), 2.5:1 needs 2 (1.25:1), 5:1 needs 3 (1.67:1), 8:1 needs 5 (1.6:1).
        assert_eq!(resampled(DVec3::new(0.5, 0.5, 1.0)), Ok(Some([1, 1, 2])));
        assert_eq!(resampled(DVec3::new(0.4, 0.4, 1.0)), Ok(Some([1, 1, 2])));
        assert_eq!(
            resampled(DVec3::new(0.957, 0.957, 4.785)),
            Ok(Some([1, 1, 3]))
        );
        assert_eq!(resampled(DVec3::new(4.0, 0.5, 0.5)), Ok(Some([5, 1, 1])));
        // Two coarse axes are each resampled.
        assert_eq!(resampled(DVec3::new(0.5, 1.5, 2.5)), Ok(Some([1, 2, 3])));
        // A ratio of 1.75 that single precision put a hair above it is processed directly,
        // as are the 1.5 mm slices of a clinical CT on 0.957 mm pixels.
        assert_eq!(
            resampled(DVec3::new(0.7, 0.7, f64::from(1.225f32))),
            Ok(None)
        );
        assert_eq!(resampled(DVec3::new(0.957, 0.957, 1.5)), Ok(None));
        let five = check(DVec3::new(0.5, 0.5, 2.5)).unwrap();
        assert_eq!(
            five.non_cubic,
            Some(NonCubicVoxels {
                size: DVec3::new(0.5, 0.5, 2.5 / 3.0)
            })
        );
        let needle = DVec3::new(0.5, 0.5, 4.5);
        assert_eq!(
            check(needle),
            Err(VoxelGridError::Anisotropic { size: needle })
        );
        // Resampling does not make an oblique grid acceptable.
        let flat = DVec3::new(0.5, 0.5, 1.5);
        let turned = DMat3::from_rotation_x(0.2) * diagonal(flat);
        assert_eq!(check_voxel_grid(flat, turned), Err(VoxelGridError::Oblique));
    }

    #[test]
    fn resampled_grids_stand_for_measurements_up_to_2_to_1() {
        assert!(measured_after_resampling(DVec3::new(0.5, 0.5, 1.0)));
        assert!(measured_after_resampling(DVec3::new(
            0.6,
            0.6,
            f64::from(1.2f32)
        )));
        assert!(!measured_after_resampling(DVec3::new(0.957, 0.957, 2.87)));
    }

    #[test]
    fn the_resampled_grid_keeps_the_end_centres() {
        let r = Resampling::of(DVec3::new(1.0, 1.0, 5.0)).unwrap();
        assert_eq!(r.factors, [1, 1, 3]);
        assert_eq!(r.dims([10, 20, 7]), [10, 20, 19]);
        assert_eq!(r.voxel_size(), DVec3::new(1.0, 1.0, 5.0 / 3.0));
        assert_eq!(
            r.to_string(),
            "voxels of 1.000000 x 1.000000 x 5.000000 are more than 1.75:1 anisotropic; resampled \
             by 3 along voxel axis k (spacing 5.000000 -> 1.666667) with cubic (Catmull-Rom) \
             interpolation"
        );
    }
}
