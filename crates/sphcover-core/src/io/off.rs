//! Object File Format (OFF), as used in geometry processing.
//!
//! ```text
//! [ST][C][N]OFF          # keyword; prefixes add per-vertex columns
//! V F E                  # counts (E, the edge count, is ignored and may be missing)
//! x y z [nx ny nz] [colour] [s t]      V lines
//! n i0 i1 … i(n-1) [colour]            F lines (0-based indices)
//! ```
//!
//! `#` starts a comment anywhere; blank lines are skipped; records are one per line. The
//! counts may follow the keyword on its line. Binary OFF and the `4OFF`/`nOFF` dimensions
//! are refused with a clear error.

use std::io::Write;

use glam::DVec3;

use super::encode::write_records;
use super::error::{Failure, Location, MemoryBudget, Problem};
use super::text::{LineCursor, Tokens, bad_number, parse_f64, parse_integer, push_real, push_uint};
use super::{
    ElementInfo, Export, FileInfo, Format, Parsed, PropertyInfo, VertexOrigins, push_polygon,
};
use crate::point_cloud::PointCloud;

/// Which optional per-vertex columns the keyword announces.
#[derive(Clone, Copy, Debug, Default)]
struct Columns {
    normals: bool,
    colours: bool,
    texture: bool,
}

fn parse_keyword(token: &[u8], at: Location) -> Result<Columns, Failure> {
    let Some(mut prefix) = token.strip_suffix(b"OFF") else {
        return Err(Failure::header(
            at,
            format!(
                "not an OFF file (the first word is {:?}, expected OFF, NOFF, COFF, …)",
                super::error::token_for_message(token)
            ),
        ));
    };
    let mut columns = Columns::default();
    while !prefix.is_empty() {
        if let Some(rest) = prefix.strip_prefix(b"ST") {
            columns.texture = true;
            prefix = rest;
        } else if let Some(rest) = prefix.strip_prefix(b"C") {
            columns.colours = true;
            prefix = rest;
        } else if let Some(rest) = prefix.strip_prefix(b"N") {
            columns.normals = true;
            prefix = rest;
        } else {
            return Err(Failure::header(
                at,
                format!(
                    "unsupported OFF variant {:?} (supported: OFF with ST, C, N prefixes)",
                    String::from_utf8_lossy(token)
                ),
            ));
        }
    }
    Ok(columns)
}

