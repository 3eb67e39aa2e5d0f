//! The non-finite policy: find vertices whose position, normal or radius holds a NaN or an
//! infinity, or voxels that do, then refuse, drop or keep them.

use std::path::Path;

use rayon::prelude::*;

use super::{Geometry, IoError, NonFinitePolicy, Parsed};
use crate::volume::VoxelValues;

/// Chunk of vertices or voxels per parallel task; fixed so counts never depend on the thread count.
const CHUNK: usize = 1 << 16;

/// Number of non-finite values of vertex `i`.
fn bad_values(parsed: &Parsed, i: usize) -> u64 {
    let p = parsed.points.positions[i];
    let mut bad = p.to_array().iter().filter(|v| !v.is_finite()).count() as u64;
    if let Some(n) = &parsed.points.normals {
        bad += n[i].to_array().iter().filter(|v| !v.is_finite()).count() as u64;
    }
    if let Some(r) = &parsed.radii {
        bad += u64::from(!r[i].is_finite());
    }
    bad
}

pub(crate) fn apply(
    parsed: Parsed,
    policy: NonFinitePolicy,
    path: &Path,
) -> Result<Geometry, IoError> {
    apply_with_columns(parsed, policy, path, &mut [])
}

/// As [`apply`], with extra per-vertex `columns` (read beside the geometry) kept in step:
/// dropping a vertex drops its entry in every column.
pub(crate) fn apply_with_columns(
    mut parsed: Parsed,
    policy: NonFinitePolicy,
    path: &Path,
    columns: &mut [Vec<f64>],
) -> Result<Geometry, IoError> {
    let n = parsed.points.positions.len();
    // Per chunk: (bad vertices, bad values, first bad vertex); summed in chunk order.
    let per_chunk: Vec<(u64, u64, Option<usize>)> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut acc = (0u64, 0u64, None);
            for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
                let bad = bad_values(&parsed, i);
                if bad > 0 {
                    acc.0 += 1;
                    acc.1 += bad;
                    acc.2.get_or_insert(i);
                }
            }
            acc
        })
        .collect();
    let vertices: u64 = per_chunk.iter().map(|c| c.0).sum();
    let coordinates: u64 = per_chunk.iter().map(|c| c.1).sum();
    let first = per_chunk.iter().find_map(|c| c.2);
    parsed.info.non_finite.vertices = vertices;
    parsed.info.non_finite.coordinates = coordinates;

    if let Some(first) = first {
        match policy {
            NonFinitePolicy::Refuse => {
                return Err(IoError::NonFinite {
                    path: path.to_path_buf(),
                    at: parsed.origins.locate(first),
                    index: first as u64,
                    vertices,
                    coordinates,
                });
            }
            NonFinitePolicy::Keep => {}
            NonFinitePolicy::Drop => drop_non_finite(&mut parsed, columns),
        }
    }
    Ok(Geometry {
        points: parsed.points,
        triangles: parsed.triangles,
        radii: parsed.radii,
        info: parsed.info,
    })
}

/// Removes the non-finite vertices and the triangles that use them, renumbering the rest.
fn drop_non_finite(parsed: &mut Parsed, columns: &mut [Vec<f64>]) {
    let n = parsed.points.positions.len();
    let keep: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| bad_values(parsed, i) == 0)
        .collect();
    let mut new_index = vec![u32::MAX; n];
    let mut next = 0u32;
    for (i, &k) in keep.iter().enumerate() {
        if k {
            new_index[i] = next;
            next += 1;
        }
    }
    parsed.points.retain_indices(|i| keep[i]);
    for column in parsed.radii.iter_mut().chain(columns.iter_mut()) {
        let mut i = 0;
        column.retain(|_| {
            i += 1;
            keep[i - 1]
        });
    }
    let before = parsed.triangles.len();
    parsed.triangles.retain_mut(|t| {
        let mapped = t.map(|v| new_index[v as usize]);
        *t = mapped;
        !mapped.contains(&u32::MAX)
    });
    parsed.info.non_finite.dropped_vertices = (n - next as usize) as u64;
    parsed.info.non_finite.dropped_triangles = (before - parsed.triangles.len()) as u64;
}

/// Voxels holding NaN or an infinity, found by [`apply_to_voxels`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct NonFiniteVoxels {
    /// How many.
    pub count: u64,
    /// Linear index of the first one.
    pub first: Option<usize>,
}

