//! The PLY header: magic, format line, elements with their properties, and the roles this
//! crate gives to the `vertex` and `face` properties.

use crate::io::error::{Failure, Location};
use crate::io::text::{LineCursor, Tokens};
use crate::io::{ElementInfo, PropertyInfo};

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// Both spellings of the specification: `char`… and `int8`….
    fn parse(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }

    pub(crate) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    pub(crate) fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes one value from the start of `b` (at least `size()` bytes long). Every type
    /// converts to `f64` exactly.
    #[inline(always)]
    pub(crate) fn read(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! decode {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                if big_endian {
                    <$t>::from_be_bytes(a) as f64
                } else {
                    <$t>::from_le_bytes(a) as f64
                }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => decode!(i16, 2),
            Scalar::U16 => decode!(u16, 2),
            Scalar::I32 => decode!(i32, 4),
            Scalar::U32 => decode!(u32, 4),
            Scalar::F32 => decode!(f32, 4),
            Scalar::F64 => decode!(f64, 8),
        }
    }
}

/// A property of an element.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Property {
    Scalar {
        name: String,
        ty: Scalar,
    },
    List {
        name: String,
        count: Scalar,
        item: Scalar,
    },
}

impl Property {
    pub(crate) fn name(&self) -> &str {
        match self {
            Property::Scalar { name, .. } | Property::List { name, .. } => name,
        }
    }

    fn type_name(&self) -> String {
        match self {
            Property::Scalar { ty, .. } => ty.name().to_string(),
            Property::List { count, item, .. } => {
                format!("list {} {}", count.name(), item.name())
            }
        }
    }
}

/// An element declaration.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Element {
    pub name: String,
    pub count: u64,
    pub properties: Vec<Property>,
    /// Header line of the declaration.
    pub line: u64,
}

impl Element {
    /// Size of a record when every property is a scalar.
    pub(crate) fn fixed_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => Some(ty.size()),
                Property::List { .. } => None,
            })
            .sum()
    }

    /// Smallest possible record: scalars plus list counts with empty lists.
    pub(crate) fn min_size(&self) -> usize {
        self.properties
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => ty.size(),
                Property::List { count, .. } => count.size(),
            })
            .sum()
    }

    pub(crate) fn info(&self) -> ElementInfo {
        ElementInfo {
            name: self.name.clone(),
            count: self.count,
            properties: self
                .properties
                .iter()
                .map(|p| PropertyInfo {
                    name: p.name().to_string(),
                    type_name: p.type_name(),
                })
                .collect(),
        }
    }
}

/// Body encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

impl Encoding {
    pub(crate) fn variant(self) -> &'static str {
        match self {
            Encoding::Ascii => "PLY ascii",
            Encoding::BinaryLittleEndian => "PLY binary little-endian",
            Encoding::BinaryBigEndian => "PLY binary big-endian",
        }
    }
}

/// A parsed header.
#[derive(Clone, Debug)]
pub(crate) struct Header {
    pub encoding: Encoding,
    pub elements: Vec<Element>,
    pub comments: Vec<String>,
    /// Byte offset of the body.
    pub body_start: usize,
    /// Line number of `end_header`.
    pub end_line: u64,
}

/// Property indices of the vertex attributes this crate reads.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct VertexRoles {
    pub xyz: [usize; 3],
    pub normal: Option<[usize; 3]>,
    pub confidence: Option<usize>,
    pub value: Option<usize>,
    pub radius: Option<usize>,
    pub color: Option<ColorChannels>,
}

/// The red, green and blue properties of a vertex and how their values map to 8 bits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ColorChannels {
    pub channels: [usize; 3],
    /// Factor to the 0–255 range: 8-bit integers are taken as they are, wider integers
    /// over their whole range (16-bit colours as LAS and some PLY writers store them), reals
    /// from `[0, 1]` (Open3D's float colours).
    pub scale: f64,
}

