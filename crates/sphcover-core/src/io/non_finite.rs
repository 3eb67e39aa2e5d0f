//! The non-finite policy: find vertices whose position, normal or radius holds a NaN or an
//! infinity, then refuse, drop or keep them.

use std::path::Path;

use rayon::prelude::*;

use super::{Geometry, IoError, NonFinitePolicy, Parsed};

/// Chunk of vertices per parallel task; fixed so counts never depend on the thread count.
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
