//! PLY body decoding: fixed-size binary vertex records in parallel, everything else in one
//! pass that checks each record against the bytes left before using it.

use glam::DVec3;
use rayon::prelude::*;

use super::header::{
    Element, Encoding, Header, Property, Scalar, VertexRoles, face_indices, parse_header,
    vertex_roles,
};
use crate::io::error::{Failure, Location, MemoryBudget, Problem};
use crate::io::text::{LineCursor, Tokens, bad_number, parse_f32, parse_f64, parse_integer};
use crate::io::{FileInfo, Format, Parsed, VertexOrigins, push_polygon};
use crate::point_cloud::PointCloud;

/// Vertex records decoded per rayon task at least (keeps task overhead negligible).
const MIN_RECORDS_PER_TASK: usize = 1 << 12;

/// The vertex attributes being filled.
#[derive(Debug, Default)]
struct Vertices {
    positions: Vec<DVec3>,
    normals: Option<Vec<DVec3>>,
    confidence: Option<Vec<f64>>,
    values: Option<Vec<f64>>,
    radii: Option<Vec<f64>>,
    colors: Option<Vec<[u8; 3]>>,
}

impl Vertices {
    /// Bytes per vertex in memory with these roles, plus `origin` bytes for its location.
    fn bytes_per_vertex(roles: &VertexRoles, origin: u64) -> u64 {
        let scalars = [roles.confidence, roles.value, roles.radius]
            .iter()
            .filter(|r| r.is_some())
            .count() as u64;
        let normals = if roles.normal.is_some() { 24 } else { 0 };
        let colors = if roles.color.is_some() { 3 } else { 0 };
        24 + normals + 8 * scalars + colors + origin
    }

    fn with_capacity(roles: &VertexRoles, n: usize) -> Vertices {
        Vertices {
            positions: Vec::with_capacity(n),
            normals: roles.normal.map(|_| Vec::with_capacity(n)),
            confidence: roles.confidence.map(|_| Vec::with_capacity(n)),
            values: roles.value.map(|_| Vec::with_capacity(n)),
            radii: roles.radius.map(|_| Vec::with_capacity(n)),
            colors: roles.color.map(|_| Vec::with_capacity(n)),
        }
    }

    /// Appends one vertex given a reader of property `k`'s value.
    #[inline]
    fn push(&mut self, roles: &VertexRoles, value: impl Fn(usize) -> f64) {
        let [x, y, z] = roles.xyz;
        self.positions
            .push(DVec3::new(value(x), value(y), value(z)));
        if let (Some(v), Some([a, b, c])) = (self.normals.as_mut(), roles.normal) {
            v.push(DVec3::new(value(a), value(b), value(c)));
        }
        for (v, k) in [
            (self.confidence.as_mut(), roles.confidence),
            (self.values.as_mut(), roles.value),
            (self.radii.as_mut(), roles.radius),
        ] {
            if let (Some(v), Some(k)) = (v, k) {
                v.push(value(k));
            }
        }
        if let (Some(v), Some(color)) = (self.colors.as_mut(), &roles.color) {
            v.push(color.channels.map(|k| color.byte(value(k))));
        }
    }
}

/// Faces being triangulated.
#[derive(Debug, Default)]
struct Faces {
    triangles: Vec<[u32; 3]>,
    polygons: u64,
    skipped: u64,
    corners: Vec<u32>,
}

impl Faces {
    /// Checks a polygon's indices (as read, in `f64`) and triangulates it.
    fn push(
        &mut self,
        face: u64,
        indices: &[f64],
        vertices: u64,
        at: Location,
    ) -> Result<(), Failure> {
        self.corners.clear();
        for &v in indices {
            if v.fract() != 0.0 || !v.is_finite() {
                return Err(Failure::syntax(
                    at,
                    format!("face {face}: vertex index {v} is not an integer"),
                ));
            }
            if v < 0.0 || v >= vertices as f64 {
                return Err(Failure::new(
                    at,
                    Problem::FaceIndexOutOfRange {
                        face,
                        index: v as i64,
                        vertices,
                    },
                ));
            }
            self.corners.push(v as u32);
        }
        self.polygons += 1;
        if !push_polygon(&self.corners, &mut self.triangles) {
            self.skipped += 1;
        }
        Ok(())
    }
}

/// Bytes of a triangle in memory: a face makes at least one unless it is degenerate.
const TRIANGLE_BYTES: u64 = 12;