/// Finds the non-finite voxels of `values`, then refuses, replaces or keeps them.
///
/// A grid cannot lose a voxel, so [`NonFinitePolicy::Drop`] gives them the lowest finite value
/// of the volume: the background, for the images this crate reads (an object brighter than
/// its surroundings), so that they take part in no object and no fit pulls towards them.
/// A volume without a finite voxel is refused whatever the policy but
/// [`NonFinitePolicy::Keep`].
pub(crate) fn apply_to_voxels(
    values: &mut VoxelValues,
    policy: NonFinitePolicy,
) -> Result<NonFiniteVoxels, NonFiniteVoxels> {
    let found = match values {
        VoxelValues::F32(v) => find_voxels(v, |x| x.is_finite()),
        VoxelValues::F64(v) => find_voxels(v, |x| x.is_finite()),
    };
    if found.count == 0 || policy == NonFinitePolicy::Keep {
        return Ok(found);
    }
    if policy == NonFinitePolicy::Refuse || found.count == values.len() as u64 {
        return Err(found);
    }
    match values {
        VoxelValues::F32(v) => replace_voxels(v, |x| x.is_finite(), f32::min),
        VoxelValues::F64(v) => replace_voxels(v, |x| x.is_finite(), f64::min),
    }
    Ok(found)
}

fn find_voxels<T: Copy + Sync>(values: &[T], finite: fn(T) -> bool) -> NonFiniteVoxels {
    // Fixed chunks summed in order: the first index never depends on the thread count.
    let per_chunk: Vec<NonFiniteVoxels> = values
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let mut found = NonFiniteVoxels::default();
            for (i, &x) in chunk.iter().enumerate() {
                if !finite(x) {
                    found.count += 1;
                    found.first.get_or_insert(c * CHUNK + i);
                }
            }
            found
        })
        .collect();
    NonFiniteVoxels {
        count: per_chunk.iter().map(|f| f.count).sum(),
        first: per_chunk.iter().find_map(|f| f.first),
    }
}

/// Sets the non-finite values to the lowest finite one (which exists: the caller checked).
fn replace_voxels<T: Copy + Send + Sync>(
    values: &mut [T],
    finite: fn(T) -> bool,
    min: fn(T, T) -> T,
) {
    let lowest = values
        .par_chunks(CHUNK)
        .filter_map(|chunk| chunk.iter().copied().filter(|&x| finite(x)).reduce(min))
        .reduce_with(min)
        .expect("at least one finite voxel");
    values.par_iter_mut().for_each(|x| {
        if !finite(*x) {
            *x = lowest;
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with_holes(n: usize, holes: &[(usize, f32)]) -> Vec<f32> {
        let mut v: Vec<f32> = (0..n).map(|i| (i % 97) as f32 - 20.0).collect();
        for &(i, x) in holes {
            v[i] = x;
        }
        v
    }

    #[test]
    fn voxels_are_counted_across_chunks_and_the_first_is_the_lowest_index() {
        let holes = [
            (CHUNK + 3, f32::NAN),
            (5, f32::INFINITY),
            (3 * CHUNK, f32::NEG_INFINITY),
        ];
        let n = 3 * CHUNK + 10;
        for policy in [NonFinitePolicy::Refuse, NonFinitePolicy::Keep] {
            let mut values = VoxelValues::F32(with_holes(n, &holes));
            let result = apply_to_voxels(&mut values, policy);
            let expected = NonFiniteVoxels {
                count: 3,
                first: Some(5),
            };
            match policy {
                NonFinitePolicy::Refuse => assert_eq!(result, Err(expected)),
                _ => assert_eq!(result, Ok(expected)),
            }
            // Neither refusing nor keeping changes a value.
            let VoxelValues::F32(v) = values else {
                unreachable!()
            };
            assert!(v[CHUNK + 3].is_nan() && v[5] == f32::INFINITY);
        }
    }

    #[test]
    fn dropping_gives_voxels_the_lowest_finite_value_and_keeps_the_others() {
        let holes = [(7, f32::NAN), (2 * CHUNK + 1, f32::INFINITY)];
        let original = with_holes(2 * CHUNK + 5, &holes);
        let mut values = VoxelValues::F64(original.iter().map(|&x| f64::from(x)).collect());
        let found = apply_to_voxels(&mut values, NonFinitePolicy::Drop).unwrap();
        assert_eq!(found.count, 2);
        let VoxelValues::F64(v) = values else {
            unreachable!()
        };
        for (i, (&after, &before)) in v.iter().zip(&original).enumerate() {
            if holes.iter().any(|h| h.0 == i) {
                assert_eq!(after, -20.0, "voxel {i}");
            } else {
                assert_eq!(after, f64::from(before), "voxel {i}");
            }
        }
    }

    #[test]
    fn a_volume_without_a_finite_voxel_is_refused_even_when_dropping() {
        let mut values = VoxelValues::F32(vec![f32::NAN; 10]);
        let refused = apply_to_voxels(&mut values, NonFinitePolicy::Drop);
        assert_eq!(
            refused,
            Err(NonFiniteVoxels {
                count: 10,
                first: Some(0)
            })
        );
        let mut clean = VoxelValues::F32(vec![1.0; 10]);
        assert_eq!(
            apply_to_voxels(&mut clean, NonFinitePolicy::Refuse),
            Ok(NonFiniteVoxels::default())
        );
    }
}
