//! The cover file: a [`Cover`] with its metadata in a PLY file that generic viewers open as a
//! point cloud of support centres.
//!
//! # Layout
//!
//! ```text
//! ply
//! format binary_little_endian 1.0          (or binary_big_endian, or ascii)
//! comment sphcover cover 1                 (format marker and version)
//! comment kernel bspline2                  (bspline2 | gaussian | wendland)
//! comment expansion 1                      (default expansion factor σ ≥ 1 for evaluation)
//! comment normalisation CX CY CZ SCALE     (unit frame → input: x_input = x·SCALE + C)
//! comment note FREE TEXT                   (any number, in order; provenance, parameters)
//! element vertex N                         (one record per support)
//! property double x                        (centre c_i, in the unit frame)
//! property double y
//! property double z
//! property double radius                   (r_i)
//! property double ax                       (linear: g(x) = a·(x − c) + b)
//! property double ay
//! property double az
//! property double b
//! end_header
//! ```
//!
//! Quadratic local functions `g(x) = (x − c)ᵀA(x − c) + b·(x − c) + k` (centred form) replace
//! `ax ay az b` with `a_xx a_xy a_xz a_yy a_yz a_zz bx by bz k` (the upper triangle of the
//! symmetric `A`; a non-symmetric `A` is written as its symmetric part, which has the same
//! value and derivatives).
//!
//! The element is `vertex` with `x y z radius` so that any PLY viewer shows the centres and
//! [`crate::io::read_spheres`] reads the file as a sphere set. Numbers in the comments are the
//! shortest decimal text that reads back as the same `f64`, so with
//! [`Precision::F64`](crate::io::Precision) (the default) a write–read cycle returns exactly
//! the cover and metadata written. The reader accepts any PLY scalar type for each property,
//! any property order and extra properties or elements (ignored); it requires the kernel line
//! and the properties of exactly one kind of local function, and treats a missing expansion
//! line as 1 and a missing normalisation line as the identity.

use std::path::Path;

use glam::{DMat3, DVec3};

use super::encode::write_records;
use super::error::{Failure, IoError, Location, Problem};
use super::ply::header::{Element, Property, parse_header};
use super::ply::read_element_columns;
use super::text::push_real;
use super::{PlyEncoding, Precision, VertexOrigins, WriteOptions, write_atomic};
use crate::cover::{Cover, CoverError};
use crate::geometry::Normalisation;
use crate::kernel::Kernel;
use crate::local_function::LocalFunctions;

/// The comment line that marks a cover file, with the layout version.
const MARKER: &str = "sphcover cover 1";

const LINEAR: [&str; 4] = ["ax", "ay", "az", "b"];
const QUADRATIC: [&str; 10] = [
    "a_xx", "a_xy", "a_xz", "a_yy", "a_yz", "a_zz", "bx", "by", "bz", "k",
];

/// What a cover file stores besides the cover.
#[derive(Clone, Debug, PartialEq)]
pub struct CoverFileMeta {
    /// The map from the cover's unit frame back to input coordinates.
    pub normalisation: Normalisation,
    /// Default expansion factor σ ≥ 1 for evaluating the cover (thesis §6.2.2).
    pub expansion: f64,
    /// Free text lines (provenance, build parameters), one `comment note` line each.
    pub notes: Vec<String>,
}

impl Default for CoverFileMeta {
    fn default() -> CoverFileMeta {
        CoverFileMeta {
            normalisation: Normalisation::IDENTITY,
            expansion: 1.0,
            notes: Vec::new(),
        }
    }
}

