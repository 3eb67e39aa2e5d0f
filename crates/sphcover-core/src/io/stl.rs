//! STL: binary and ascii in, binary out.
//!
//! A file is binary exactly when its size is `84 + 50·n` for the triangle count `n` stored at
//! byte 80: many binary files start with `solid` too, so the prefix decides nothing. STL
//! repeats every vertex in each triangle; identical vertices (bit-equal coordinates) are
//! merged into one index, numbered in order of first appearance, so the result never
//! depends on hashing.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::io::Write;

use glam::DVec3;

use super::error::{Failure, Location, MemoryBudget, Problem};
use super::text::{LineCursor, Tokens, bad_number, parse_f64};
use super::{
    ElementInfo, Export, FileInfo, Format, Parsed, PropertyInfo, VertexOrigins, push_polygon,
};
use crate::point_cloud::PointCloud;

const HEADER: usize = 80;
const RECORD: usize = 50;
/// Bytes reserved per triangle of a binary file: the triangle (12) and half a merged vertex
/// (the reader expects each vertex to be shared by about six triangles, so `n / 2`
/// vertices), each a position (24), an origin (8) and a hash-table entry (key, index and
/// control byte, about 32).
const BYTES_PER_TRIANGLE: u64 = 12 + (24 + 8 + 32) / 2;

/// A fast hasher for vertex keys (bit patterns are already well mixed by the floats).
#[derive(Default)]
struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// Merges bit-identical vertices, remembering where each first appeared.
#[derive(Default)]
struct VertexMerger {
    index: HashMap<[u64; 3], u32, BuildHasherDefault<KeyHasher>>,
    positions: Vec<DVec3>,
    origins: Vec<u64>,
}

impl VertexMerger {
    fn with_capacity(n: usize) -> VertexMerger {
        VertexMerger {
            index: HashMap::with_capacity_and_hasher(n, BuildHasherDefault::default()),
            positions: Vec::with_capacity(n),
            origins: Vec::with_capacity(n),
        }
    }

    fn insert(&mut self, p: DVec3, origin: u64, at: Location) -> Result<u32, Failure> {
        let key = p.to_array().map(f64::to_bits);
        if let Some(&i) = self.index.get(&key) {
            return Ok(i);
        }
        let i = u32::try_from(self.positions.len())
            .map_err(|_| Failure::syntax(at, "more than 2^32 - 1 distinct vertices"))?;
        self.index.insert(key, i);
        self.positions.push(p);
        self.origins.push(origin);
        Ok(i)
    }
}

/// True when some vertex is used by no triangle (STL cannot store it).
pub(crate) fn has_unreferenced_vertex(vertices: usize, triangles: &[[u32; 3]]) -> bool {
    let mut used = vec![false; vertices];
    for t in triangles {
        for &v in t {
            if let Some(u) = used.get_mut(v as usize) {
                *u = true;
            }
        }
    }
    used.iter().any(|&u| !u)
}

/// Reads an STL file; what a binary file's triangle count reserves must fit in `limit` bytes.
pub(crate) fn read(bytes: &[u8], limit: Option<u64>) -> Result<Parsed, Failure> {
    let declared = bytes
        .get(HEADER..HEADER + 4)
        .map(|b| u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])));
    let binary_size = declared.map(|n| (HEADER + 4) as u64 + RECORD as u64 * n);
    if binary_size == Some(bytes.len() as u64) {
        return read_binary(bytes, limit);
    }
    let size_mismatch = || {
        let n = declared.unwrap_or(0);
        Failure::header(
            Location::Byte(HEADER as u64),
            format!(
                "binary STL declares {n} triangles ({} bytes) but the file has {} bytes",
                binary_size.unwrap_or(0),
                bytes.len()
            ),
        )
    };
    // Ascii STL never holds a NUL byte: with one, a "solid" header is a binary file's whose
    // size is wrong (truncated or padded), not text.
    let binary_looking = declared.is_some() && bytes.contains(&0);
    if bytes.trim_ascii_start().starts_with(b"solid") && !binary_looking {
        return read_ascii(bytes);
    }
    if declared.is_some() {
        return Err(size_mismatch());
    }
    Err(Failure::header(
        Location::Byte(0),
        format!(
            "not an STL file ({} bytes: too short for binary STL, and no \"solid\" keyword)",
            bytes.len()
        ),
    ))
}

fn read_binary(bytes: &[u8], limit: Option<u64>) -> Result<Parsed, Failure> {
    let n = (bytes.len() - HEADER - 4) / RECORD;
    MemoryBudget::new(limit).reserve((n as u64).saturating_mul(BYTES_PER_TRIANGLE), || {
        format!("{n} triangles")
    })?;
    let mut merger = VertexMerger::with_capacity(n / 2);
    let mut triangles = Vec::with_capacity(n);
    let f32_at =
        |o: usize| f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
    for t in 0..n {
        let record = HEADER + 4 + t * RECORD;
        let mut tri = [0u32; 3];
        for (c, slot) in tri.iter_mut().enumerate() {
            let o = record + 12 + 12 * c;
            let p = DVec3::new(
                f64::from(f32_at(o)),
                f64::from(f32_at(o + 4)),
                f64::from(f32_at(o + 8)),
            );
            *slot = merger.insert(p, o as u64, Location::Byte(o as u64))?;
        }
        triangles.push(tri);
    }
    let header_text = String::from_utf8_lossy(&bytes[..HEADER])
        .trim_end_matches(['\0', ' '])
        .to_string();
    finish(
        bytes,
        "STL binary",
        merger,
        triangles,
        n as u64,
        0,
        vec![header_text],
    )
}

