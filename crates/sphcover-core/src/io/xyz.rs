//! Column text formats: point clouds (`.xyz`, `.pwn`, `.txt`) and sphere sets (`.sph`,
//! `.spheres`, `.txt` with 4 columns), one record per line.
//!
//! Columns are separated by blanks or commas; `#` starts a comment; blank lines are skipped.
//! The layout is fixed by the first data line's column count:
//!
//! | columns | `.xyz` `.pwn` | `.txt` | `.sph` `.spheres` |
//! |---|---|---|---|
//! | 3 | x y z | x y z | — |
//! | 4 | x y z value | x y z r (sphere) | x y z r |
//! | 6 | x y z nx ny nz | same | — |
//! | 7 | x y z nx ny nz value | same | — |
//!
//! or by a first line that is a comment naming the columns as the writer does (`# x y z r`),
//! which also keeps an empty sphere set a sphere set.

use std::io::Write;

use glam::DVec3;

use super::encode::write_records;
use super::error::{Failure, GrowingBudget, Location, Problem};
use super::text::{LineCursor, Tokens, bad_number, parse_f64, push_real};
use super::{ElementInfo, Export, FileInfo, Format, Parsed, PropertyInfo, VertexOrigins};
use crate::point_cloud::PointCloud;

/// The meaning of the columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Layout {
    Points,
    PointsValue,
    PointsNormals,
    PointsNormalsValue,
    Spheres,
}

const LAYOUTS: [Layout; 5] = [
    Layout::Points,
    Layout::PointsValue,
    Layout::PointsNormals,
    Layout::PointsNormalsValue,
    Layout::Spheres,
];

impl Layout {
    fn names(self) -> &'static [&'static str] {
        match self {
            Layout::Points => &["x", "y", "z"],
            Layout::PointsValue => &["x", "y", "z", "value"],
            Layout::PointsNormals => &["x", "y", "z", "nx", "ny", "nz"],
            Layout::PointsNormalsValue => &["x", "y", "z", "nx", "ny", "nz", "value"],
            Layout::Spheres => &["x", "y", "z", "r"],
        }
    }

    fn columns(self) -> usize {
        self.names().len()
    }

    fn element(self) -> &'static str {
        if self == Layout::Spheres {
            "sphere"
        } else {
            "point"
        }
    }

    fn from_count(columns: usize, format: Format) -> Option<Layout> {
        match (columns, format) {
            (4, Format::Sph | Format::Txt) => Some(Layout::Spheres),
            (_, Format::Sph) => None,
            (3, _) => Some(Layout::Points),
            (4, _) => Some(Layout::PointsValue),
            (6, _) => Some(Layout::PointsNormals),
            (7, _) => Some(Layout::PointsNormalsValue),
            _ => None,
        }
    }
}

/// The layout named by a first-line comment such as `# x y z nx ny nz`.
fn layout_from_comment(line: &[u8]) -> Option<Layout> {
    let text = line.trim_ascii_start().strip_prefix(b"#")?;
    let words: Vec<&[u8]> = Tokens::new(text, true).collect();
    LAYOUTS.into_iter().find(|layout| {
        layout.names().len() == words.len()
            && layout
                .names()
                .iter()
                .zip(&words)
                .all(|(n, w)| n.as_bytes() == *w)
    })
}

