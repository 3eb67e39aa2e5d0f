//! Resampling of a volume along its coarse voxel axes by integer factors with Catmull–Rom
//! interpolation, so that a CT whose slices are a few times its pixels reaches the near-cubic
//! voxels the pipeline works on (see [`crate::Resampling`]).
//!
//! The new grid keeps the world frame: along a resampled axis of `n` voxels, sample `m` of
//! the `(n − 1)·factor + 1` lies at voxel coordinate `m / factor` of the original, so the
//! original centres are samples again (their values copied bit for bit) and
//! [`Volume::voxel_centre`] gives world positions on the original axis. Between them the
//! Catmull–Rom spline interpolates its four neighbours: it reproduces polynomials up to
//! degree two exactly (cubics are not), and unlike a B-spline it leaves the measured values
//! where they are. The border repeats the edge voxel.
//!
//! A non-finite voxel is no sample for the pipeline (the cover skips it, the intensity model
//! ignores it); here it acts as a border of its neighbours' splines and keeps its own place,
//! so it neither turns its neighbours' interpolants non-finite nor grows: between a finite
//! and a non-finite centre each sample takes the nearer one's value (the finite one at a tie).

use std::time::{Duration, Instant};

use rayon::prelude::*;
use sphcover_core::{Volume, VolumeError, VoxelValues};

use crate::error::SkeletonError;
use crate::voxel_grid::{Resampling, resamplable};

/// What [`crate::extract_skeleton`] or [`crate::nms_skeleton`] did to a volume whose voxels
/// were more than [`crate::MAX_ANISOTROPY`] apart before their stages: they ran on the
/// resampled grid, and their outputs are in world coordinates as for any volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResampledGrid {
    /// The voxel size of the input and the factor along each voxel axis.
    pub resampling: Resampling,
    /// Grid dimensions of the input.
    pub original_dims: [usize; 3],
    /// Grid dimensions the stages ran on.
    pub dims: [usize; 3],
    /// Wall time of the resampling (not one of the stages of [`crate::stage_names`]).
    pub time: Duration,
}

/// `volume` resampled as [`Resampling::of`] its voxel size asks, `None` when it is processed
/// as it is: within [`crate::MAX_ANISOTROPY`], and also beyond
/// [`crate::MAX_RESAMPLED_ANISOTROPY`], which [`crate::check_voxel_grid`] refuses, since there
/// the refined grid would grow without bound.
pub(crate) fn resample_if_anisotropic(
    volume: &Volume,
) -> Result<Option<(Volume, ResampledGrid)>, SkeletonError> {
    let size = volume.voxel_size();
    let Some(resampling) = Resampling::of(size).filter(|_| resamplable(size)) else {
        return Ok(None);
    };
    let start = Instant::now();
    let grid = resample_volume(volume, resampling.factors)?;
    let record = ResampledGrid {
        resampling,
        original_dims: volume.dims(),
        dims: grid.dims(),
        time: start.elapsed(),
    };
    Ok(Some((grid, record)))
}

/// The samples of `volume` on its grid refined by `factors[a]` along voxel axis `a` (a factor
/// of 0 is taken as 1), as `f32`, with the voxel→world map adjusted so that world positions
/// stay where they were (see the module's documentation). With every factor 1 the volume is
/// returned as it is. The result does not depend on the number of threads.
///
/// Fails only when the refined grid's voxel count does not fit in `usize`.
pub fn resample_volume(volume: &Volume, factors: [usize; 3]) -> Result<Volume, VolumeError> {
    let factors = factors.map(|f| f.max(1));
    if factors == [1; 3] {
        return Ok(volume.clone());
    }
    let mut dims = volume.dims();
    let mut data: Option<Vec<f32>> = None;
    for (axis, &factor) in factors.iter().enumerate() {
        if factor == 1 {
            continue;
        }
        let refined =
            refined_length(dims[axis], factor).ok_or_else(|| VolumeError::InvalidDims {
                dims: Resampling {
                    size: volume.voxel_size(),
                    factors,
                }
                .dims(volume.dims()),
            })?;
        let next = match (&data, volume.values()) {
            (Some(values), _) => refine_axis(values, dims, axis, factor, refined)?,
            (None, VoxelValues::F32(values)) => refine_axis(values, dims, axis, factor, refined)?,
            (None, VoxelValues::F64(values)) => refine_axis(values, dims, axis, factor, refined)?,
        };
        dims[axis] = refined;
        data = Some(next);
    }
    let mut affine = volume.affine();
    for (axis, &factor) in factors.iter().enumerate() {
        let column = affine.matrix3.col_mut(axis);
        *column /= factor as f64;
    }
    let values = data.map_or_else(|| volume.values().clone(), VoxelValues::F32);
    Volume::new(dims, values, affine)
}