/// Counts the vertex arrays (`capacity` records of `bytes_per_record` each) in the budget.
fn reserve(
    budget: &mut MemoryBudget,
    element: &Element,
    capacity: usize,
    bytes_per_record: u64,
) -> Result<(), Failure> {
    budget.reserve((capacity as u64).saturating_mul(bytes_per_record), || {
        let plural = |n: u64| {
            let name = &element.name;
            match name.as_str() {
                "vertex" if n != 1 => "vertices".to_string(),
                _ if n != 1 => format!("{name}s"),
                _ => name.clone(),
            }
        };
        if capacity as u64 == element.count {
            format!("{} {}", element.count, plural(element.count))
        } else {
            format!(
                "{} {} (of which the file can hold {capacity})",
                element.count,
                plural(element.count)
            )
        }
    })
}

/// Room for `capacity` vertices, each with its 8-byte origin, after charging it to `budget`.
fn reserve_vertices(
    budget: &mut MemoryBudget,
    element: &Element,
    roles: &VertexRoles,
    capacity: usize,
) -> Result<Vertices, Failure> {
    reserve(
        budget,
        element,
        capacity,
        Vertices::bytes_per_vertex(roles, 8),
    )?;
    Ok(Vertices::with_capacity(roles, capacity))
}

/// Reads a PLY file; the vertex and face arrays must fit in `limit` bytes.
pub(crate) fn read(bytes: &[u8], limit: Option<u64>) -> Result<Parsed, Failure> {
    let header = parse_header(bytes)?;
    let end = Location::Line(header.end_line);
    let vertex = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| Failure::header(end, "the file has no vertex element"))?;
    let vertex_element = &header.elements[vertex];
    let roles = vertex_roles(vertex_element)?;
    if vertex_element.count > u64::from(u32::MAX) {
        return Err(Failure::header(
            Location::Line(vertex_element.line),
            format!(
                "the file declares {} vertices; at most {} are supported",
                vertex_element.count,
                u32::MAX
            ),
        ));
    }
    let face = header.elements.iter().position(|e| e.name == "face");
    let face_list = match face {
        Some(f) if header.elements[f].count > 0 => Some((f, face_indices(&header.elements[f])?)),
        _ => None,
    };

    let mut vertices = Vertices::default();
    let mut faces = Faces::default();
    let mut budget = MemoryBudget::new(limit);
    let origins = match header.encoding {
        Encoding::Ascii => read_ascii(
            bytes,
            &header,
            vertex,
            &roles,
            face_list,
            (&mut vertices, &mut faces),
            &mut budget,
        )?,
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => read_binary(
            bytes,
            &header,
            vertex,
            &roles,
            face_list,
            (&mut vertices, &mut faces),
            &mut budget,
        )?,
    };

    let mut info = FileInfo::new(Format::Ply, header.encoding.variant(), bytes.len());
    info.elements = header.elements.iter().map(Element::info).collect();
    info.comments = header.comments;
    info.polygons = faces.polygons;
    info.skipped_polygons = faces.skipped;
    Ok(Parsed {
        points: PointCloud {
            positions: vertices.positions,
            normals: vertices.normals,
            confidence: vertices.confidence,
            values: vertices.values,
            colors: vertices.colors,
        },
        triangles: faces.triangles,
        radii: vertices.radii,
        info,
        origins,
    })
}

