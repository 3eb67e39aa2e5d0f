//! ASPRS LAS point clouds (`.las`), versions 1.0 to 1.4, point data record formats 0 to 10;
//! read only.
//!
//! * Positions are `raw · scale + offset` in `f64`, with the scale and offset of the public
//!   header block; every point record format starts with the `i32` triple `X Y Z`.
//! * The `u16` intensity, which every record format stores right after `X Y Z` (byte 12),
//!   becomes [`PointCloud::values`].
//! * The `u16` red, green and blue of formats 2, 3, 5, 7, 8 and 10 become
//!   [`PointCloud::colors`]. The specification scales them to 16 bits, but many writers
//!   store 8-bit values as they are: when no channel of the file exceeds 255 the values are
//!   taken as 8-bit, else divided down from 16 bits. A file whose colours are all black
//!   declares colour fields it never filled (writers zero them): it gets no colours.
//! * The other fields (returns, classification, GPS time, waveforms, extra bytes) are not
//!   read.
//! * Records are `point data record length` bytes apart, starting at `offset to point
//!   data`; a length larger than the format's minimum (extra bytes) is allowed.
//! * The point count is the 64-bit count of the 1.4 header when it is non-zero, else the
//!   legacy 32-bit count; it is checked against the bytes present before anything is
//!   allocated.
//! * Compressed LAZ files (the point format with bit 7 or 6 set, as LASzip writes it) are
//!   decompressed first ([`super::laz`]) and then read as the same LAS file uncompressed.
//! * Variable length records are skipped (but LAZ's, which describes the compression).

use glam::DVec3;
use rayon::prelude::*;

use super::error::{Failure, Location, MemoryBudget, Problem};
use super::{ElementInfo, FileInfo, Format, Parsed, PropertyInfo, VertexOrigins};
use crate::point_cloud::PointCloud;

/// Size of the LAS 1.0–1.2 public header block; later versions only add to it.
const MIN_HEADER: usize = 227;
/// Size of the LAS 1.4 public header block (with the 64-bit point count).
const HEADER_1_4: usize = 375;

/// Fields of one point data record format, as `(name, type)`, in file order.
fn record_fields(format: u8) -> Vec<(&'static str, &'static str)> {
    let mut fields = vec![
        ("x", "int"),
        ("y", "int"),
        ("z", "int"),
        ("intensity", "ushort"),
    ];
    if format <= 5 {
        fields.extend([
            ("return_flags", "uchar"),
            ("classification", "uchar"),
            ("scan_angle_rank", "char"),
            ("user_data", "uchar"),
            ("point_source_id", "ushort"),
        ]);
        if matches!(format, 1 | 3 | 4 | 5) {
            fields.push(("gps_time", "double"));
        }
        if matches!(format, 2 | 3 | 5) {
            fields.extend([("red", "ushort"), ("green", "ushort"), ("blue", "ushort")]);
        }
    } else {
        fields.extend([
            ("return_flags", "uchar"),
            ("classification_flags", "uchar"),
            ("classification", "uchar"),
            ("user_data", "uchar"),
            ("scan_angle", "short"),
            ("point_source_id", "ushort"),
            ("gps_time", "double"),
        ]);
        if matches!(format, 7 | 8 | 10) {
            fields.extend([("red", "ushort"), ("green", "ushort"), ("blue", "ushort")]);
        }
        if matches!(format, 8 | 10) {
            fields.push(("nir", "ushort"));
        }
    }
    if matches!(format, 4 | 5 | 9 | 10) {
        fields.extend([
            ("wave_packet_index", "uchar"),
            ("wave_offset", "ulong"),
            ("wave_size", "uint"),
            ("return_point_location", "float"),
            ("x_t", "float"),
            ("y_t", "float"),
            ("z_t", "float"),
        ]);
    }
    fields
}

/// Bytes of a field type named in [`record_fields`].
fn type_size(type_name: &str) -> usize {
    match type_name {
        "uchar" | "char" => 1,
        "ushort" | "short" => 2,
        "int" | "uint" | "float" => 4,
        _ => 8,
    }
}

/// The minimum record length of a point data record format (the sum of its fields).
pub(crate) fn min_record_length(format: u8) -> usize {
    record_fields(format)
        .iter()
        .map(|(_, t)| type_size(t))
        .sum()
}

fn header(at: usize, message: impl Into<String>) -> Failure {
    Failure::header(Location::Byte(at as u64), message)
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(a)
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_bits(u64_at(b, at))
}

/// A fixed-width text field of the header, up to its first NUL, trimmed.
fn text_at(b: &[u8], at: usize, len: usize) -> String {
    let raw = &b[at..at + len];
    let end = raw.iter().position(|&c| c == 0).unwrap_or(len);
    String::from_utf8_lossy(&raw[..end]).trim().to_string()
}

/// Bytes of a point in memory: its position and its intensity (and 3 of colour for the
/// formats with RGB).
const POINT_BYTES: u64 = 24 + 8;