/// Writes a cover file (see the module docs for the layout), atomically.
pub fn write_cover(
    path: &Path,
    cover: &Cover,
    meta: &CoverFileMeta,
    options: &WriteOptions,
) -> Result<(), IoError> {
    let invalid = |message: String| IoError::InvalidData {
        path: path.to_path_buf(),
        message,
    };
    let norm = meta.normalisation;
    if !(norm.centre.is_finite() && norm.scale.is_finite() && norm.scale > 0.0) {
        return Err(invalid(format!(
            "normalisation {norm:?} must have a finite centre and a finite positive scale"
        )));
    }
    if !(meta.expansion.is_finite() && meta.expansion >= 1.0) {
        return Err(invalid(format!(
            "expansion factor {} must be finite and ≥ 1",
            meta.expansion
        )));
    }
    if let Some(note) = meta.notes.iter().find(|n| n.contains(['\n', '\r'])) {
        return Err(invalid(format!("note {note:?} spans several lines")));
    }

    let double = options.precision == Precision::F64;
    let real = if double { "double" } else { "float" };
    let format = match options.ply_encoding {
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
        PlyEncoding::BinaryBigEndian => "binary_big_endian",
        PlyEncoding::Ascii => "ascii",
    };
    let mut header = format!(
        "ply\nformat {format} 1.0\ncomment {MARKER}\ncomment kernel {}\ncomment expansion {}\ncomment normalisation {} {} {} {}\n",
        cover.kernel().name(),
        number(meta.expansion),
        number(norm.centre.x),
        number(norm.centre.y),
        number(norm.centre.z),
        number(norm.scale),
    );
    for note in &meta.notes {
        header.push_str(&format!("comment note {note}\n"));
    }
    header.push_str(&format!("element vertex {}\n", cover.len()));
    let names: &[&str] = if cover.funcs().is_linear() {
        &LINEAR
    } else {
        &QUADRATIC
    };
    for name in ["x", "y", "z", "radius"].iter().chain(names) {
        header.push_str(&format!("property {real} {name}\n"));
    }
    header.push_str("end_header\n");

    let encoding = options.ply_encoding;
    write_atomic(path, &options.inputs, |w| {
        w.write_all(header.as_bytes())?;
        write_records(w, cover.len(), |i, buf| {
            let mut fields = [0.0; 14];
            let n = record(cover, i, &mut fields);
            match encoding {
                PlyEncoding::Ascii => {
                    for (k, &v) in fields[..n].iter().enumerate() {
                        if k > 0 {
                            buf.push(b' ');
                        }
                        push_real(buf, v, double);
                    }
                    buf.push(b'\n');
                }
                PlyEncoding::BinaryLittleEndian | PlyEncoding::BinaryBigEndian => {
                    let big = encoding == PlyEncoding::BinaryBigEndian;
                    for &v in &fields[..n] {
                        match (double, big) {
                            (true, false) => buf.extend_from_slice(&v.to_le_bytes()),
                            (true, true) => buf.extend_from_slice(&v.to_be_bytes()),
                            (false, false) => buf.extend_from_slice(&(v as f32).to_le_bytes()),
                            (false, true) => buf.extend_from_slice(&(v as f32).to_be_bytes()),
                        }
                    }
                }
            }
        })
    })
}

/// The shortest decimal text of `v` that reads back exactly.
fn number(v: f64) -> String {
    let mut out = Vec::new();
    super::text::push_f64(&mut out, v);
    String::from_utf8_lossy(&out).into_owned()
}

/// The fields of support `i` in file order; returns their number.
fn record(cover: &Cover, i: usize, out: &mut [f64; 14]) -> usize {
    let c = cover.centres()[i];
    out[..4].copy_from_slice(&[c.x, c.y, c.z, cover.radii()[i]]);
    match cover.funcs() {
        LocalFunctions::Linear { alpha, beta } => {
            let a = alpha[i];
            out[4..8].copy_from_slice(&[a.x, a.y, a.z, beta[i]]);
            8
        }
        LocalFunctions::Quadratic { a, b, k } => {
            // Entry (r, c) is column c, row r.
            let m = a[i];
            let e = |r: usize, c: usize| {
                let (u, v) = (m.col(c)[r], m.col(r)[c]);
                if u == v { u } else { 0.5 * u + 0.5 * v }
            };
            let b = b[i];
            out[4..14].copy_from_slice(&[
                e(0, 0),
                e(0, 1),
                e(0, 2),
                e(1, 1),
                e(1, 2),
                e(2, 2),
                b.x,
                b.y,
                b.z,
                k[i],
            ]);
            14
        }
    }
}

/// Reads a cover file written by [`write_cover`] (or any PLY with the same properties and
/// comments; see the module docs).
pub fn read_cover(path: &Path) -> Result<(Cover, CoverFileMeta), IoError> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    parse_cover(&bytes, path)
}

