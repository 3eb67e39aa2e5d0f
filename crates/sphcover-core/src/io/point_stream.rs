//! Scan files read a block of points at a time, for scans larger than memory.
//!
//! * Binary PLY whose vertex records have a fixed size and come first in the body (what
//!   every scanner and point tool writes), and LAS, are decoded straight from a read-only map
//!   of the file, block by block; the pages of each block are handed back to the system once
//!   decoded, so the process holds about one block whatever the file's size.
//! * LAZ is decompressed block by block; the compressed file stays mapped (a tenth of the
//!   points' size, or less).
//! * Other files (ascii PLY, PLY with lists in the vertex records, text formats, meshes)
//!   are read whole and then handed out in blocks.
//!
//! The blocks carry what [`read_point_cloud`](super::read_point_cloud) gives for the same
//! file (positions, normals, confidence, values, colours), except that LAS blocks carry
//! positions only: whether LAS colours are 8 or 16 bits is decided over the whole file. No
//! [`NonFinitePolicy`](super::NonFinitePolicy) is applied: a consumer meets non-finite points
//! as they are.

use std::path::Path;

use super::error::{Failure, Location, Problem};
use super::ply::header::{Encoding, parse_header, vertex_roles};
use super::{Format, IoError, ReadOptions};
use crate::point_cloud::PointCloud;

/// What [`stream_points`] went through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PointStreamInfo {
    /// The file's format.
    pub format: Format,
    /// Points handed out.
    pub points: u64,
    /// Whether the file was read a block at a time (`false`: read whole, then handed out).
    pub streamed: bool,
}

/// Reads the points of the file at `path` in blocks of at most `block` points (at least 1)
/// and hands each to `visit`, in file order; stops at the first error `visit` returns. A
/// damaged file gives the same [`IoError`] its whole read gives, naming the file and the
/// byte or line, possibly after some blocks were handed out.
///
/// ```
/// # fn main() -> Result<(), sphcover_core::io::IoError> {
/// use sphcover_core::{DVec3, PointCloud, io};
/// let dir = std::env::temp_dir().join(format!("sphcover-doc-stream-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let path = dir.join("line.ply");
/// let cloud = PointCloud::from_positions((0..10).map(|i| DVec3::new(i as f64, 0.0, 0.0)).collect());
/// io::write_point_cloud(&path, &cloud, &io::WriteOptions::default())?;
/// let mut sizes = Vec::new();
/// io::stream_points(&path, &io::ReadOptions::default(), 4, |block| {
///     sizes.push(block.len());
///     Ok::<(), io::IoError>(())
/// })?;
/// assert_eq!(sizes, [4, 4, 2]);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// # Ok(())
/// # }
/// ```
pub fn stream_points<E: From<IoError>>(
    path: &Path,
    options: &ReadOptions,
    block: usize,
    mut visit: impl FnMut(PointCloud) -> Result<(), E>,
) -> Result<PointStreamInfo, E> {
    let block = block.max(1);
    let format = Format::from_path(path)?;
    let read_error = |source| IoError::Read {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(read_error)?;
    let size = file.metadata().map_err(read_error)?.len();
    let map = (size > 0).then(|| super::map_file(&file)).flatten();
    let streamed = match (&map, format) {
        (Some(map), Format::Ply) => stream_ply(map, path, block, &mut visit)?,
        (Some(map), Format::Las) => stream_las(map, path, block, &mut visit)?,
        _ => None,
    };
    if let Some(points) = streamed {
        return Ok(PointStreamInfo {
            format,
            points,
            streamed: true,
        });
    }
    drop(map);
    let whole = super::read_point_cloud(
        path,
        &ReadOptions {
            non_finite: super::NonFinitePolicy::Keep,
            ..options.clone()
        },
    )?;
    let points = whole.len() as u64;
    for start in (0..whole.len()).step_by(block) {
        visit(slice(&whole, start..(start + block).min(whole.len())))?;
    }
    Ok(PointStreamInfo {
        format,
        points,
        streamed: false,
    })
}

/// Hands back the pages of `map[start..end]` to the system (they were read and are not
/// needed again); best effort.
#[allow(unsafe_code)]
fn release(map: &memmap2::Mmap, start: usize, end: usize) {
    const PAGE: usize = 4096;
    let (first, last) = (start.div_ceil(PAGE) * PAGE, end / PAGE * PAGE);
    if last > first {
        // SAFETY: the map is private and read-only, so dropping its pages loses nothing: a
        // later access would read them from the file again. Nothing here reads them again.
        let _ = unsafe {
            map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, first, last - first)
        };
    }
}