impl ColorChannels {
    fn new(channels: [usize; 3], ty: Scalar) -> ColorChannels {
        let scale = match ty {
            Scalar::I8 | Scalar::U8 => 1.0,
            Scalar::I16 | Scalar::U16 => 255.0 / f64::from(u16::MAX),
            Scalar::I32 | Scalar::U32 => 255.0 / f64::from(u32::MAX),
            Scalar::F32 | Scalar::F64 => 255.0,
        };
        ColorChannels { channels, scale }
    }

    /// One channel's value as a byte (rounded, clamped; NaN is 0).
    #[inline]
    pub fn byte(&self, value: f64) -> u8 {
        // `as` saturates and maps NaN to 0.
        (value * self.scale).round() as u8
    }
}

pub(crate) fn parse_header(bytes: &[u8]) -> Result<Header, Failure> {
    if !bytes.starts_with(b"ply") {
        return Err(Failure::header(
            Location::Byte(0),
            "not a PLY file (it does not start with \"ply\")",
        ));
    }
    let mut cursor = LineCursor::new(bytes, 0, 1);
    let magic_ok = cursor
        .next_line()
        .is_some_and(|(_, l)| l.trim_ascii_end() == b"ply");
    if !magic_ok {
        return Err(Failure::header(
            Location::Line(1),
            "the first line must be exactly \"ply\"",
        ));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut comments = Vec::new();
    loop {
        let Some((n, line)) = cursor.next_line() else {
            return Err(Failure::header(
                Location::Line(cursor.next_line_number()),
                "the header has no end_header line",
            ));
        };
        let at = Location::Line(n);
        let mut tokens = Tokens::new(line, false);
        let Some(keyword) = tokens.next() else {
            continue;
        };
        match keyword {
            b"comment" | b"obj_info" => {
                let text = line
                    .trim_ascii_start()
                    .get(keyword.len()..)
                    .unwrap_or_default()
                    .trim_ascii();
                comments.push(String::from_utf8_lossy(text).into_owned());
            }
            b"format" => {
                if encoding.is_some() {
                    return Err(Failure::header(at, "second format line"));
                }
                encoding = Some(match tokens.next() {
                    Some(b"ascii") => Encoding::Ascii,
                    Some(b"binary_little_endian") => Encoding::BinaryLittleEndian,
                    Some(b"binary_big_endian") => Encoding::BinaryBigEndian,
                    other => {
                        return Err(Failure::header(
                            at,
                            format!(
                                "unknown PLY format {:?} (expected ascii, binary_little_endian or binary_big_endian)",
                                String::from_utf8_lossy(other.unwrap_or_default())
                            ),
                        ));
                    }
                });
            }
            b"element" => {
                let (Some(name), Some(count), None) = (tokens.next(), tokens.next(), tokens.next())
                else {
                    return Err(Failure::header(at, "expected \"element NAME COUNT\""));
                };
                let count = parse_count(count).map_err(|m| Failure::header(at, m))?;
                elements.push(Element {
                    name: String::from_utf8_lossy(name).into_owned(),
                    count,
                    properties: Vec::new(),
                    line: n,
                });
            }
            b"property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(Failure::header(at, "property before any element"));
                };
                let property = parse_property(&mut tokens).map_err(|m| Failure::header(at, m))?;
                element.properties.push(property);
            }
            b"end_header" => break,
            other => {
                return Err(Failure::header(
                    at,
                    format!(
                        "unknown header keyword {:?}",
                        crate::io::error::token_for_message(other)
                    ),
                ));
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(Failure::header(
            Location::Line(cursor.line()),
            "the header has no format line",
        ));
    };
    Ok(Header {
        encoding,
        elements,
        comments,
        body_start: cursor.position(),
        end_line: cursor.line(),
    })
}

fn parse_count(token: &[u8]) -> Result<u64, String> {
    let text = String::from_utf8_lossy(token);
    if token.starts_with(b"-") {
        return Err(format!("negative element count {text}"));
    }
    text.parse::<u64>().map_err(|_| {
        format!(
            "bad element count {:?}",
            crate::io::error::token_for_message(token)
        )
    })
}

fn parse_property(tokens: &mut Tokens<'_>) -> Result<Property, String> {
    let scalar = |t: Option<&[u8]>| -> Result<Scalar, String> {
        let t = t.ok_or("incomplete property line")?;
        Scalar::parse(t).ok_or_else(|| {
            format!(
                "unknown property type {:?}",
                crate::io::error::token_for_message(t)
            )
        })
    };
    let first = tokens.next();
    let property = if first == Some(b"list") {
        let count = scalar(tokens.next())?;
        let item = scalar(tokens.next())?;
        if !count.is_integer() {
            return Err(format!(
                "list count type {} is not an integer type",
                count.name()
            ));
        }
        let name = tokens.next().ok_or("property list without a name")?;
        Property::List {
            name: String::from_utf8_lossy(name).into_owned(),
            count,
            item,
        }
    } else {
        let ty = scalar(first)?;
        let name = tokens.next().ok_or("property without a name")?;
        Property::Scalar {
            name: String::from_utf8_lossy(name).into_owned(),
            ty,
        }
    };
    if tokens.next().is_some() {
        return Err("extra words after the property name".to_string());
    }
    Ok(property)
}

/// Finds the properties of the vertex attributes (first match in file order for each).
pub(crate) fn vertex_roles(element: &Element) -> Result<VertexRoles, Failure> {
    let at = Location::Line(element.line);
    let find = |pred: &dyn Fn(&str) -> bool| -> Result<Option<usize>, Failure> {
        match element.properties.iter().position(|p| pred(p.name())) {
            Some(i) => match &element.properties[i] {
                Property::Scalar { .. } => Ok(Some(i)),
                Property::List { name, .. } => Err(Failure::header(
                    at,
                    format!("vertex property {name} is a list, expected a scalar"),
                )),
            },
            None => Ok(None),
        }
    };
    let named = |name: &'static str| move |p: &str| p == name;
    let mut xyz = [0; 3];
    for (slot, name) in xyz.iter_mut().zip(["x", "y", "z"]) {
        *slot = find(&named(name))?.ok_or_else(|| {
            Failure::header(at, format!("the vertex element has no property {name}"))
        })?;
    }
    let normal = match (
        find(&named("nx"))?,
        find(&named("ny"))?,
        find(&named("nz"))?,
    ) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        _ => None,
    };
    Ok(VertexRoles {
        xyz,
        normal,
        confidence: find(&named("confidence"))?,
        // `quality` is MeshLab's per-vertex scalar, what the writer names the values.
        value: find(&|p| {
            matches!(p, "quality" | "value" | "scalar" | "intensity") || p.starts_with("scalar_")
        })?,
        radius: find(&named("radius"))?,
        color: color_channels(element, &|name: &str| find(&|p: &str| p == name))?,
    })
}