/// The values of the scalar properties `wanted` (property indices) of every record of
/// element `target`, one column per wanted property, with the location of each record. The
/// other elements are walked over with the same checks as [`read`]. For readers of PLY
/// layouts of their own (the cover file).
pub(crate) fn read_element_columns(
    bytes: &[u8],
    header: &Header,
    target: usize,
    wanted: &[usize],
) -> Result<(Vec<Vec<f64>>, VertexOrigins), Failure> {
    let element = &header.elements[target];
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); wanted.len()];
    match header.encoding {
        Encoding::Ascii => {
            let mut cursor = LineCursor::new(bytes, header.body_start, header.end_line + 1);
            let mut lines = Vec::new();
            for (e, el) in header.elements.iter().enumerate() {
                if el.properties.is_empty() {
                    continue;
                }
                let mut mask = vec![false; el.properties.len()];
                if e == target {
                    for &k in wanted {
                        mask[k] = true;
                    }
                    walk_ascii(&mut cursor, el, &mask, None, |_, line, scalars, _| {
                        lines.push(line);
                        for (column, &k) in columns.iter_mut().zip(wanted) {
                            column.push(scalars[k]);
                        }
                        Ok(())
                    })?;
                } else {
                    walk_ascii(&mut cursor, el, &mask, None, |_, _, _, _| Ok(()))?;
                }
            }
            Ok((columns, VertexOrigins::Lines(lines)))
        }
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
            let big = header.encoding == Encoding::BinaryBigEndian;
            let mut pos = header.body_start;
            let mut starts = Vec::new();
            for (e, el) in header.elements.iter().enumerate() {
                if el.properties.is_empty() {
                    // Records without properties occupy no bytes.
                    continue;
                }
                let mut fields = vec![(0usize, 0usize); el.properties.len()];
                if e == target {
                    pos = walk_binary(bytes, pos, el, big, &mut fields, |_, start, fields| {
                        starts.push(start as u64);
                        for (column, &k) in columns.iter_mut().zip(wanted) {
                            column.push(field_value(bytes, element, fields, k, big));
                        }
                        Ok(())
                    })?;
                } else {
                    pos = walk_binary(bytes, pos, el, big, &mut fields, |_, _, _| Ok(()))?;
                }
            }
            Ok((columns, VertexOrigins::Bytes(starts)))
        }
    }
}

fn truncated(at: Location, element: &Element, index: u64) -> Failure {
    Failure::new(
        at,
        Problem::Truncated {
            element: element.name.clone(),
            index,
            declared: element.count,
        },
    )
}

fn read_binary(
    bytes: &[u8],
    header: &Header,
    vertex: usize,
    roles: &VertexRoles,
    face_list: Option<(usize, usize)>,
    (vertices, faces): (&mut Vertices, &mut Faces),
    budget: &mut MemoryBudget,
) -> Result<VertexOrigins, Failure> {
    let big = header.encoding == Encoding::BinaryBigEndian;
    let vertex_count = header.elements[vertex].count;
    let mut origins = VertexOrigins::Stride {
        start: 0,
        stride: 0,
    };
    let mut pos = header.body_start;
    for (e, element) in header.elements.iter().enumerate() {
        let remaining = bytes.len() - pos;
        if let Some(stride) = element.fixed_size() {
            // Fixed-size records: the declared count must fit in the bytes left.
            let available = remaining
                .checked_div(stride)
                .map_or(element.count, |n| n as u64);
            if element.count > available {
                let at = Location::Byte((pos + available as usize * stride) as u64);
                return Err(truncated(at, element, available));
            }
            let len = element.count as usize * stride;
            if e == vertex {
                // Located by their stride: no per-vertex origin.
                let per_vertex = Vertices::bytes_per_vertex(roles, 0);
                reserve(budget, element, element.count as usize, per_vertex)?;
                *vertices = decode_fixed_vertices(&bytes[pos..pos + len], element, roles, big);
                origins = VertexOrigins::Stride {
                    start: pos as u64,
                    stride: stride as u64,
                };
            }
            pos += len;
            continue;
        }
        let capacity = (element.count as usize).min(remaining / element.min_size().max(1));
        let mut fields = vec![(0usize, 0usize); element.properties.len()];
        if e == vertex {
            *vertices = reserve_vertices(budget, element, roles, capacity)?;
            let mut starts = Vec::with_capacity(capacity);
            pos = walk_binary(bytes, pos, element, big, &mut fields, |_, start, fields| {
                starts.push(start as u64);
                vertices.push(roles, |k| field_value(bytes, element, fields, k, big));
                Ok(())
            })?;
            origins = VertexOrigins::Bytes(starts);
        } else if let Some((f, list)) = face_list
            && f == e
        {
            reserve(budget, element, capacity, TRIANGLE_BYTES)?;
            faces.triangles.reserve(capacity);
            let Property::List { item, .. } = element.properties[list] else {
                return Err(Failure::header(
                    Location::Line(element.line),
                    "face list expected",
                ));
            };
            let mut indices = Vec::new();
            pos = walk_binary(bytes, pos, element, big, &mut fields, |i, start, fields| {
                let (offset, len) = fields[list];
                indices.clear();
                indices
                    .extend((0..len).map(|j| item.read(&bytes[offset + j * item.size()..], big)));
                faces.push(i, &indices, vertex_count, Location::Byte(start as u64))
            })?;
        } else {
            pos = walk_binary(bytes, pos, element, big, &mut fields, |_, _, _| Ok(()))?;
        }
    }
    Ok(origins)
}