fn read_ascii(bytes: &[u8]) -> Result<Parsed, Failure> {
    #[derive(PartialEq)]
    enum State {
        Outside,
        InSolid,
        InFacet,
        InLoop,
    }
    let mut state = State::Outside;
    let mut cursor = LineCursor::new(bytes, 0, 1);
    let mut merger = VertexMerger::default();
    let mut triangles = Vec::new();
    let mut corners: Vec<u32> = Vec::new();
    let mut facets = 0u64;
    let mut skipped = 0u64;
    let mut names = Vec::new();
    while let Some((line_no, line)) = cursor.next_content_line(None) {
        let at = Location::Line(line_no);
        let mut tokens = Tokens::new(line, false);
        let keyword = tokens.next().unwrap_or_default();
        let unexpected = || {
            Failure::syntax(
                at,
                format!(
                    "unexpected {:?} in ascii STL",
                    super::error::token_for_message(keyword)
                ),
            )
        };
        match (keyword, &state) {
            (b"solid", State::Outside) => {
                let name = line.trim_ascii().get(5..).unwrap_or_default().trim_ascii();
                names.push(String::from_utf8_lossy(name).into_owned());
                state = State::InSolid;
            }
            (b"endsolid", State::InSolid) => state = State::Outside,
            (b"facet", State::InSolid) => state = State::InFacet,
            (b"outer", State::InFacet) => {
                corners.clear();
                state = State::InLoop;
            }
            (b"vertex", State::InLoop) => {
                let mut xyz = [0.0; 3];
                for (k, slot) in xyz.iter_mut().enumerate() {
                    let token = tokens.next().ok_or_else(|| {
                        Failure::new(
                            at,
                            Problem::WrongFieldCount {
                                element: "facet".to_string(),
                                index: facets,
                                expected: 3,
                                found: k,
                            },
                        )
                    })?;
                    *slot = parse_f64(token)
                        .ok_or_else(|| bad_number(at, "facet", facets, token, false))?;
                }
                if tokens.next().is_some() {
                    return Err(Failure::new(
                        at,
                        Problem::WrongFieldCount {
                            element: "facet".to_string(),
                            index: facets,
                            expected: 3,
                            found: Tokens::new(line, false).count() - 1,
                        },
                    ));
                }
                corners.push(merger.insert(DVec3::from_array(xyz), line_no, at)?);
            }
            (b"endloop", State::InLoop) => state = State::InFacet,
            (b"endfacet", State::InFacet) => {
                // Some writers emit polygons with more than 3 vertices: fan them.
                if !push_polygon(&corners, &mut triangles) {
                    skipped += 1;
                }
                corners.clear();
                facets += 1;
                state = State::InSolid;
            }
            _ => return Err(unexpected()),
        }
    }
    // A missing final `endsolid` loses nothing (many exporters omit it); a missing
    // `endloop`/`endfacet` means the file was cut.
    if matches!(state, State::InFacet | State::InLoop) {
        return Err(Failure::new(
            Location::Line(cursor.next_line_number()),
            Problem::Syntax(format!("facet {facets} truncated: the file ends inside it")),
        ));
    }
    let mut parsed = finish(
        bytes,
        "STL ascii",
        merger,
        triangles,
        facets,
        skipped,
        names,
    )?;
    if let VertexOrigins::Bytes(lines) = parsed.origins {
        parsed.origins = VertexOrigins::Lines(lines);
    }
    Ok(parsed)
}

fn finish(
    bytes: &[u8],
    variant: &str,
    merger: VertexMerger,
    triangles: Vec<[u32; 3]>,
    facets: u64,
    skipped: u64,
    comments: Vec<String>,
) -> Result<Parsed, Failure> {
    let mut info = FileInfo::new(Format::Stl, variant, bytes.len());
    let property = |name: &str, type_name: &str| PropertyInfo {
        name: name.to_string(),
        type_name: type_name.to_string(),
    };
    let real = if variant == "STL binary" {
        "float"
    } else {
        "text"
    };
    info.elements.push(ElementInfo {
        name: "facet".to_string(),
        count: facets,
        properties: vec![
            property("normal", real),
            property("vertex1", real),
            property("vertex2", real),
            property("vertex3", real),
        ],
    });
    info.elements.push(ElementInfo {
        name: "vertex (merged)".to_string(),
        count: merger.positions.len() as u64,
        properties: ["x", "y", "z"].map(|n| property(n, real)).to_vec(),
    });
    info.comments = comments;
    info.polygons = facets;
    info.skipped_polygons = skipped;
    Ok(Parsed {
        points: PointCloud::from_positions(merger.positions),
        triangles,
        radii: None,
        info,
        origins: VertexOrigins::Bytes(merger.origins),
    })
}

pub(crate) fn write(w: &mut dyn Write, e: &Export<'_>) -> std::io::Result<()> {
    let count = u32::try_from(e.triangles.len()).map_err(|_| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "binary STL holds at most 2^32 - 1 triangles",
        )
    })?;
    // The header must not start with "solid", or naive readers take the file for ascii.
    let mut header = [b' '; HEADER];
    let text = b"binary STL written by sphcover";
    header[..text.len()].copy_from_slice(text);
    w.write_all(&header)?;
    w.write_all(&count.to_le_bytes())?;
    super::encode::write_records(w, e.triangles.len(), |t, buf| {
        let [a, b, c] = e.triangles[t].map(|v| e.positions[v as usize]);
        let normal = (b - a).cross(c - a).normalize_or_zero();
        for v in [normal, a, b, c] {
            for x in v.to_array() {
                buf.extend_from_slice(&(x as f32).to_le_bytes());
            }
        }
        buf.extend_from_slice(&[0, 0]);
    })
}