pub(crate) fn read(bytes: &[u8], format: Format, limit: Option<u64>) -> Result<Parsed, Failure> {
    let mut budget = GrowingBudget::new(limit);
    let mut cursor = LineCursor::new(bytes, 0, 1);
    let first_line = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
    let mut layout = layout_from_comment(first_line);
    if format == Format::Sph && layout.is_some_and(|l| l != Layout::Spheres) {
        return Err(Failure::header(
            Location::Line(1),
            "the column comment does not name sphere columns \"x y z r\"",
        ));
    }
    let mut positions: Vec<DVec3> = Vec::new();
    let mut normals: Vec<DVec3> = Vec::new();
    let mut extra: Vec<f64> = Vec::new();
    let mut lines: Vec<u64> = Vec::new();
    let mut values = [0.0f64; 7];
    while let Some((line_no, line)) = cursor.next_content_line(Some(b'#')) {
        let at = Location::Line(line_no);
        let index = positions.len() as u64;
        let found = Tokens::new(line, true).count();
        let current = match layout {
            Some(l) => l,
            None => {
                let l = Layout::from_count(found, format).ok_or_else(|| {
                    let expected = if format == Format::Sph {
                        "4"
                    } else {
                        "3, 4, 6 or 7"
                    };
                    Failure::syntax(
                        at,
                        format!(
                            "{} {index}: expected {expected} numbers, found {found}",
                            if format == Format::Sph {
                                "sphere"
                            } else {
                                "point"
                            }
                        ),
                    )
                })?;
                // Reserve from the first line's length: no count is declared, and this
                // bounds the estimate by the file size.
                let estimate = budget.capped(bytes.len() / (line.len() + 1).max(1), 32);
                positions.reserve(estimate);
                lines.reserve(estimate);
                layout = Some(l);
                l
            }
        };
        if found != current.columns() {
            return Err(Failure::new(
                at,
                Problem::WrongFieldCount {
                    element: current.element().to_string(),
                    index,
                    expected: current.columns(),
                    found,
                },
            ));
        }
        for (slot, token) in values.iter_mut().zip(Tokens::new(line, true)) {
            *slot = parse_f64(token)
                .ok_or_else(|| bad_number(at, current.element(), index, token, false))?;
        }
        // Position and line number, and 8 bytes per further column.
        budget.add(32 + 8 * (current.columns() as u64 - 3), || {
            format!("{} {}s by line {line_no}", index + 1, current.element())
        })?;
        positions.push(DVec3::new(values[0], values[1], values[2]));
        match current {
            Layout::Points => {}
            Layout::PointsValue | Layout::Spheres => extra.push(values[3]),
            Layout::PointsNormals => normals.push(DVec3::new(values[3], values[4], values[5])),
            Layout::PointsNormalsValue => {
                normals.push(DVec3::new(values[3], values[4], values[5]));
                extra.push(values[6]);
            }
        }
        lines.push(line_no);
    }
    if positions.len() > u32::MAX as usize {
        return Err(Failure::syntax(
            Location::Line(cursor.line()),
            "more than 2^32 - 1 points",
        ));
    }
    let layout = layout.unwrap_or(if format == Format::Sph {
        Layout::Spheres
    } else {
        Layout::Points
    });
    let (normals, values, radii) = match layout {
        Layout::Points => (None, None, None),
        Layout::PointsValue => (None, Some(extra), None),
        Layout::PointsNormals => (Some(normals), None, None),
        Layout::PointsNormalsValue => (Some(normals), Some(extra), None),
        Layout::Spheres => (None, None, Some(extra)),
    };
    let variant = format!("{} text ({})", format.name(), layout.names().join(" "));
    let mut info = FileInfo::new(format, variant, bytes.len());
    info.elements.push(ElementInfo {
        name: layout.element().to_string(),
        count: positions.len() as u64,
        properties: layout
            .names()
            .iter()
            .map(|n| PropertyInfo {
                name: n.to_string(),
                type_name: "text".to_string(),
            })
            .collect(),
    });
    Ok(Parsed {
        points: PointCloud {
            positions,
            normals,
            confidence: None,
            values,
            colors: None,
        },
        triangles: Vec::new(),
        radii,
        info,
        origins: VertexOrigins::Lines(lines),
    })
}

pub(crate) fn write(w: &mut dyn Write, e: &Export<'_>, double: bool) -> std::io::Result<()> {
    let layout = match (e.radii.is_some(), e.normals.is_some(), e.values.is_some()) {
        (true, _, _) => Layout::Spheres,
        (false, true, true) => Layout::PointsNormalsValue,
        (false, true, false) => Layout::PointsNormals,
        (false, false, true) => Layout::PointsValue,
        (false, false, false) => Layout::Points,
    };
    w.write_all(format!("# {}\n", layout.names().join(" ")).as_bytes())?;
    write_records(w, e.positions.len(), |i, buf| {
        let mut row = [0.0; 7];
        row[..3].copy_from_slice(&e.positions[i].to_array());
        let mut n = 3;
        if let Some(normals) = e.normals {
            row[3..6].copy_from_slice(&normals[i].to_array());
            n = 6;
        }
        if let Some(last) = e.radii.or(e.values) {
            row[n] = last[i];
            n += 1;
        }
        for (k, &v) in row[..n].iter().enumerate() {
            if k > 0 {
                buf.push(b' ');
            }
            push_real(buf, v, double);
        }
        buf.push(b'\n');
    })
}