/// Value of scalar property `k` of a walked record.
#[inline]
fn field_value(
    bytes: &[u8],
    element: &Element,
    fields: &[(usize, usize)],
    k: usize,
    big: bool,
) -> f64 {
    match element.properties[k] {
        Property::Scalar { ty, .. } => ty.read(&bytes[fields[k].0..], big),
        Property::List { .. } => f64::NAN,
    }
}

/// Walks the records of an element with list properties, checking every length against the
/// bytes left. `visit(index, record start, fields)` sees, per property, the offset of its
/// data and its item count. Returns the offset after the element.
fn walk_binary(
    bytes: &[u8],
    mut pos: usize,
    element: &Element,
    big: bool,
    fields: &mut [(usize, usize)],
    mut visit: impl FnMut(u64, usize, &[(usize, usize)]) -> Result<(), Failure>,
) -> Result<usize, Failure> {
    for i in 0..element.count {
        let start = pos;
        for (k, property) in element.properties.iter().enumerate() {
            match *property {
                Property::Scalar { ty, .. } => {
                    if bytes.len() - pos < ty.size() {
                        return Err(truncated(Location::Byte(start as u64), element, i));
                    }
                    fields[k] = (pos, 1);
                    pos += ty.size();
                }
                Property::List {
                    count,
                    item,
                    ref name,
                } => {
                    if bytes.len() - pos < count.size() {
                        return Err(truncated(Location::Byte(start as u64), element, i));
                    }
                    let len = count.read(&bytes[pos..], big);
                    if len < 0.0 {
                        return Err(Failure::syntax(
                            Location::Byte(pos as u64),
                            format!("{} {i}: negative length {len} of list {name}", element.name),
                        ));
                    }
                    pos += count.size();
                    // At most 2^32 items of at most 8 bytes: no overflow in usize (64-bit).
                    let len = len as usize;
                    let size = len.saturating_mul(item.size());
                    if bytes.len() - pos < size {
                        return Err(truncated(Location::Byte(start as u64), element, i));
                    }
                    fields[k] = (pos, len);
                    pos += size;
                }
            }
        }
        visit(i, start, fields)?;
    }
    Ok(pos)
}

/// The points of a block of fixed-size binary vertex records (positions, normals, confidence,
/// values and colours), for readers that go through a file a block at a time.
pub(crate) fn decode_vertex_block(
    data: &[u8],
    element: &Element,
    roles: &VertexRoles,
    big: bool,
) -> PointCloud {
    let v = decode_fixed_vertices(data, element, roles, big);
    PointCloud {
        positions: v.positions,
        normals: v.normals,
        confidence: v.confidence,
        values: v.values,
        colors: v.colors,
    }
}

/// Decodes fixed-size vertex records in parallel, one pass per attribute; `collect_into_vec`
/// writes each result at its record's index, so the output never depends on the threads.
fn decode_fixed_vertices(
    data: &[u8],
    element: &Element,
    roles: &VertexRoles,
    big: bool,
) -> Vertices {
    let mut offsets = Vec::with_capacity(element.properties.len());
    let mut types = Vec::with_capacity(element.properties.len());
    let mut offset = 0;
    for property in &element.properties {
        if let Property::Scalar { ty, .. } = *property {
            offsets.push(offset);
            types.push(ty);
            offset += ty.size();
        }
    }
    let stride = offset;
    let field = |k: usize| (offsets[k], types[k]);
    let decode3 = |[a, b, c]: [usize; 3]| {
        let ((oa, ta), (ob, tb), (oc, tc)) = (field(a), field(b), field(c));
        move |r: &[u8]| {
            DVec3::new(
                ta.read(&r[oa..], big),
                tb.read(&r[ob..], big),
                tc.read(&r[oc..], big),
            )
        }
    };
    let records = || {
        data.par_chunks_exact(stride)
            .with_min_len(MIN_RECORDS_PER_TASK)
    };
    let position = decode3(roles.xyz);
    let mut positions = Vec::new();
    let normals = match roles.normal {
        // One pass for both: the records are read from memory once.
        Some(n) => {
            let normal = decode3(n);
            let mut normals = Vec::new();
            records()
                .map(|r| (position(r), normal(r)))
                .unzip_into_vecs(&mut positions, &mut normals);
            Some(normals)
        }
        None => {
            records().map(position).collect_into_vec(&mut positions);
            None
        }
    };
    let scalar = |k: usize| -> Vec<f64> {
        let (o, t): (usize, Scalar) = field(k);
        let mut out = Vec::new();
        records()
            .map(|r| t.read(&r[o..], big))
            .collect_into_vec(&mut out);
        out
    };
    let colors = roles.color.map(|color| {
        let channels = color.channels.map(field);
        let mut out = Vec::new();
        records()
            .map(|r| channels.map(|(o, t)| color.byte(t.read(&r[o..], big))))
            .collect_into_vec(&mut out);
        out
    });
    Vertices {
        positions,
        normals,
        confidence: roles.confidence.map(scalar),
        values: roles.value.map(scalar),
        radii: roles.radius.map(scalar),
        colors,
    }
}

