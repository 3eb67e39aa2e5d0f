//! Wavefront OBJ: `v`, `vn` and `f` statements; every other statement is ignored.
//!
//! OBJ stores normals by corner (`f v//vn`), `sphcover` by vertex. A file's normals become
//! per-vertex normals when either
//! * there are as many `vn` as `v` and every corner that names a normal names the one with
//!   its vertex's index (the layout of point clouds saved as OBJ and of this writer), or
//! * every corner names a normal, each vertex is always paired with the same one, and every
//!   vertex is used by a face.
//!
//! Otherwise the normals are left out rather than guessed.

use std::io::Write;

use glam::DVec3;

use super::encode::write_records;
use super::error::{Failure, GrowingBudget, Location, Problem};
use super::text::{LineCursor, Tokens, bad_number, parse_f64, parse_integer, push_real, push_uint};
use super::{
    ElementInfo, Export, FileInfo, Format, Parsed, PropertyInfo, VertexOrigins, push_polygon,
};
use crate::point_cloud::PointCloud;

/// Pairing of vertices with normals seen so far.
#[derive(Debug)]
struct NormalPairing {
    /// Every corner named a normal.
    every_corner: bool,
    /// Every named normal has its vertex's index.
    identity: bool,
    /// No vertex was paired with two different normals.
    consistent: bool,
    /// Normal index per vertex (`u32::MAX`: unpaired).
    pair: Vec<u32>,
}

/// Resolves an OBJ index (1-based, or negative relative to the `count` defined so far).
fn resolve(index: i64, count: usize) -> Option<i64> {
    match index {
        0 => None,
        i if i > 0 => Some(i - 1),
        i => Some(count as i64 + i),
    }
}