/// Parses the bytes of a cover file held in memory; `path` only names the file in errors.
pub fn parse_cover(bytes: &[u8], path: &Path) -> Result<(Cover, CoverFileMeta), IoError> {
    if bytes.is_empty() {
        return Err(Failure::new(Location::Byte(0), Problem::EmptyFile).into_io(path));
    }
    parse(bytes).map_err(|f| f.into_io(path))
}

fn parse(bytes: &[u8]) -> Result<(Cover, CoverFileMeta), Failure> {
    let header = parse_header(bytes)?;
    let end = Location::Line(header.end_line);
    let (kernel, meta) = parse_comments(bytes, header.body_start, &header.comments, end)?;
    let target = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| Failure::header(end, "the file has no vertex element (the supports)"))?;
    let element = &header.elements[target];
    let at = Location::Line(element.line);
    let find = |name: &str| -> Result<Option<usize>, Failure> {
        match element.properties.iter().position(|p| p.name() == name) {
            None => Ok(None),
            Some(k) => match element.properties[k] {
                Property::Scalar { .. } => Ok(Some(k)),
                Property::List { .. } => Err(Failure::header(
                    at,
                    format!("vertex property {name} is a list, expected a scalar"),
                )),
            },
        }
    };
    let all = |names: &[&str]| -> Result<Option<Vec<usize>>, Failure> {
        let found: Vec<Option<usize>> = names.iter().map(|n| find(n)).collect::<Result<_, _>>()?;
        Ok(found.into_iter().collect())
    };
    let Some(geometry) = all(&["x", "y", "z", "radius"])? else {
        return Err(Failure::header(
            at,
            "the vertex element needs properties x, y, z and radius",
        ));
    };
    let (linear, wanted_funcs) = match (all(&LINEAR)?, all(&QUADRATIC)?) {
        (Some(l), None) => (true, l),
        (None, Some(q)) => (false, q),
        (Some(_), Some(_)) => {
            return Err(Failure::header(
                at,
                "the vertex element has both linear (ax ay az b) and quadratic (a_xx … k) coefficients",
            ));
        }
        (None, None) => {
            return Err(Failure::header(
                at,
                "the vertex element has no local-function coefficients: expected ax ay az b (linear) or a_xx a_xy a_xz a_yy a_yz a_zz bx by bz k (quadratic)",
            ));
        }
    };
    let wanted: Vec<usize> = geometry.iter().chain(&wanted_funcs).copied().collect();
    let (columns, origins) = read_element_columns(bytes, &header, target, &wanted)?;
    let n = columns[0].len();
    let col = |k: usize| &columns[k];
    let centres: Vec<DVec3> = (0..n)
        .map(|i| DVec3::new(col(0)[i], col(1)[i], col(2)[i]))
        .collect();
    let radii = col(3).clone();
    let funcs = if linear {
        LocalFunctions::Linear {
            alpha: (0..n)
                .map(|i| DVec3::new(col(4)[i], col(5)[i], col(6)[i]))
                .collect(),
            beta: col(7).clone(),
        }
    } else {
        let q = |k: usize, i: usize| col(4 + k)[i];
        LocalFunctions::Quadratic {
            a: (0..n)
                .map(|i| {
                    DMat3::from_cols(
                        DVec3::new(q(0, i), q(1, i), q(2, i)),
                        DVec3::new(q(1, i), q(3, i), q(4, i)),
                        DVec3::new(q(2, i), q(4, i), q(5, i)),
                    )
                })
                .collect(),
            b: (0..n)
                .map(|i| DVec3::new(q(6, i), q(7, i), q(8, i)))
                .collect(),
            k: col(13).clone(),
        }
    };
    let cover = Cover::new(centres, radii, funcs, kernel)
        .map_err(|e| cover_failure(e, &origins, element))?;
    Ok((cover, meta))
}