fn read_ascii(
    bytes: &[u8],
    header: &Header,
    vertex: usize,
    roles: &VertexRoles,
    face_list: Option<(usize, usize)>,
    (vertices, faces): (&mut Vertices, &mut Faces),
    budget: &mut MemoryBudget,
) -> Result<VertexOrigins, Failure> {
    let vertex_count = header.elements[vertex].count;
    let mut cursor = LineCursor::new(bytes, header.body_start, header.end_line + 1);
    let mut lines = Vec::new();
    for (e, element) in header.elements.iter().enumerate() {
        if element.properties.is_empty() {
            // Records without properties occupy no text at all.
            continue;
        }
        // A record takes at least one digit and one separator per property.
        let min_record = 2 * element.properties.len().max(1);
        let capacity = (element.count as usize).min(cursor.remaining() / min_record);
        let mut wanted = vec![false; element.properties.len()];
        if e == vertex {
            *vertices = reserve_vertices(budget, element, roles, capacity)?;
            lines = Vec::with_capacity(capacity);
            let normal = roles.normal.unwrap_or(roles.xyz);
            let color = roles.color.map_or(roles.xyz, |c| c.channels);
            for k in roles
                .xyz
                .iter()
                .chain(&normal)
                .chain(&color)
                .chain(&roles.confidence)
                .chain(&roles.value)
                .chain(&roles.radius)
            {
                wanted[*k] = true;
            }
            walk_ascii(
                &mut cursor,
                element,
                &wanted,
                None,
                |_, line, scalars, _| {
                    lines.push(line);
                    vertices.push(roles, |k| scalars[k]);
                    Ok(())
                },
            )?;
        } else if let Some((f, list)) = face_list
            && f == e
        {
            reserve(budget, element, capacity, TRIANGLE_BYTES)?;
            faces.triangles.reserve(capacity);
            walk_ascii(
                &mut cursor,
                element,
                &wanted,
                Some(list),
                |i, line, _, indices| faces.push(i, indices, vertex_count, Location::Line(line)),
            )?;
        } else {
            walk_ascii(&mut cursor, element, &wanted, None, |_, _, _, _| Ok(()))?;
        }
    }
    Ok(VertexOrigins::Lines(lines))
}

/// Parses an ascii field of type `ty`.
#[inline]
fn parse_field(
    ty: Scalar,
    token: &[u8],
    at: Location,
    element: &Element,
    index: u64,
) -> Result<f64, Failure> {
    let value = match ty {
        Scalar::F32 => parse_f32(token).map(f64::from),
        Scalar::F64 => parse_f64(token),
        _ => parse_integer(token).map(|v| v as f64),
    };
    value.ok_or_else(|| bad_number(at, &element.name, index, token, ty.is_integer()))
}