/// The colour properties under the names writers use: `red green blue` (MeshLab, Open3D,
/// PCL), `r g b`, `diffuse_red …` (older scanners' exports). All three or none.
fn color_channels(
    element: &Element,
    find_named: &dyn Fn(&str) -> Result<Option<usize>, Failure>,
) -> Result<Option<ColorChannels>, Failure> {
    for names in [
        ["red", "green", "blue"],
        ["r", "g", "b"],
        ["diffuse_red", "diffuse_green", "diffuse_blue"],
    ] {
        let mut channels = [0; 3];
        let mut found = 0;
        for (slot, name) in channels.iter_mut().zip(names) {
            if let Some(k) = find_named(name)? {
                *slot = k;
                found += 1;
            }
        }
        if found == 3
            && let Property::Scalar { ty, .. } = element.properties[channels[0]]
        {
            return Ok(Some(ColorChannels::new(channels, ty)));
        }
    }
    Ok(None)
}

/// Finds the face list of vertex indices.
pub(crate) fn face_indices(element: &Element) -> Result<usize, Failure> {
    let at = Location::Line(element.line);
    let index = element
        .properties
        .iter()
        .position(|p| matches!(p.name(), "vertex_indices" | "vertex_index"))
        .ok_or_else(|| {
            Failure::header(at, "the face element has no vertex_indices list property")
        })?;
    match &element.properties[index] {
        Property::List { .. } => Ok(index),
        Property::Scalar { name, .. } => Err(Failure::header(
            at,
            format!("face property {name} is a scalar, expected a list"),
        )),
    }
}