/// `(n − 1)·factor + 1`, `None` on overflow.
fn refined_length(n: usize, factor: usize) -> Option<usize> {
    n.checked_sub(1)?.checked_mul(factor)?.checked_add(1)
}

/// A voxel value as the interpolation reads it.
trait Sample: Copy + Send + Sync {
    fn to_f64(self) -> f64;
    fn to_f32(self) -> f32;
}

impl Sample for f32 {
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn to_f32(self) -> f32 {
        self
    }
}

impl Sample for f64 {
    fn to_f64(self) -> f64 {
        self
    }
    fn to_f32(self) -> f32 {
        self as f32
    }
}

/// The Catmull–Rom weights of the samples at offsets −1, 0, 1, 2 for a point at `t ∈ [0, 1]`
/// between offsets 0 and 1.
fn catmull_rom_weights(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// `values` (grid `dims`, x fastest) refined along `axis` by `factor` to `refined` samples.
fn refine_axis<T: Sample>(
    values: &[T],
    dims: [usize; 3],
    axis: usize,
    factor: usize,
    refined: usize,
) -> Result<Vec<f32>, VolumeError> {
    let mut out_dims = dims;
    out_dims[axis] = refined;
    let count = out_dims
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .ok_or(VolumeError::InvalidDims { dims: out_dims })?;
    let weights: Vec<[f64; 4]> = (0..factor)
        .map(|r| catmull_rom_weights(r as f64 / factor as f64))
        .collect();
    let stride = [1, dims[0], dims[0] * dims[1]][axis];
    let n = dims[axis];
    let row = out_dims[0];
    let mut out = vec![0.0f32; count];
    out.par_chunks_mut(row)
        .with_min_len(64)
        .enumerate()
        .for_each(|(r, line)| {
            let (j, k) = (r % out_dims[1], r / out_dims[1]);
            for (i, slot) in line.iter_mut().enumerate() {
                let mut ijk = [i, j, k];
                let m = ijk[axis];
                let (at, rem) = (m / factor, m % factor);
                ijk[axis] = 0;
                let base = ijk[0] + dims[0] * (ijk[1] + dims[1] * ijk[2]);
                let get = |p: usize| values[base + p * stride];
                *slot = if rem == 0 {
                    get(at).to_f32()
                } else {
                    interpolate(|p| get(p).to_f64(), n, at, rem, factor, &weights[rem])
                };
            }
        });
    Ok(out)
}

/// The sample at `rem / factor` of the way from original sample `at` to `at + 1` (both
/// inside the `n` samples) of the line `get`.
fn interpolate(
    get: impl Fn(usize) -> f64,
    n: usize,
    at: usize,
    rem: usize,
    factor: usize,
    weights: &[f64; 4],
) -> f32 {
    let (p1, p2) = (get(at), get(at + 1));
    if !(p1.is_finite() && p2.is_finite()) {
        // Nearest neighbour: a non-finite voxel keeps its own half-spacing, no more.
        let nearer_first = 2 * rem < factor || (2 * rem == factor && p1.is_finite());
        return (if nearer_first { p1 } else { p2 }) as f32;
    }
    let outer = |p: Option<usize>, edge: f64| p.map(&get).filter(|v| v.is_finite()).unwrap_or(edge);
    let p0 = outer(at.checked_sub(1), p1);
    let p3 = outer(Some(at + 2).filter(|&p| p < n), p2);
    (weights[0] * p0 + weights[1] * p1 + weights[2] * p2 + weights[3] * p3) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DAffine3, DMat3, DVec3};
    use proptest::prelude::*;

    /// A volume of `dims` whose voxel `(i, j, k)` holds `f(i, j, k)`, on an affine with
    /// permuted, flipped and scaled axes.
    fn volume_of(dims: [usize; 3], f: impl Fn(f64, f64, f64) -> f64) -> Volume {
        let mut values = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    values.push(f(i as f64, j as f64, k as f64) as f32);
                }
            }
        }
        let affine = DAffine3::from_mat3_translation(
            DMat3::from_cols(DVec3::Y * -0.7, DVec3::X * 0.7, DVec3::Z * 3.1),
            DVec3::new(-12.0, 40.5, 7.25),
        );
        Volume::new(dims, VoxelValues::F32(values), affine).unwrap()
    }

    fn values(volume: &Volume) -> &[f32] {
        match volume.values() {
            VoxelValues::F32(v) => v,
            VoxelValues::F64(_) => panic!("resampled values are f32"),
        }
    }

    /// The original voxel coordinates of sample `ijk` of a grid refined by `factors`.
    fn original_coordinates(ijk: [usize; 3], factors: [usize; 3]) -> DVec3 {
        DVec3::from_array(std::array::from_fn(|a| ijk[a] as f64 / factors[a] as f64))
    }

    /// Whether the four taps of the spline at refined coordinate `m` along an axis of `n`
    /// original samples lie inside the grid (away from the clamped borders).
    fn interior(m: usize, factor: usize, n: usize) -> bool {
        let at = m / factor;
        m.is_multiple_of(factor) || (at >= 1 && at + 2 < n)
    }

    fn dims_and_factors() -> impl Strategy<Value = ([usize; 3], [usize; 3])> {
        (
            prop::array::uniform3(1usize..7),
            prop::array::uniform3(1usize..5),
        )
    }

    proptest! {
        #[test]
        fn constants_are_kept((dims, factors) in dims_and_factors(), c in -3e3f32..3e3) {
            let out = resample_volume(&volume_of(dims, |_, _, _| f64::from(c)), factors).unwrap();
            prop_assert!(values(&out).iter().all(|&v| v == c));
        }

        /// The original samples come back bit for bit, non-finite ones included.
        #[test]
        fn original_centres_keep_their_values(
            (dims, factors) in dims_and_factors(),
            seed in 0u64..1000,
        ) {
            let v = volume_of(dims, |i, j, k| {
                let h = (i * 12.9898 + j * 78.233 + k * 37.719 + seed as f64).sin() * 43758.5453;
                match (h.fract().abs() * 20.0) as usize {
                    0 => f64::NAN,
                    1 => f64::INFINITY,
                    _ => h,
                }
            });
            let out = resample_volume(&v, factors).unwrap();
            for idx in 0..v.len() {
                let [i, j, k] = v.ijk(idx);
                let o = out.index(i * factors[0], j * factors[1], k * factors[2]);
                prop_assert_eq!(values(&out)[o].to_bits(), values(&v)[idx].to_bits());
            }
        }

        /// Away from the borders the spline reproduces polynomials of degree two along each
        /// resampled axis, so linear and quadratic ramps come out as they were rendered.
        #[test]
        fn quadratics_are_reproduced_inside(
            (dims, factors) in dims_and_factors(),
            a in -10.0..10.0f64,
            b in prop::array::uniform3(-5.0..5.0f64),
            q in prop::array::uniform3(-1.0..1.0f64),
        ) {
            let f = |x: DVec3| a + DVec3::from_array(b).dot(x) + DVec3::from_array(q).dot(x * x);
            let v = volume_of(dims, |i, j, k| f(DVec3::new(i, j, k)));
            let out = resample_volume(&v, factors).unwrap();
            for idx in 0..out.len() {
                let ijk = out.ijk(idx);
                if (0..3).all(|a| interior(ijk[a], factors[a], dims[a])) {
                    let expected = f(original_coordinates(ijk, factors));
                    let got = f64::from(values(&out)[idx]);
                    // The inputs are rounded to f32 before the spline sees them.
                    prop_assert!((got - expected).abs() <= 1e-4, "{ijk:?}: {got} vs {expected}");
                }
            }
        }

        /// The new voxel centres lie on the original grid lines, at fractions of a voxel.
        #[test]
        fn new_centres_stay_in_the_world_frame((dims, factors) in dims_and_factors()) {
            let v = volume_of(dims, |i, _, _| i);
            let out = resample_volume(&v, factors).unwrap();
            prop_assert_eq!(
                out.dims(),
                std::array::from_fn(|a| (dims[a] - 1) * factors[a] + 1)
            );
            let last = out.dims().map(|d| d - 1);
            for ijk in [[0, 0, 0], last, [last[0] / 2, last[1], last[2] / 3]] {
                let expected = v.affine().transform_point3(original_coordinates(ijk, factors));
                prop_assert!((out.voxel_centre(ijk) - expected).length() < 1e-12);
            }
            let size = out.voxel_size() * DVec3::from_array(factors.map(|f| f as f64));
            prop_assert!((size - v.voxel_size()).abs().max_element() < 1e-12);
        }
    }

    #[test]
    fn non_finite_voxels_do_not_spread() {
        let dims = [3, 2, 9];
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let v = volume_of(dims, |_, _, k| if k == 4.0 { bad } else { 100.0 * k });
            for factor in 1..=4 {
                let out = resample_volume(&v, [1, 1, factor]).unwrap();
                for idx in 0..out.len() {
                    let k = out.ijk(idx)[2] as f64 / factor as f64;
                    let value = values(&out)[idx];
                    // Only the samples within half a slice of the bad one take its value.
                    if (k - 4.0).abs() < 0.5 {
                        assert_eq!(value.to_bits(), (bad as f32).to_bits(), "k {k}");
                    } else {
                        assert!(value.is_finite(), "k {k}: {value}");
                    }
                    // Beside it, the spline repeats the neighbour as it does at a border:
                    // the ramp's values stay within their slices' range.
                    if (k - 4.0).abs() >= 0.5 && (k - 4.0).abs() <= 1.0 {
                        let near = if k < 4.0 { 300.0 } else { 500.0 };
                        assert_eq!(value, near, "k {k}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_border_repeats_the_edge_voxel() {
        // A ramp 0, 1, 2 refined by 2: the end segments take tangents from the repeated
        // edge (half the ramp's slope at the ends), the middle sample is exact.
        let v = volume_of([1, 1, 3], |_, _, k| k);
        let out = resample_volume(&v, [1, 1, 2]).unwrap();
        assert_eq!(values(&out), [0.0, 0.4375, 1.0, 1.5625, 2.0]);
    }

    #[test]
    fn only_grids_within_the_limit_are_resampled_by_the_pipeline() {
        let grid = |z: f64| {
            Volume::axis_aligned(
                [2, 2, 3],
                VoxelValues::F32(vec![0.0; 12]),
                DVec3::new(0.5, 0.5, z),
                DVec3::ZERO,
            )
            .unwrap()
        };
        assert!(resample_if_anisotropic(&grid(0.875)).unwrap().is_none());
        let (resampled, record) = resample_if_anisotropic(&grid(2.5)).unwrap().unwrap();
        assert_eq!((record.dims, resampled.dims()), ([2, 2, 7], [2, 2, 7]));
        assert_eq!(record.original_dims, [2, 2, 3]);
        // Refused by the grid check, and no refinement without bound here.
        assert!(resample_if_anisotropic(&grid(50.0)).unwrap().is_none());
    }

    #[test]
    fn double_values_and_unit_factors() {
        let v = Volume::axis_aligned(
            [2, 1, 2],
            VoxelValues::F64(vec![0.1, 0.2, 0.3, 0.4]),
            DVec3::new(0.5, 0.5, 1.5),
            DVec3::ZERO,
        )
        .unwrap();
        assert_eq!(resample_volume(&v, [1, 1, 1]).unwrap(), v);
        assert_eq!(resample_volume(&v, [0, 1, 1]).unwrap(), v);
        let out = resample_volume(&v, [1, 1, 3]).unwrap();
        assert_eq!(out.dims(), [2, 1, 4]);
        assert_eq!(values(&out)[0], 0.1f32);
        assert_eq!(values(&out)[7], 0.4f32);
        assert_eq!(out.voxel_size(), DVec3::new(0.5, 0.5, 0.5));
    }

    #[test]
    fn every_thread_count_gives_the_same_samples() {
        let v = volume_of([17, 9, 23], |i, j, k| (i * 0.7).sin() * 300.0 + j * k);
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| resample_volume(&v, [1, 3, 4]).unwrap())
        };
        let one = run(1);
        assert_eq!(
            values(&one).iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            values(&run(4))
                .iter()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        );
    }
}