/// Byte offset of the red, green, blue `u16` triple in a record of `format`, if it has one.
fn rgb_offset(format: u8) -> Option<usize> {
    match format {
        2 => Some(20),
        3 | 5 => Some(28),
        7 | 8 | 10 => Some(30),
        _ => None,
    }
}

/// The records' colours as bytes (see the module notes for the scaling), or `None` when the
/// format has none or every colour is black.
fn record_colors(data: &[u8], record_length: usize, at: usize) -> Option<Vec<[u8; 3]>> {
    let rgb = |r: &[u8]| [0, 2, 4].map(|k| u16_at(r, at + k));
    let records = || data.par_chunks_exact(record_length);
    let brightest = records()
        .map(|r| rgb(r).into_iter().max().unwrap_or(0))
        .max()?;
    if brightest == 0 {
        return None;
    }
    let scale = if brightest > 255 {
        255.0 / f64::from(u16::MAX)
    } else {
        1.0
    };
    let mut colors = Vec::new();
    records()
        .map(|r| rgb(r).map(|c| (f64::from(c) * scale).round() as u8))
        .collect_into_vec(&mut colors);
    Some(colors)
}

/// Reads a LAS file; the points must fit in `limit` bytes.
/// Where and how a LAS file stores its points, from its public header block.
pub(crate) struct LasLayout {
    pub major: u8,
    pub minor: u8,
    pub header_size: usize,
    pub compressed: bool,
    pub point_format: u8,
    pub record_length: usize,
    pub min_length: usize,
    /// Byte where the point records start.
    pub offset: usize,
    pub count: u64,
    pub scale: DVec3,
    pub shift: DVec3,
}

impl LasLayout {
    /// The position of a point record.
    #[inline]
    pub(crate) fn position(&self, r: &[u8]) -> DVec3 {
        let raw = DVec3::new(
            f64::from(u32_at(r, 0) as i32),
            f64::from(u32_at(r, 4) as i32),
            f64::from(u32_at(r, 8) as i32),
        );
        raw * self.scale + self.shift
    }

    /// Decompresses the records of a LAZ file (`bytes` is the whole file).
    pub(crate) fn decompress(&self, bytes: &[u8]) -> Result<Vec<u8>, Failure> {
        super::laz::decompress_records(bytes, self.compression(bytes))
    }

    /// Where the compressed records are and what they decompress to: `(vlr_start,
    /// vlr_count, offset, count, record_length)`.
    fn compression(&self, bytes: &[u8]) -> (usize, u32, usize, u64, usize) {
        (
            self.header_size,
            u32_at(bytes, 100),
            self.offset,
            self.count,
            self.record_length,
        )
    }

    /// Decompresses the records of a LAZ file `block_points` at a time (see
    /// [`super::laz::decompress_blocks`]).
    pub(crate) fn decompress_blocks(
        &self,
        bytes: &[u8],
        block_points: u64,
        visit: impl FnMut(&[u8]) -> Result<(), Failure>,
    ) -> Result<(), Failure> {
        super::laz::decompress_blocks(bytes, self.compression(bytes), block_points, visit)
    }
}

