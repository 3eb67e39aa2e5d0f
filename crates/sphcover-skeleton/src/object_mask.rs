//! Removing noise specks from the object mask before the cover is built.
//!
//! The method is described on [`drop_small_object_components()`].

use sphcover_core::{Volume, VoxelValues};

/// What [`drop_small_object_components`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ObjectMaskStats {
    /// Connected components (26-neighbourhood) of the voxels above the threshold.
    pub components: usize,
    /// Components dropped.
    pub dropped_components: usize,
    /// Voxels in them.
    pub dropped_voxels: usize,
    /// Voxels dropped because the smoothed volume is below the threshold there.
    pub unsmooth_voxels: usize,
}

/// Lowers to `threshold` every voxel of a connected component (26-neighbourhood) of
/// `{v > threshold}` holding fewer than `min_fraction` of the largest component's voxels.
/// With `smooth` (the volume's values smoothed), voxels where the smoothed value is at or
/// below the threshold are lowered first. Returns the new volume (`None` when nothing was
/// dropped) and the counts.
///
/// At high noise a fraction of the background voxels exceeds the threshold (at 30 % noise
/// and a mid-contrast threshold, about 5 % of them). Each would become an object point and
/// then a support centre, and the ridge test would find sheets all over the background. At
/// such densities the specks form small clusters (below the site-percolation threshold of the
/// 26-neighbourhood, about 10 %), while the part is one large cluster: connected components
/// of the mask smaller than a fraction of the largest are dropped by lowering their voxels to
/// the threshold (they stay samples of the fits, no longer object points).
///
/// Specks touching the part survive that test and grow clumps on its faces, each with ridges
/// of its own. When the noise is strong (the pipeline's [`crate::SkeletonParams::smooth_mask_noise`]),
/// the mask is therefore also intersected with the mask of the volume smoothed by a Gaussian
/// of one voxel: a speck is one voxel, and smoothing takes it far below the threshold, while
/// a plate keeps most of its contrast. Below that noise level the smoothed mask is not used,
/// since it would also erode the thinnest plates (a 2-voxel plate blurred by the scanner
/// barely reaches half the contrast). On grids resampled from thick slices the level is
/// lower (a speck there is a needle along the slice axis: see
/// [`crate::SkeletonParams::smooth_mask_noise`]).
pub fn drop_small_object_components(
    volume: &Volume,
    threshold: f64,
    min_fraction: f64,
    smooth: Option<&[f64]>,
) -> (Option<Volume>, ObjectMaskStats) {
    let [nx, ny, nz] = volume.dims();
    let neighbours_26 = |v: usize, visit: &mut dyn FnMut(usize)| {
        let [i, j, k] = volume.ijk(v);
        for dk in -1i64..=1 {
            for dj in -1i64..=1 {
                for di in -1i64..=1 {
                    let (a, b, c) = (i as i64 + di, j as i64 + dj, k as i64 + dk);
                    if a < 0 || b < 0 || c < 0 || a >= nx as i64 || b >= ny as i64 || c >= nz as i64
                    {
                        continue;
                    }
                    visit(volume.index(a as usize, b as usize, c as usize));
                }
            }
        }
    };
    let (values, stats) = lower_specks(
        volume.len(),
        |i| volume.value(i),
        threshold,
        min_fraction,
        smooth,
        neighbours_26,
    );
    let cleaned = values.map(|values| {
        Volume::new(volume.dims(), VoxelValues::F64(values), volume.affine())
            .expect("same dims and affine as a valid volume")
    });
    (cleaned, stats)
}

/// The speck removal of [`drop_small_object_components`] on any `n` points with values
/// `value(i)` and a neighbourhood (`for_each_neighbour(i, visit)` visits the neighbours of
/// `i`): the new values, `None` when nothing was lowered.
pub(crate) fn lower_specks(
    n: usize,
    value: impl Fn(usize) -> f64,
    threshold: f64,
    min_fraction: f64,
    smooth: Option<&[f64]>,
    for_each_neighbour: impl Fn(usize, &mut dyn FnMut(usize)),
) -> (Option<Vec<f64>>, ObjectMaskStats) {
    let raw_object = |i: usize| value(i) > threshold;
    let object: Vec<bool> = (0..n)
        .map(|i| raw_object(i) && smooth.is_none_or(|s| s[i] > threshold))
        .collect();
    let unsmooth_voxels = (0..n).filter(|&i| raw_object(i) && !object[i]).count();
    let mut label = vec![u32::MAX; n];
    let mut sizes: Vec<usize> = Vec::new();
    let mut stack = Vec::new();
    for seed in 0..n {
        if !object[seed] || label[seed] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        let mut size = 0;
        label[seed] = id;
        stack.push(seed);
        while let Some(v) = stack.pop() {
            size += 1;
            for_each_neighbour(v, &mut |w| {
                if object[w] && label[w] == u32::MAX {
                    label[w] = id;
                    stack.push(w);
                }
            });
        }
        sizes.push(size);
    }
    let largest = sizes.iter().copied().max().unwrap_or(0);
    let keep: Vec<bool> = sizes
        .iter()
        .map(|&s| s as f64 >= min_fraction * largest as f64)
        .collect();
    let mut stats = ObjectMaskStats {
        components: sizes.len(),
        dropped_components: keep.iter().filter(|&&k| !k).count(),
        dropped_voxels: 0,
        unsmooth_voxels,
    };
    if stats.dropped_components == 0 && unsmooth_voxels == 0 {
        return (None, stats);
    }
    let values: Vec<f64> = (0..n)
        .map(|i| {
            let l = label[i];
            if l != u32::MAX && !keep[l as usize] {
                stats.dropped_voxels += 1;
                threshold
            } else if raw_object(i) && !object[i] {
                threshold
            } else {
                value(i)
            }
        })
        .collect();
    (Some(values), stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::DVec3;

    #[test]
    fn specks_are_lowered_and_the_part_kept() {
        let n = 12;
        let values: Vec<f64> = (0..n * n * n)
            .map(|idx| {
                let (i, j, k) = (idx % n, (idx / n) % n, idx / (n * n));
                if (4..8).contains(&k) {
                    1.0 // the plate
                } else if (i, j, k) == (2, 2, 1) || (i, j, k) == (9, 9, 10) {
                    0.9 // two specks
                } else {
                    0.0
                }
            })
            .collect();
        let v = Volume::axis_aligned([n, n, n], VoxelValues::F64(values), DVec3::ONE, DVec3::ZERO)
            .unwrap();
        let (cleaned, stats) = drop_small_object_components(&v, 0.5, 0.01, None);
        assert_eq!(
            (
                stats.components,
                stats.dropped_components,
                stats.dropped_voxels
            ),
            (3, 2, 2)
        );
        let cleaned = cleaned.unwrap();
        assert_eq!(cleaned.value(v.index(2, 2, 1)), 0.5);
        assert_eq!(cleaned.value(v.index(5, 5, 5)), 1.0);
        let (none, _) = drop_small_object_components(&cleaned, 0.5, 0.01, None);
        assert!(none.is_none());
        // The smoothed mask drops a lone voxel even when it is kept as a component.
        let smooth: Vec<f64> = (0..v.len())
            .map(|i| {
                if i == v.index(2, 2, 1) {
                    0.1
                } else {
                    v.value(i)
                }
            })
            .collect();
        let (c, stats) = drop_small_object_components(&v, 0.5, 0.0, Some(&smooth));
        assert_eq!(stats.unsmooth_voxels, 1);
        assert_eq!(c.unwrap().value(v.index(2, 2, 1)), 0.5);
    }
}
