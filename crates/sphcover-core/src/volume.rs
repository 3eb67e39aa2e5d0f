//! Scalar volumes on a regular grid (CT images and the like) with their voxel→world map.

use glam::{DAffine3, DMat3, DVec3};

use crate::point_cloud::PointCloud;

/// Voxel values, stored in the narrowest type that holds them exactly.
#[derive(Clone, Debug, PartialEq)]
pub enum VoxelValues {
    /// Single precision (8- and 16-bit integer images and `f32` images).
    F32(Vec<f32>),
    /// Double precision (32-bit integer images, `f64` images, scaled NIfTI-2 images).
    F64(Vec<f64>),
}

impl VoxelValues {
    /// Number of voxels.
    pub fn len(&self) -> usize {
        match self {
            VoxelValues::F32(v) => v.len(),
            VoxelValues::F64(v) => v.len(),
        }
    }

    /// True when there is no voxel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The value of voxel `index` (linear index), widened to `f64`.
    #[inline]
    pub fn get(&self, index: usize) -> f64 {
        match self {
            VoxelValues::F32(v) => f64::from(v[index]),
            VoxelValues::F64(v) => v[index],
        }
    }
}

/// Why a [`Volume`] could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VolumeError {
    /// A dimension is zero, or the voxel count overflows `usize`.
    #[error("invalid dimensions {dims:?}")]
    InvalidDims {
        /// The dimensions given.
        dims: [usize; 3],
    },
    /// The value array does not have one entry per voxel.
    #[error("{found} values for {expected} voxels")]
    LengthMismatch {
        /// `dims[0]·dims[1]·dims[2]`.
        expected: usize,
        /// Length of the value array.
        found: usize,
    },
    /// The voxel→world map is not finite or not invertible.
    #[error("the voxel-to-world map is not finite and invertible")]
    SingularAffine,
}

/// A scalar volume: `dims[0] × dims[1] × dims[2]` voxel values, `x` fastest (voxel `(i, j, k)`
/// has linear index `i + dims[0]·(j + dims[1]·k)`, the NIfTI order), and the affine map from
/// voxel indices to world coordinates (the centre of voxel `(i, j, k)` is at
/// `affine · (i, j, k)`).
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    dims: [usize; 3],
    values: VoxelValues,
    affine: DAffine3,
}

impl Volume {
    /// Builds a volume after checking the dimensions, the value count and the affine.
    pub fn new(
        dims: [usize; 3],
        values: VoxelValues,
        affine: DAffine3,
    ) -> Result<Volume, VolumeError> {
        let count = dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .filter(|&n| n > 0)
            .ok_or(VolumeError::InvalidDims { dims })?;
        if values.len() != count {
            return Err(VolumeError::LengthMismatch {
                expected: count,
                found: values.len(),
            });
        }
        if !is_invertible_affine(&affine) {
            return Err(VolumeError::SingularAffine);
        }
        Ok(Volume {
            dims,
            values,
            affine,
        })
    }

    /// A volume with axis-aligned voxels of size `voxel_size` whose voxel `(0, 0, 0)` is
    /// centred at `origin`.
    pub fn axis_aligned(
        dims: [usize; 3],
        values: VoxelValues,
        voxel_size: DVec3,
        origin: DVec3,
    ) -> Result<Volume, VolumeError> {
        Volume::new(
            dims,
            values,
            DAffine3::from_mat3_translation(DMat3::from_diagonal(voxel_size), origin),
        )
    }

    /// Grid dimensions `[nx, ny, nz]`.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Always false: a volume has at least one voxel.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// The voxel values.
    pub fn values(&self) -> &VoxelValues {
        &self.values
    }

    /// Takes the values out.
    pub fn into_values(self) -> VoxelValues {
        self.values
    }

    /// The voxel→world affine map.
    pub fn affine(&self) -> DAffine3 {
        self.affine
    }

    /// Linear index of voxel `(i, j, k)` (no bounds check beyond the debug assertions).
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        debug_assert!(i < self.dims[0] && j < self.dims[1] && k < self.dims[2]);
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// Voxel indices `(i, j, k)` of linear index `index`.
    #[inline]
    pub fn ijk(&self, index: usize) -> [usize; 3] {
        let i = index % self.dims[0];
        let rest = index / self.dims[0];
        [i, rest % self.dims[1], rest / self.dims[1]]
    }