/// Checks the public header block of the LAS file `bytes` (the whole file: uncompressed
/// records are checked against its length) and says where its points are.
pub(crate) fn layout(bytes: &[u8]) -> Result<LasLayout, Failure> {
    if !bytes.starts_with(b"LASF") {
        let found = super::error::token_for_message(&bytes[..bytes.len().min(4)]);
        return Err(header(
            0,
            format!("signature {found:?} is not \"LASF\": not a LAS file"),
        ));
    }
    if bytes.len() < MIN_HEADER {
        return Err(header(
            bytes.len(),
            format!(
                "file ends inside the {MIN_HEADER}-byte LAS public header ({} bytes)",
                bytes.len()
            ),
        ));
    }
    let (major, minor) = (bytes[24], bytes[25]);
    if major != 1 || minor > 4 {
        return Err(header(
            24,
            format!("version {major}.{minor} is not LAS 1.0 to 1.4"),
        ));
    }
    let header_size = usize::from(u16_at(bytes, 94));
    let required = match minor {
        0..=2 => MIN_HEADER,
        3 => MIN_HEADER + 8,
        _ => HEADER_1_4,
    };
    if header_size < required {
        return Err(header(
            94,
            format!(
                "header size {header_size} is smaller than the {required} bytes of a LAS 1.{minor} header"
            ),
        ));
    }
    if bytes.len() < header_size {
        return Err(header(
            bytes.len(),
            format!(
                "file ends inside the {header_size}-byte LAS public header ({} bytes)",
                bytes.len()
            ),
        ));
    }
    let compressed = bytes[104] & 0xC0 != 0;
    let point_format = bytes[104] & 0x3F;
    if point_format > 10 {
        return Err(header(
            104,
            format!("point data record format {point_format} is not one of 0 to 10"),
        ));
    }
    let record_length = usize::from(u16_at(bytes, 105));
    let min_length = min_record_length(point_format);
    if record_length < min_length {
        return Err(header(
            105,
            format!(
                "point data record length {record_length} is shorter than the {min_length} bytes of point format {point_format}"
            ),
        ));
    }
    let offset = u32_at(bytes, 96) as usize;
    if offset < header_size {
        return Err(header(
            96,
            format!("offset to point data {offset} lies inside the {header_size}-byte header"),
        ));
    }
    let legacy_count = u64::from(u32_at(bytes, 107));
    // `header_size ≥ 375` was checked for 1.4, so the 64-bit count is within the file.
    let count = match minor {
        4.. => match u64_at(bytes, 247) {
            0 => legacy_count,
            n => n,
        },
        _ => legacy_count,
    };
    let mut scale = [0.0; 3];
    let mut shift = [0.0; 3];
    for axis in 0..3 {
        let s_at = 131 + 8 * axis;
        let o_at = 155 + 8 * axis;
        scale[axis] = f64_at(bytes, s_at);
        shift[axis] = f64_at(bytes, o_at);
        if !(scale[axis].is_finite() && scale[axis] != 0.0) {
            return Err(header(
                s_at,
                format!(
                    "{} scale factor {} is not finite and non-zero",
                    ["x", "y", "z"][axis],
                    scale[axis]
                ),
            ));
        }
        if !shift[axis].is_finite() {
            return Err(header(
                o_at,
                format!(
                    "{} offset {} is not finite",
                    ["x", "y", "z"][axis],
                    shift[axis]
                ),
            ));
        }
    }

    let available = bytes.len().saturating_sub(offset) as u64 / record_length as u64;
    if !compressed && count > available {
        let first_missing =
            (offset as u64 + available * record_length as u64).min(bytes.len() as u64);
        return Err(Failure::new(
            Location::Byte(first_missing),
            Problem::Truncated {
                element: "vertex".into(),
                index: available,
                declared: count,
            },
        ));
    }
    // Zero points at an offset past the end: nothing is truncated, but the header lies.
    if offset > bytes.len() {
        return Err(header(
            96,
            format!(
                "point data offset {offset} lies past the end of the file ({} bytes)",
                bytes.len()
            ),
        ));
    }
    Ok(LasLayout {
        major,
        minor,
        header_size,
        compressed,
        point_format,
        record_length,
        min_length,
        offset,
        count,
        scale: DVec3::from_array(scale),
        shift: DVec3::from_array(shift),
    })
}

pub(crate) fn read(bytes: &[u8], limit: Option<u64>) -> Result<Parsed, Failure> {
    let layout = layout(bytes)?;
    let LasLayout {
        major,
        minor,
        compressed,
        point_format,
        record_length,
        min_length,
        offset,
        count,
        ..
    } = layout;
    let mut budget = MemoryBudget::new(limit);
    if compressed {
        budget.reserve(count.saturating_mul(record_length as u64), || {
            format!("{count} compressed records of {record_length} bytes")
        })?;
    }
    let point_bytes = POINT_BYTES
        + if rgb_offset(point_format).is_some() {
            3
        } else {
            0
        };
    budget.reserve(count.saturating_mul(point_bytes), || {
        format!("{count} points")
    })?;
    let decompressed;
    let data = if compressed {
        decompressed = layout.decompress(bytes)?;
        &decompressed[..]
    } else {
        // `count ≤ available`, so this fits in `usize`: it is bounded by the file size.
        &bytes[offset..offset + count as usize * record_length]
    };
    let (positions, values): (Vec<DVec3>, Vec<f64>) = data
        .par_chunks_exact(record_length)
        .map(|r| (layout.position(r), f64::from(u16_at(r, 12))))
        .unzip();
    let colors = rgb_offset(point_format).and_then(|at| record_colors(data, record_length, at));

    let mut info = FileInfo::new(
        Format::Las,
        format!(
            "{} {major}.{minor}, point format {point_format}",
            if compressed { "LAZ" } else { "LAS" }
        ),
        bytes.len(),
    );
    let mut properties: Vec<PropertyInfo> = record_fields(point_format)
        .into_iter()
        .map(|(name, type_name)| PropertyInfo {
            name: name.to_string(),
            type_name: type_name.to_string(),
        })
        .collect();
    if record_length > min_length {
        properties.push(PropertyInfo {
            name: "extra_bytes".into(),
            type_name: format!("{} bytes", record_length - min_length),
        });
    }
    info.elements.push(ElementInfo {
        name: "vertex".into(),
        count,
        properties,
    });
    for (label, at) in [("system", 26), ("software", 58)] {
        let text = text_at(bytes, at, 32);
        if !text.is_empty() {
            info.comments.push(format!("{label}: {text}"));
        }
    }
    Ok(Parsed {
        points: PointCloud {
            positions,
            normals: None,
            confidence: None,
            values: Some(values),
            colors,
        },
        triangles: Vec::new(),
        radii: None,
        info,
        origins: VertexOrigins::Stride {
            start: offset as u64,
            stride: record_length as u64,
        },
    })
}
