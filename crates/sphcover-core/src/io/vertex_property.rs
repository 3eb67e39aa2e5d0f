//! One named scalar property of a file's vertices, read beside the geometry.
//!
//! [`read_geometry`](super::read_geometry) keeps only the vertex properties it gives a role
//! (position, normal, confidence, value, radius). Scans carry more: a per-point quality, an
//! outlier label, a segment id. Viewers and reports need those by name, without widening the
//! geometry type for every property a file may declare.

use std::path::Path;

use super::ply::header::{Property, parse_header};
use super::{Format, Geometry, IoError, MAP_THRESHOLD, ReadOptions, map_file, non_finite, ply};

/// Reads a geometry file as [`read_geometry`](super::read_geometry) does, and the values of
/// the scalar vertex property named `property` (exact, case-sensitive name), one per vertex
/// of the returned geometry.
///
/// The values are `None` when the file declares no such scalar property of its `vertex`
/// element; only PLY files declare named properties, so other formats always give `None`
/// (their attributes are in [`Geometry::points`]). Vertices dropped by
/// [`NonFinitePolicy::Drop`](super::NonFinitePolicy::Drop) are dropped from the values too.
pub fn read_geometry_with_vertex_property(
    path: &Path,
    property: &str,
    options: &ReadOptions,
) -> Result<(Geometry, Option<Vec<f64>>), IoError> {
    let format = Format::from_path(path)?;
    if format != Format::Ply {
        return Ok((super::read_geometry(path, options)?, None));
    }
    let read_error = |source| IoError::Read {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(read_error)?;
    let size = file.metadata().map_err(read_error)?.len();
    if size >= MAP_THRESHOLD
        && let Some(map) = map_file(&file)
    {
        return parse_ply_with_vertex_property(&map, path, property, options);
    }
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(&mut &file, &mut bytes).map_err(read_error)?;
    parse_ply_with_vertex_property(&bytes, path, property, options)
}

/// Parses PLY bytes held in memory and the scalar vertex property `property`; `path` only
/// names the file in errors.
pub fn parse_ply_with_vertex_property(
    bytes: &[u8],
    path: &Path,
    property: &str,
    options: &ReadOptions,
) -> Result<(Geometry, Option<Vec<f64>>), IoError> {
    let whole = || super::parse_geometry(bytes, Format::Ply, path, options);
    if bytes.is_empty() {
        return Ok((whole()?, None));
    }
    let header = parse_header(bytes).map_err(|f| f.into_io(path))?;
    let column = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .and_then(|v| {
            let k = header.elements[v]
                .properties
                .iter()
                .position(|p| matches!(p, Property::Scalar { .. }) && p.name() == property)?;
            Some((v, k))
        });
    let Some((vertex, k)) = column else {
        return Ok((whole()?, None));
    };
    let parsed = ply::read(bytes, options.max_bytes).map_err(|f| f.into_io(path))?;
    let (mut columns, _) =
        ply::read_element_columns(bytes, &header, vertex, &[k]).map_err(|f| f.into_io(path))?;
    let geometry = non_finite::apply_with_columns(parsed, options.non_finite, path, &mut columns)?;
    Ok((geometry, columns.pop()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::NonFinitePolicy;

    const ASCII: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n\
        property float y\nproperty float z\nproperty uchar label\nproperty double quality\n\
        element face 2\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0 1 0.5\n1 0 0 0 0.25\n0 1 0 1 -2\n1 1 nan 0 7\n3 0 1 2\n3 1 3 2\n";

    fn binary_le() -> Vec<u8> {
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
            property double x\nproperty double y\nproperty double z\nproperty short seg\n\
            end_header\n"
            .to_vec();
        for (i, seg) in [(0.0f64, -3i16), (1.0, 4), (2.0, 300)] {
            for c in [i, 2.0 * i, 3.0 * i] {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
            bytes.extend_from_slice(&seg.to_le_bytes());
        }
        bytes
    }

    fn options(non_finite: NonFinitePolicy) -> ReadOptions {
        ReadOptions {
            non_finite,
            ..ReadOptions::default()
        }
    }

    #[test]
    fn reads_an_ascii_property_and_drops_with_the_vertices() {
        let path = Path::new("a.ply");
        let (g, q) = parse_ply_with_vertex_property(
            ASCII.as_bytes(),
            path,
            "quality",
            &options(NonFinitePolicy::Keep),
        )
        .unwrap();
        assert_eq!(g.points.len(), 4);
        assert_eq!(q, Some(vec![0.5, 0.25, -2.0, 7.0]));

        let (g, label) = parse_ply_with_vertex_property(
            ASCII.as_bytes(),
            path,
            "label",
            &options(NonFinitePolicy::Drop),
        )
        .unwrap();
        assert_eq!(g.points.len(), 3);
        assert_eq!(g.triangles, vec![[0, 1, 2]]);
        assert_eq!(label, Some(vec![1.0, 0.0, 1.0]));
    }

    #[test]
    fn refuses_non_finite_vertices_like_the_plain_reader() {
        let err = parse_ply_with_vertex_property(
            ASCII.as_bytes(),
            Path::new("a.ply"),
            "quality",
            &options(NonFinitePolicy::Refuse),
        )
        .unwrap_err();
        assert!(matches!(err, IoError::NonFinite { index: 3, .. }), "{err}");
    }

    #[test]
    fn reads_a_binary_property() {
        let bytes = binary_le();
        let (g, seg) = parse_ply_with_vertex_property(
            &bytes,
            Path::new("b.ply"),
            "seg",
            &ReadOptions::default(),
        )
        .unwrap();
        assert_eq!(g.points.len(), 3);
        assert_eq!(seg, Some(vec![-3.0, 4.0, 300.0]));
    }

    #[test]
    fn a_missing_or_list_property_is_none() {
        let path = Path::new("a.ply");
        let keep = options(NonFinitePolicy::Keep);
        for name in ["nope", "vertex_indices", "Quality"] {
            let (g, v) =
                parse_ply_with_vertex_property(ASCII.as_bytes(), path, name, &keep).unwrap();
            assert_eq!(g.points.len(), 4);
            assert_eq!(v, None, "{name}");
        }
    }

    #[test]
    fn malformed_files_are_refused_with_a_location() {
        let truncated = &ASCII.as_bytes()[..ASCII.len() - 12];
        let err = parse_ply_with_vertex_property(
            truncated,
            Path::new("t.ply"),
            "quality",
            &ReadOptions::default(),
        )
        .unwrap_err();
        assert!(matches!(err, IoError::Malformed { .. }), "{err}");
        let err =
            parse_ply_with_vertex_property(b"", Path::new("e.ply"), "x", &ReadOptions::default())
                .unwrap_err();
        assert!(matches!(err, IoError::Malformed { .. }), "{err}");
    }
}