/// Reads an OFF file; the arrays its counts reserve must fit in `limit` bytes.
pub(crate) fn read(bytes: &[u8], limit: Option<u64>) -> Result<Parsed, Failure> {
    let mut cursor = LineCursor::new(bytes, 0, 1);
    let Some((first_line, line)) = cursor.next_content_line(Some(b'#')) else {
        return Err(Failure::header(
            Location::Line(1),
            "no OFF keyword (the file holds only comments)",
        ));
    };
    let mut tokens = Tokens::new(line, false);
    let keyword = tokens.next().unwrap_or_default();
    let columns = parse_keyword(keyword, Location::Line(first_line))?;
    let mut rest: Vec<&[u8]> = tokens.collect();
    if rest.first() == Some(&&b"BINARY"[..]) {
        return Err(Failure::header(
            Location::Line(first_line),
            "binary OFF is not supported",
        ));
    }
    let mut counts_line = first_line;
    if rest.is_empty() {
        let Some((n, line)) = cursor.next_content_line(Some(b'#')) else {
            return Err(Failure::header(
                Location::Line(cursor.next_line_number()),
                "missing the counts line \"V F E\"",
            ));
        };
        counts_line = n;
        rest = Tokens::new(line, false).collect();
    }
    let at = Location::Line(counts_line);
    if !(2..=3).contains(&rest.len()) {
        return Err(Failure::header(
            at,
            format!(
                "expected the counts \"V F E\", found {} numbers",
                rest.len()
            ),
        ));
    }
    let mut counts = [0u64; 2];
    for (slot, token) in counts.iter_mut().zip(&rest) {
        *slot = parse_integer(token)
            .and_then(|v| u64::try_from(v).ok())
            .ok_or_else(|| {
                Failure::header(
                    at,
                    format!(
                        "bad count {:?} (expected a non-negative integer)",
                        super::error::token_for_message(token)
                    ),
                )
            })?;
    }
    let [vertex_count, face_count] = counts;
    if vertex_count > u64::from(u32::MAX) {
        return Err(Failure::header(
            at,
            format!(
                "{vertex_count} vertices declared; at most {} are supported",
                u32::MAX
            ),
        ));
    }

    // Preallocate no more than the bytes left can hold ("0 0 0\n" is 6 bytes).
    let capacity = (vertex_count as usize).min(cursor.remaining() / 6);
    let mut budget = MemoryBudget::new(limit);
    // Position, normal and line number of each vertex.
    let per_vertex = 24 + if columns.normals { 24 } else { 0 } + 8;
    budget.reserve((capacity as u64).saturating_mul(per_vertex), || {
        declared_count(vertex_count, capacity, "vertices")
    })?;
    let mut positions = Vec::with_capacity(capacity);
    let mut normals = columns.normals.then(|| Vec::with_capacity(capacity));
    let mut lines = Vec::with_capacity(capacity);
    let base = if columns.normals { 6 } else { 3 };
    let mut values = [0.0; 6];
    for i in 0..vertex_count {
        let Some((line_no, line)) = cursor.next_content_line(Some(b'#')) else {
            return Err(truncated(&cursor, "vertex", i, vertex_count));
        };
        let at = Location::Line(line_no);
        let found = Tokens::new(line, false).count();
        // Colour and texture columns follow; without them the count is exact.
        let exact = !columns.colours && !columns.texture;
        if found < base || (exact && found != base) {
            return Err(Failure::new(
                at,
                Problem::WrongFieldCount {
                    element: "vertex".to_string(),
                    index: i,
                    expected: base,
                    found,
                },
            ));
        }
        for (slot, token) in values.iter_mut().zip(Tokens::new(line, false)).take(base) {
            *slot = parse_f64(token).ok_or_else(|| bad_number(at, "vertex", i, token, false))?;
        }
        positions.push(DVec3::new(values[0], values[1], values[2]));
        if let Some(n) = normals.as_mut() {
            n.push(DVec3::new(values[3], values[4], values[5]));
        }
        lines.push(line_no);
    }

    // "3 0 1 2\n" is 8 bytes; each face makes at least one 12-byte triangle.
    let face_capacity = (face_count as usize).min(cursor.remaining() / 8);
    budget.reserve((face_capacity as u64).saturating_mul(12), || {
        declared_count(face_count, face_capacity, "faces")
    })?;
    let mut triangles = Vec::with_capacity(face_capacity);
    let mut corners = Vec::new();
    let mut skipped = 0u64;
    for f in 0..face_count {
        let Some((line_no, line)) = cursor.next_content_line(Some(b'#')) else {
            return Err(truncated(&cursor, "face", f, face_count));
        };
        let at = Location::Line(line_no);
        let mut tokens = Tokens::new(line, false);
        let first = tokens.next().unwrap_or_default();
        let n = parse_integer(first)
            .filter(|&n| n >= 0)
            .ok_or_else(|| bad_number(at, "face", f, first, true))?;
        corners.clear();
        for k in 0..n {
            let token = tokens.next().ok_or_else(|| {
                Failure::new(
                    at,
                    Problem::WrongFieldCount {
                        element: "face".to_string(),
                        index: f,
                        expected: usize::try_from(n).unwrap_or(usize::MAX).saturating_add(1),
                        found: k as usize + 1,
                    },
                )
            })?;
            let index =
                parse_integer(token).ok_or_else(|| bad_number(at, "face", f, token, true))?;
            if index < 0 || index as u64 >= vertex_count {
                return Err(Failure::new(
                    at,
                    Problem::FaceIndexOutOfRange {
                        face: f,
                        index,
                        vertices: vertex_count,
                    },
                ));
            }
            corners.push(index as u32);
        }
        // A colour may follow the indices.
        let trailing = tokens.count();
        if trailing > 4 {
            return Err(Failure::syntax(
                at,
                format!(
                    "face {f}: {trailing} numbers after the {n} indices (at most a colour of 4)"
                ),
            ));
        }
        if !push_polygon(&corners, &mut triangles) {
            skipped += 1;
        }
    }

    let variant = String::from_utf8_lossy(keyword).into_owned();
    let mut info = FileInfo::new(Format::Off, variant, bytes.len());
    let text = |name: &str| PropertyInfo {
        name: name.to_string(),
        type_name: "text".to_string(),
    };
    let mut properties: Vec<PropertyInfo> = ["x", "y", "z"].map(text).to_vec();
    if columns.normals {
        properties.extend(["nx", "ny", "nz"].map(text));
    }
    info.elements.push(ElementInfo {
        name: "vertex".to_string(),
        count: vertex_count,
        properties,
    });
    info.elements.push(ElementInfo {
        name: "face".to_string(),
        count: face_count,
        properties: vec![text("vertex_indices")],
    });
    info.polygons = face_count;
    info.skipped_polygons = skipped;
    Ok(Parsed {
        points: PointCloud {
            positions,
            normals,
            confidence: None,
            values: None,
            colors: None,
        },
        triangles,
        radii: None,
        info,
        origins: VertexOrigins::Lines(lines),
    })
}

/// `"N vertices"`, or with how many of them the file can hold when fewer.
fn declared_count(count: u64, capacity: usize, what: &str) -> String {
    if capacity as u64 == count {
        format!("{count} {what}")
    } else {
        format!("{count} {what} (of which the file can hold {capacity})")
    }
}

fn truncated(cursor: &LineCursor<'_>, element: &str, index: u64, declared: u64) -> Failure {
    Failure::new(
        Location::Line(cursor.next_line_number()),
        Problem::Truncated {
            element: element.to_string(),
            index,
            declared,
        },
    )
}

pub(crate) fn write(w: &mut dyn Write, e: &Export<'_>, double: bool) -> std::io::Result<()> {
    let keyword = if e.normals.is_some() { "NOFF" } else { "OFF" };
    w.write_all(format!("{keyword}\n{} {} 0\n", e.positions.len(), e.triangles.len()).as_bytes())?;
    write_records(w, e.positions.len(), |i, buf| {
        let mut first = true;
        let normal = e.normals.map(|n| n[i].to_array());
        for c in e.positions[i]
            .to_array()
            .iter()
            .chain(normal.iter().flatten())
        {
            if !first {
                buf.push(b' ');
            }
            first = false;
            push_real(buf, *c, double);
        }
        buf.push(b'\n');
    })?;
    write_records(w, e.triangles.len(), |t, buf| {
        buf.push(b'3');
        for v in e.triangles[t] {
            buf.push(b' ');
            push_uint(buf, u64::from(v));
        }
        buf.push(b'\n');
    })
}