/// Places a rejected support at its record.
fn cover_failure(error: CoverError, origins: &VertexOrigins, element: &Element) -> Failure {
    let index = match error {
        CoverError::NonFiniteCentre { index, .. }
        | CoverError::InvalidRadius { index, .. }
        | CoverError::NonFiniteFunction { index }
        | CoverError::ExpandedRadiusOverflow { index, .. } => Some(index),
        _ => None,
    };
    let at = match (index, origins) {
        (Some(i), VertexOrigins::Lines(lines)) => Location::Line(lines[i]),
        (Some(i), VertexOrigins::Bytes(starts)) => Location::Byte(starts[i]),
        (Some(i), VertexOrigins::Stride { start, stride }) => {
            Location::Byte(start + stride * i as u64)
        }
        (None, _) => Location::Line(element.line),
    };
    Failure::syntax(at, format!("invalid support: {error}"))
}

/// Reads the kernel and metadata from the header comments.
fn parse_comments(
    bytes: &[u8],
    header_len: usize,
    comments: &[String],
    end: Location,
) -> Result<(Kernel, CoverFileMeta), Failure> {
    let mut kernel = None;
    let mut meta = CoverFileMeta::default();
    for comment in comments {
        let mut words = comment.split_ascii_whitespace();
        let keyword = words.next().unwrap_or_default();
        let at = || Location::Line(comment_line(bytes, header_len, comment));
        let numbers = |count: usize| -> Result<Vec<f64>, Failure> {
            let rest: Vec<&str> = comment.split_ascii_whitespace().skip(1).collect();
            let values: Option<Vec<f64>> = rest.iter().map(|w| w.parse().ok()).collect();
            match values {
                Some(v) if v.len() == count => Ok(v),
                _ => Err(Failure::header(
                    at(),
                    format!("expected \"{keyword}\" and {count} number(s), found {comment:?}"),
                )),
            }
        };
        match keyword {
            "kernel" => {
                let name = words.next().unwrap_or_default();
                kernel = Some(
                    name.parse::<Kernel>()
                        .map_err(|e| Failure::header(at(), e.to_string()))?,
                );
            }
            "expansion" => {
                let v = numbers(1)?[0];
                if !(v.is_finite() && v >= 1.0) {
                    return Err(Failure::header(
                        at(),
                        format!("expansion factor {v} must be finite and ≥ 1"),
                    ));
                }
                meta.expansion = v;
            }
            "normalisation" => {
                let v = numbers(4)?;
                let centre = DVec3::new(v[0], v[1], v[2]);
                if !(centre.is_finite() && v[3].is_finite() && v[3] > 0.0) {
                    return Err(Failure::header(
                        at(),
                        "normalisation needs a finite centre and a finite positive scale",
                    ));
                }
                meta.normalisation = Normalisation {
                    centre,
                    scale: v[3],
                };
            }
            "note" => {
                let text = comment.trim_start()["note".len()..].trim_start();
                meta.notes.push(text.to_string());
            }
            _ => {}
        }
    }
    let kernel = kernel.ok_or_else(|| {
        Failure::header(
            end,
            "no \"comment kernel NAME\" line: not a sphcover cover file",
        )
    })?;
    Ok((kernel, meta))
}

/// The header line holding `comment` (the first one whose text after the keyword matches).
fn comment_line(bytes: &[u8], header_len: usize, comment: &str) -> u64 {
    let header = &bytes[..header_len.min(bytes.len())];
    for (n, line) in header.split(|&b| b == b'\n').enumerate() {
        let line = line.trim_ascii();
        for keyword in [&b"comment"[..], b"obj_info"] {
            if let Some(rest) = line.strip_prefix(keyword)
                && rest.trim_ascii() == comment.as_bytes()
            {
                return n as u64 + 1;
            }
        }
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::ply::header::Encoding;

    #[test]
    fn encoding_names_match_the_header_parser() {
        // The writer's format names are the ones the shared PLY header parser accepts.
        for (enc, expected) in [
            ("binary_little_endian", Encoding::BinaryLittleEndian),
            ("binary_big_endian", Encoding::BinaryBigEndian),
            ("ascii", Encoding::Ascii),
        ] {
            let text = format!("ply\nformat {enc} 1.0\nend_header\n");
            assert_eq!(parse_header(text.as_bytes()).unwrap().encoding, expected);
        }
    }
}