/// Walks ascii records, one per non-blank line. `visit(index, line, scalars, list)` sees the
/// values of the `wanted` scalar properties (by property index) and the items of list
/// property `list`.
fn walk_ascii(
    cursor: &mut LineCursor<'_>,
    element: &Element,
    wanted: &[bool],
    list: Option<usize>,
    mut visit: impl FnMut(u64, u64, &[f64], &[f64]) -> Result<(), Failure>,
) -> Result<(), Failure> {
    let mut scalars = vec![0.0; element.properties.len()];
    let mut items = Vec::new();
    for i in 0..element.count {
        let Some((line_no, line)) = cursor.next_content_line(None) else {
            return Err(truncated(
                Location::Line(cursor.next_line_number()),
                element,
                i,
            ));
        };
        let at = Location::Line(line_no);
        let wrong_count = |expected: usize| {
            Failure::new(
                at,
                Problem::WrongFieldCount {
                    element: element.name.clone(),
                    index: i,
                    expected,
                    found: Tokens::new(line, false).count(),
                },
            )
        };
        let mut tokens = Tokens::new(line, false);
        let mut expected = 0usize;
        for (k, property) in element.properties.iter().enumerate() {
            expected += 1;
            let token = tokens.next().ok_or_else(|| wrong_count(expected))?;
            match *property {
                Property::Scalar { ty, .. } => {
                    if wanted[k] {
                        scalars[k] = parse_field(ty, token, at, element, i)?;
                    }
                }
                Property::List { item, .. } => {
                    let len = parse_integer(token)
                        .filter(|&n| n >= 0)
                        .ok_or_else(|| bad_number(at, &element.name, i, token, true))?;
                    let len = usize::try_from(len).unwrap_or(usize::MAX);
                    expected = expected.saturating_add(len);
                    if list == Some(k) {
                        items.clear();
                        for _ in 0..len {
                            let token = tokens.next().ok_or_else(|| wrong_count(expected))?;
                            items.push(parse_field(item, token, at, element, i)?);
                        }
                    } else {
                        for _ in 0..len {
                            tokens.next().ok_or_else(|| wrong_count(expected))?;
                        }
                    }
                }
            }
        }
        if tokens.next().is_some() {
            return Err(wrong_count(expected));
        }
        visit(i, line_no, &scalars, &items)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn colors(bytes: &[u8]) -> Option<Vec<[u8; 3]>> {
        read(bytes, None).unwrap().points.colors
    }

    #[test]
    fn colours_are_scaled_by_their_type() {
        let ascii = |ty: &str, names: [&str; 3], rows: &str| {
            let [r, g, b] = names;
            format!(
                "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                 property float z\nproperty {ty} {r}\nproperty {ty} {g}\nproperty {ty} {b}\n\
                 end_header\n{rows}"
            )
        };
        let rgb = ["red", "green", "blue"];
        let uchar = ascii("uchar", rgb, "0 0 0 255 0 17\n1 1 1 3 128 90\n");
        assert_eq!(
            colors(uchar.as_bytes()),
            Some(vec![[255, 0, 17], [3, 128, 90]])
        );
        let float = ascii("float", ["r", "g", "b"], "0 0 0 1 0 0.5\n1 1 1 -1 2 nan\n");
        assert_eq!(
            colors(float.as_bytes()),
            Some(vec![[255, 0, 128], [0, 255, 0]])
        );
        let diffuse = ["diffuse_red", "diffuse_green", "diffuse_blue"];
        let ushort = ascii(
            "ushort",
            diffuse,
            "0 0 0 65535 257 0\n1 1 1 32768 0 65535\n",
        );
        assert_eq!(
            colors(ushort.as_bytes()),
            Some(vec![[255, 1, 0], [128, 0, 255]])
        );
        let partial = ascii(
            "uchar",
            ["red", "green", "alpha"],
            "0 0 0 1 2 3\n1 1 1 4 5 6\n",
        );
        assert_eq!(colors(partial.as_bytes()), None);
    }

    #[test]
    fn binary_colours_decode_on_both_paths() {
        // Fixed-size records decode in parallel; a list property makes the walked path.
        for (big, list) in [(false, false), (true, false), (false, true), (true, true)] {
            let format = if big { "big" } else { "little" };
            let mut bytes = format!(
                "ply\nformat binary_{format}_endian 1.0\nelement vertex 3\nproperty double x\n\
                 property double y\nproperty double z\nproperty uchar red\nproperty uchar green\n\
                 property uchar blue\n{}end_header\n",
                if list {
                    "property list uchar int tags\n"
                } else {
                    ""
                }
            )
            .into_bytes();
            for i in 0..3u8 {
                for c in [1.0f64, 2.0, f64::from(i)] {
                    bytes.extend(if big {
                        c.to_be_bytes()
                    } else {
                        c.to_le_bytes()
                    });
                }
                bytes.extend([i, 10 * i, 255 - i]);
                if list {
                    bytes.push(0);
                }
            }
            assert_eq!(
                colors(&bytes),
                Some(vec![[0, 0, 255], [1, 10, 254], [2, 20, 253]]),
                "{format} endian, list {list}"
            );
        }
    }
}