/// Binary PLY with fixed-size vertex records first in the body, block by block; `None` for
/// other layouts (read whole instead).
fn stream_ply<E: From<IoError>>(
    map: &memmap2::Mmap,
    path: &Path,
    block: usize,
    visit: &mut impl FnMut(PointCloud) -> Result<(), E>,
) -> Result<Option<u64>, E> {
    let bytes: &[u8] = map;
    let fail = |f: Failure| E::from(f.into_io(path));
    let header = parse_header(bytes).map_err(fail)?;
    let big = match header.encoding {
        Encoding::Ascii => return Ok(None),
        Encoding::BinaryLittleEndian => false,
        Encoding::BinaryBigEndian => true,
    };
    let Some(element) = header.elements.first().filter(|e| e.name == "vertex") else {
        return Ok(None);
    };
    let Some(stride) = element.fixed_size() else {
        return Ok(None);
    };
    let roles = vertex_roles(element).map_err(fail)?;
    let start = header.body_start;
    let available = ((bytes.len() - start) / stride.max(1)) as u64;
    if element.count > available {
        let at = Location::Byte((start as u64) + available * stride as u64);
        return Err(fail(Failure::new(
            at,
            Problem::Truncated {
                element: element.name.clone(),
                index: available,
                declared: element.count,
            },
        )));
    }
    let records = Records {
        start,
        stride,
        count: element.count as usize,
    };
    records.each_block(map, block, visit, |data| {
        super::ply::decode_vertex_block(data, element, &roles, big)
    })?;
    Ok(Some(element.count))
}

/// Fixed-size records in a map: `count` of `stride` bytes from byte `start`.
struct Records {
    start: usize,
    stride: usize,
    count: usize,
}

impl Records {
    /// Decodes the records `block` at a time and hands each block to `visit`, handing the
    /// pages of each block back to the system once decoded.
    fn each_block<E>(
        &self,
        map: &memmap2::Mmap,
        block: usize,
        visit: &mut impl FnMut(PointCloud) -> Result<(), E>,
        decode: impl Fn(&[u8]) -> PointCloud,
    ) -> Result<(), E> {
        for first in (0..self.count).step_by(block) {
            let last = (first + block).min(self.count);
            let (a, b) = (
                self.start + first * self.stride,
                self.start + last * self.stride,
            );
            let cloud = decode(&map[a..b]);
            release(map, a, b);
            visit(cloud)?;
        }
        Ok(())
    }
}

/// LAS and LAZ positions, block by block.
fn stream_las<E: From<IoError>>(
    map: &memmap2::Mmap,
    path: &Path,
    block: usize,
    visit: &mut impl FnMut(PointCloud) -> Result<(), E>,
) -> Result<Option<u64>, E> {
    use rayon::prelude::*;
    let bytes: &[u8] = map;
    let fail = |f: Failure| E::from(f.into_io(path));
    let layout = super::las::layout(bytes).map_err(fail)?;
    let positions = |records: &[u8]| -> PointCloud {
        PointCloud::from_positions(
            records
                .par_chunks_exact(layout.record_length)
                .map(|r| layout.position(r))
                .collect(),
        )
    };
    if layout.compressed {
        // `visit`'s error is carried past the decompressor, which speaks `Failure` only.
        let mut stopped: Option<E> = None;
        let result = layout.decompress_blocks(bytes, block as u64, |records| {
            match visit(positions(records)) {
                Ok(()) => Ok(()),
                Err(e) => {
                    stopped = Some(e);
                    Err(Failure::header(Location::Byte(0), "stopped"))
                }
            }
        });
        if let Some(e) = stopped {
            return Err(e);
        }
        result.map_err(fail)?;
        return Ok(Some(layout.count));
    }
    let records = Records {
        start: layout.offset,
        stride: layout.record_length,
        count: layout.count as usize,
    };
    records.each_block(map, block, visit, positions)?;
    Ok(Some(layout.count))
}

/// Points `range` of `cloud`, with their attributes.
fn slice(cloud: &PointCloud, range: std::ops::Range<usize>) -> PointCloud {
    fn part<T: Clone>(v: &Option<Vec<T>>, r: &std::ops::Range<usize>) -> Option<Vec<T>> {
        v.as_ref().map(|v| v[r.clone()].to_vec())
    }
    PointCloud {
        positions: cloud.positions[range.clone()].to_vec(),
        normals: part(&cloud.normals, &range),
        confidence: part(&cloud.confidence, &range),
        values: part(&cloud.values, &range),
        colors: part(&cloud.colors, &range),
    }
}