    /// The value of voxel `index` (linear index), widened to `f64`.
    #[inline]
    pub fn value(&self, index: usize) -> f64 {
        self.values.get(index)
    }

    /// World position of the centre of voxel `(i, j, k)`.
    #[inline]
    pub fn voxel_centre(&self, ijk: [usize; 3]) -> DVec3 {
        self.affine
            .transform_point3(DVec3::new(ijk[0] as f64, ijk[1] as f64, ijk[2] as f64))
    }

    /// Edge lengths of a voxel: the lengths of the affine's columns.
    pub fn voxel_size(&self) -> DVec3 {
        let m = self.affine.matrix3;
        DVec3::new(m.x_axis.length(), m.y_axis.length(), m.z_axis.length())
    }

    /// The longest voxel diagonal, `max ‖A·(±1, ±1, 1)‖` (for orthogonal axes
    /// `√(dx² + dy² + dz²)`).
    pub fn voxel_diagonal(&self) -> f64 {
        let m = self.affine.matrix3;
        [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)]
            .iter()
            .map(|&(a, b)| (m * DVec3::new(a, b, 1.0)).length())
            .fold(0.0, f64::max)
    }

    /// Smallest and largest finite value, or `None` when no value is finite.
    pub fn value_range(&self) -> Option<(f64, f64)> {
        let (lo, hi) = match &self.values {
            VoxelValues::F32(v) => finite_range(v.iter().map(|&x| f64::from(x))),
            VoxelValues::F64(v) => finite_range(v.iter().copied()),
        };
        (lo <= hi).then_some((lo, hi))
    }

    /// Every voxel centre in world coordinates with its value, in linear-index order.
    pub fn to_samples(&self) -> PointCloud {
        let positions = (0..self.len())
            .map(|idx| self.voxel_centre(self.ijk(idx)))
            .collect();
        let values = (0..self.len()).map(|idx| self.value(idx)).collect();
        PointCloud {
            positions,
            values: Some(values),
            ..PointCloud::default()
        }
    }
}

/// True when the affine map is finite and its linear part invertible with a finite inverse.
pub(crate) fn is_invertible_affine(affine: &DAffine3) -> bool {
    let m = affine.matrix3;
    m.is_finite()
        && affine.translation.is_finite()
        && m.determinant().is_normal()
        && m.inverse().is_finite()
}

fn finite_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_round_trip_and_centres() {
        let vol = Volume::axis_aligned(
            [3, 4, 5],
            VoxelValues::F32((0..60).map(|i| i as f32).collect()),
            DVec3::new(0.5, 1.0, 2.0),
            DVec3::new(10.0, 0.0, -1.0),
        )
        .unwrap();
        for idx in 0..60 {
            let [i, j, k] = vol.ijk(idx);
            assert_eq!(vol.index(i, j, k), idx);
        }
        assert_eq!(vol.voxel_centre([2, 3, 4]), DVec3::new(11.0, 3.0, 7.0));
        assert_eq!(vol.value_range(), Some((0.0, 59.0)));
        assert!((vol.voxel_diagonal() - (0.25f64 + 1.0 + 4.0).sqrt()).abs() < 1e-15);
        let s = vol.to_samples();
        assert_eq!(s.positions[59], DVec3::new(11.0, 3.0, 7.0));
        assert_eq!(s.values.unwrap()[7], 7.0);
    }

    #[test]
    fn invalid_inputs_are_refused() {
        let v = || VoxelValues::F64(vec![0.0; 8]);
        assert!(matches!(
            Volume::axis_aligned([2, 0, 4], v(), DVec3::ONE, DVec3::ZERO),
            Err(VolumeError::InvalidDims { .. })
        ));
        assert!(matches!(
            Volume::axis_aligned([2, 2, 3], v(), DVec3::ONE, DVec3::ZERO),
            Err(VolumeError::LengthMismatch { .. })
        ));
        assert_eq!(
            Volume::axis_aligned([2, 2, 2], v(), DVec3::new(1.0, 0.0, 1.0), DVec3::ZERO),
            Err(VolumeError::SingularAffine)
        );
        assert_eq!(
            Volume::axis_aligned([usize::MAX, 2, 2], v(), DVec3::ONE, DVec3::ZERO),
            Err(VolumeError::InvalidDims {
                dims: [usize::MAX, 2, 2]
            })
        );
    }
}