pub(crate) fn read(bytes: &[u8], limit: Option<u64>) -> Result<Parsed, Failure> {
    let mut budget = GrowingBudget::new(limit);
    let mut cursor = LineCursor::new(bytes, 0, 1);
    let mut positions: Vec<DVec3> = Vec::new();
    let mut lines: Vec<u64> = Vec::new();
    let mut normals: Vec<DVec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut polygons = 0u64;
    let mut skipped = 0u64;
    let mut corners: Vec<u32> = Vec::new();
    let mut pairing = NormalPairing {
        every_corner: true,
        identity: true,
        consistent: true,
        pair: Vec::new(),
    };
    // Corners referring to vertices defined later (allowed by most readers): checked at the
    // end, (face, line, index as written, resolved index).
    let mut forward: Vec<(u64, u64, i64, i64)> = Vec::new();

    while let Some((line_no, line)) = cursor.next_content_line(Some(b'#')) {
        let at = Location::Line(line_no);
        let mut tokens = Tokens::new(line, false);
        let Some(keyword) = tokens.next() else {
            continue;
        };
        match keyword {
            b"v" | b"vn" => {
                let element = if keyword == b"v" { "vertex" } else { "normal" };
                let index = if keyword == b"v" {
                    positions.len()
                } else {
                    normals.len()
                } as u64;
                let mut xyz = [0.0; 3];
                for (k, slot) in xyz.iter_mut().enumerate() {
                    let token = tokens.next().ok_or_else(|| {
                        Failure::new(
                            at,
                            Problem::WrongFieldCount {
                                element: element.to_string(),
                                index,
                                expected: 3,
                                found: k,
                            },
                        )
                    })?;
                    *slot = parse_f64(token)
                        .ok_or_else(|| bad_number(at, element, index, token, false))?;
                }
                // Trailing `w` or vertex colours are ignored.
                let p = DVec3::from_array(xyz);
                // A vertex: position, line number and its slot in the normal pairing; a
                // normal: itself and its copy as a vertex normal.
                budget.add(if keyword == b"v" { 36 } else { 48 }, || {
                    format!(
                        "{} vertices and {} normals by line {line_no}",
                        positions.len(),
                        normals.len()
                    )
                })?;
                if keyword == b"v" {
                    if positions.len() >= u32::MAX as usize {
                        return Err(Failure::syntax(at, "more than 2^32 - 1 vertices"));
                    }
                    positions.push(p);
                    lines.push(line_no);
                } else {
                    normals.push(p);
                }
            }
            b"f" => {
                let face = polygons;
                corners.clear();
                for corner in tokens {
                    let mut parts = corner.split(|&b| b == b'/');
                    let v_text = parts.next().unwrap_or_default();
                    let _texture = parts.next();
                    let n_text = parts.next().filter(|t| !t.is_empty());
                    if parts.next().is_some() {
                        return Err(Failure::syntax(
                            at,
                            format!(
                                "face {face}: bad corner {:?} (expected v, v/vt, v//vn or v/vt/vn)",
                                super::error::token_for_message(corner)
                            ),
                        ));
                    }
                    let written = parse_integer(v_text)
                        .ok_or_else(|| bad_number(at, "face", face, v_text, true))?;
                    let out_of_range = |index: i64, vertices: usize| {
                        Failure::new(
                            at,
                            Problem::FaceIndexOutOfRange {
                                face,
                                index,
                                vertices: vertices as u64,
                            },
                        )
                    };
                    let v = resolve(written, positions.len())
                        .filter(|&v| v >= 0 && v < i64::from(u32::MAX))
                        .ok_or_else(|| out_of_range(written, positions.len()))?;
                    if v as usize >= positions.len() {
                        forward.push((face, line_no, written, v));
                    }
                    corners.push(v as u32);
                    match n_text {
                        None => pairing.every_corner = false,
                        Some(n_text) => {
                            let written_n = parse_integer(n_text)
                                .ok_or_else(|| bad_number(at, "face", face, n_text, true))?;
                            let n = resolve(written_n, normals.len())
                                .filter(|&n| n >= 0 && (n as usize) < normals.len())
                                .ok_or_else(|| {
                                    Failure::syntax(
                                        at,
                                        format!(
                                            "face {face}: normal index {written_n} out of range (the file has {} normals so far)",
                                            normals.len()
                                        ),
                                    )
                                })? as u32;
                            pairing.identity &= i64::from(n) == v;
                            let v = v as usize;
                            if v < positions.len() {
                                if pairing.pair.len() < positions.len() {
                                    pairing.pair.resize(positions.len(), u32::MAX);
                                }
                                let slot = &mut pairing.pair[v];
                                if *slot == u32::MAX {
                                    *slot = n;
                                } else if *slot != n {
                                    pairing.consistent = false;
                                }
                            } else {
                                pairing.consistent = false;
                            }
                        }
                    }
                }
                // Its triangles, and a check for each corner naming a later vertex.
                let later = corners
                    .iter()
                    .filter(|&&v| v as usize >= positions.len())
                    .count();
                budget.add(
                    12 * corners.len().saturating_sub(2) as u64 + 32 * later as u64,
                    || {
                        format!(
                            "{} vertices and {} faces by line {line_no}",
                            positions.len(),
                            polygons + 1
                        )
                    },
                )?;
                polygons += 1;
                if !push_polygon(&corners, &mut triangles) {
                    skipped += 1;
                }
            }
            _ => {}
        }
    }
    if let Some(&(face, line, index, _)) = forward
        .iter()
        .find(|&&(_, _, _, v)| v as usize >= positions.len())
    {
        return Err(Failure::new(
            Location::Line(line),
            Problem::FaceIndexOutOfRange {
                face,
                index,
                vertices: positions.len() as u64,
            },
        ));
    }

    let n = positions.len();
    let per_vertex_normals = if !normals.is_empty() && normals.len() == n && pairing.identity {
        Some(normals.clone())
    } else if polygons > 0
        && pairing.every_corner
        && pairing.consistent
        && pairing.pair.len() == n
        && pairing.pair.iter().all(|&p| p != u32::MAX)
    {
        Some(pairing.pair.iter().map(|&p| normals[p as usize]).collect())
    } else {
        None
    };

    let mut info = FileInfo::new(Format::Obj, "OBJ", bytes.len());
    let text = |name: &str| PropertyInfo {
        name: name.to_string(),
        type_name: "text".to_string(),
    };
    info.elements.push(ElementInfo {
        name: "vertex".to_string(),
        count: n as u64,
        properties: ["x", "y", "z"].map(text).to_vec(),
    });
    if !normals.is_empty() {
        info.elements.push(ElementInfo {
            name: "normal".to_string(),
            count: normals.len() as u64,
            properties: ["nx", "ny", "nz"].map(text).to_vec(),
        });
    }
    if polygons > 0 {
        info.elements.push(ElementInfo {
            name: "face".to_string(),
            count: polygons,
            properties: vec![text("vertex_indices")],
        });
    }
    info.polygons = polygons;
    info.skipped_polygons = skipped;
    Ok(Parsed {
        points: PointCloud {
            positions,
            normals: per_vertex_normals,
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

pub(crate) fn write(w: &mut dyn Write, e: &Export<'_>, double: bool) -> std::io::Result<()> {
    w.write_all(b"# written by sphcover\n")?;
    let vector = |tag: &'static [u8], v: DVec3, buf: &mut Vec<u8>| {
        buf.extend_from_slice(tag);
        for c in v.to_array() {
            buf.push(b' ');
            push_real(buf, c, double);
        }
        buf.push(b'\n');
    };
    write_records(w, e.positions.len(), |i, buf| {
        vector(b"v", e.positions[i], buf)
    })?;
    if let Some(normals) = e.normals {
        write_records(w, normals.len(), |i, buf| vector(b"vn", normals[i], buf))?;
    }
    let with_normals = e.normals.is_some();
    write_records(w, e.triangles.len(), |t, buf| {
        buf.push(b'f');
        for v in e.triangles[t] {
            let one_based = u64::from(v) + 1;
            buf.push(b' ');
            push_uint(buf, one_based);
            if with_normals {
                buf.extend_from_slice(b"//");
                push_uint(buf, one_based);
            }
        }
        buf.push(b'\n');
    })
}
