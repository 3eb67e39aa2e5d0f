//! Reading what real files contain: the variants each format allows, the attributes found by
//! name, non-finite policies, format detection, writer refusals and atomic output.

use std::path::{Path, PathBuf};

use sphcover_core::io::{
    Format, IoError, Location, NonFinitePolicy, PlyEncoding, Precision, Problem, ReadOptions,
    SphereSet, WriteOptions, parse_geometry, read_geometry, read_mesh, read_point_cloud,
    read_spheres, write_atomic, write_mesh, write_point_cloud, write_spheres,
};
use sphcover_core::{DVec3, PointCloud, TriMesh};

fn parse(bytes: &[u8], name: &str) -> Result<sphcover_core::io::Geometry, IoError> {
    let path = Path::new(name);
    parse_geometry(
        bytes,
        Format::from_path(path)?,
        path,
        &ReadOptions::default(),
    )
}

fn parse_with(
    bytes: &[u8],
    name: &str,
    policy: NonFinitePolicy,
) -> Result<sphcover_core::io::Geometry, IoError> {
    let path = Path::new(name);
    let options = ReadOptions {
        non_finite: policy,
        ..ReadOptions::default()
    };
    parse_geometry(bytes, Format::from_path(path)?, path, &options)
}

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

#[test]
fn ply_ascii_with_unknown_elements_lists_and_named_attributes() {
    let text = b"ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nobj_info scanner 7\r\n\
element material 1\r\nproperty list uchar float coeffs\r\nproperty uchar id\r\n\
element vertex 3\r\nproperty float x\r\nproperty float y\r\nproperty double z\r\n\
property uchar red\r\nproperty list int int segment_index\r\nproperty float nx\r\n\
property float ny\r\nproperty float nz\r\nproperty float quality\r\nproperty float scalar_Intensity\r\n\
element face 2\r\nproperty uchar flags\r\nproperty list uchar int vertex_indices\r\n\
element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\nend_header\r\n\
2 0.5 1.5 9\r\n\
0 0 0.1 255 2 7 8 0 0 1 0.5 10\r\n\
1 0 0 0 0 0 0 1 1 11\r\n\
\r\n\
0 1 0 12 3 1 2 3 0 1 0 0.25 12\r\n\
1 3 0 1 2\r\n\
0 4 0 1 2 0\r\n\
0 1\r\n";
    let g = parse(text, "hand.ply").unwrap();
    assert_eq!(g.info.variant, "PLY ascii");
    assert_eq!(g.info.comments, vec!["made by hand", "scanner 7"]);
    assert_eq!(
        g.points.positions,
        vec![v(0.0, 0.0, 0.1), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]
    );
    // `float` fields hold f32 values, `double` fields f64 values.
    assert_eq!(g.points.positions[0].z, 0.1);
    assert_eq!(
        g.points.normals.as_deref(),
        Some(&[v(0.0, 0.0, 1.0), v(0.0, 0.0, 1.0), v(0.0, 1.0, 0.0)][..])
    );
    // `quality` (MeshLab's scalar) comes before `scalar_Intensity`: it is the values.
    assert_eq!(g.points.confidence, None);
    assert_eq!(g.points.values.as_deref(), Some(&[0.5, 1.0, 0.25][..]));
    assert_eq!(g.triangles, vec![[0, 1, 2], [0, 1, 2], [0, 2, 0]]);
    assert_eq!(g.info.polygons, 2);
    let names: Vec<&str> = g.info.elements.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names, ["material", "vertex", "face", "edge"]);
    let seg = &g.info.elements[1].properties[4];
    assert_eq!(
        (seg.name.as_str(), seg.type_name.as_str()),
        ("segment_index", "list int int")
    );
}

/// Encodes a binary PLY with a vertex list property and odd scalar types.
fn binary_ply(big: bool) -> Vec<u8> {
    let format = if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut b = format!(
        "ply\nformat {format} 1.0\nelement vertex 2\nproperty int16 x\nproperty uint8 y\n\
property float64 z\nproperty list uint16 int8 labels\nproperty float32 radius\n\
element face 1\nproperty list int uint32 vertex_index\nend_header\n"
    )
    .into_bytes();
    let mut put = |bytes: &[u8]| {
        let mut bytes = bytes.to_vec();
        if big {
            bytes.reverse();
        }
        b.extend_from_slice(&bytes);
    };
    for (x, y, z, labels, r) in [
        (-3i16, 200u8, 0.25f64, vec![1i8, -2], 0.5f32),
        (7, 1, -1.0, vec![], 2.0),
    ] {
        put(&x.to_le_bytes());
        put(&y.to_le_bytes());
        put(&z.to_le_bytes());
        put(&(labels.len() as u16).to_le_bytes());
        for l in labels {
            put(&l.to_le_bytes());
        }
        put(&r.to_le_bytes());
    }
    put(&4i32.to_le_bytes());
    for i in [0u32, 1, 0, 1] {
        put(&i.to_le_bytes());
    }
    b
}

#[test]
fn ply_binary_both_endians_any_scalar_type_and_vertex_lists() {
    for big in [false, true] {
        let g = parse(&binary_ply(big), "typed.ply").unwrap();
        assert_eq!(
            g.points.positions,
            vec![v(-3.0, 200.0, 0.25), v(7.0, 1.0, -1.0)]
        );
        assert_eq!(g.radii.as_deref(), Some(&[0.5, 2.0][..]));
        assert_eq!(g.triangles, vec![[0, 1, 0], [0, 0, 1]]);
        assert_eq!(g.info.polygons, 1);
        let expected = if big {
            "PLY binary big-endian"
        } else {
            "PLY binary little-endian"
        };
        assert_eq!(g.info.variant, expected);
    }
}

#[test]
fn ply_errors_name_line_or_byte_and_record() {
    let text = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 5\n";
    let err = parse(text, "bunny.ply").unwrap_err();
    assert_eq!(
        err.to_string(),
        "bunny.ply: line 9: vertex 1: expected 3 numbers, found 2"
    );

    let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
    let header = bin.len();
    bin.extend_from_slice(&[0u8; 12 * 2 + 5]);
    let err = parse(&bin, "scan.ply").unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "scan.ply: byte {}: vertex 2 truncated (the file declares 3 vertex records)",
            header + 24
        )
    );

    let absurd = b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    let err = parse(absurd, "absurd.ply").unwrap_err();
    assert!(err.to_string().starts_with("absurd.ply: line 3:"), "{err}");

    let faces = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n";
    match parse(faces, "f.ply").unwrap_err() {
        IoError::Malformed { at, problem, .. } => {
            assert_eq!(at, Location::Line(13));
            assert_eq!(
                problem,
                Problem::FaceIndexOutOfRange {
                    face: 0,
                    index: 3,
                    vertices: 3
                }
            );
        }
        other => panic!("{other}"),
    }
}

#[test]
fn obj_corner_forms_negative_indices_polygons_and_ignored_statements() {
    let text = b"# comment\nmtllib a.mtl\no thing\nv 0 0 0 1.0 0.5 0.5 0.5\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
vt 0 0\nvn 0 0 1\nvn 0 0 -1\ng group\nusemtl m\ns off\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4//1 -2//1 -1//1\nl 1 2\np 1\n";
    let g = parse(text, "quad.obj").unwrap();
    assert_eq!(g.points.positions.len(), 4);
    assert_eq!(g.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
    assert_eq!(g.info.polygons, 2);
    // Every corner names normal 1 for every vertex: consistent pairing.
    assert_eq!(g.points.normals, Some(vec![v(0.0, 0.0, 1.0); 4]));

    let inconsistent =
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 1 0 0\nf 1//1 2//1 3//1\nf 1//2 2//1 3//1\n";
    assert_eq!(parse(inconsistent, "a.obj").unwrap().points.normals, None);
    let cloud = b"v 0 0 0\nvn 1 0 0\nv 1 1 1\nvn 0 1 0\n";
    let g = parse(cloud, "cloud.obj").unwrap();
    assert_eq!(
        g.points.normals,
        Some(vec![v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)])
    );

    let err = parse(b"v 0 0 0\nv 1 0 0\nf 1 2 3\n", "bad.obj").unwrap_err();
    assert_eq!(
        err.to_string(),
        "bad.obj: line 3: face 0: vertex index 3 out of range (the file has 2 vertices)"
    );
    let err = parse(b"v 0 0 0\nv 1 0 x\n", "bad.obj").unwrap_err();
    assert_eq!(
        err.to_string(),
        "bad.obj: line 2: vertex 1: bad number \"x\""
    );
}

#[test]
fn off_variants_comments_and_colours() {
    let text = b"# header comment\nNOFF\n# counts\n4 2 0\n0 0 0 0 0 1\n1 0 0 0 0 1 # trailing\n\n1 1 0 0 0 1\n0 1 0 0 0 1\n4 0 1 2 3 255 0 0\n2 0 1\n";
    let g = parse(text, "n.off").unwrap();
    assert_eq!(g.points.positions.len(), 4);
    assert_eq!(g.points.normals.as_ref().map(Vec::len), Some(4));
    assert_eq!(g.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(g.info.polygons, 2);
    assert_eq!(g.info.skipped_polygons, 1);

    let coff = b"COFF 3 1 3\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2\n";
    let g = parse(coff, "c.off").unwrap();
    assert_eq!(g.points.normals, None);
    assert_eq!(g.triangles, vec![[0, 1, 2]]);

    let err = parse(b"OFF\n3 1 0\n0 0 0\n1 0 0\n", "t.off").unwrap_err();
    assert_eq!(
        err.to_string(),
        "t.off: line 5: vertex 2 truncated (the file declares 3 vertex records)"
    );
}

fn binary_stl(header: &[u8], triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut b = vec![b' '; 80];
    b[..header.len()].copy_from_slice(header);
    b.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    for t in triangles {
        b.extend_from_slice(&[0u8; 12]);
        for p in t {
            for c in p {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

#[test]
fn stl_binary_starting_with_solid_and_vertex_merging() {
    let a = [0.0f32, 0.0, 0.0];
    let b = [1.0f32, 0.0, 0.0];
    let c = [0.0f32, 1.0, 0.0];
    let d = [0.0f32, 0.0, 1.0];
    let bytes = binary_stl(b"solid but binary", &[[a, b, c], [a, c, d], [b, c, d]]);
    let g = parse(&bytes, "s.stl").unwrap();
    assert_eq!(g.info.variant, "STL binary");
    assert_eq!(
        g.points.positions,
        vec![
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(0.0, 1.0, 0.0),
            v(0.0, 0.0, 1.0)
        ]
    );
    assert_eq!(g.triangles, vec![[0, 1, 2], [0, 2, 3], [1, 2, 3]]);

    let ascii = b"solid cube\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n  endloop\n endfacet\n facet normal 0 0 1\n  outer loop\n   vertex 1 0 0\n   vertex 1 1 0\n   vertex 0 1 0\n  endloop\n endfacet\nendsolid cube\n";
    let g = parse(ascii, "a.stl").unwrap();
    assert_eq!(g.info.variant, "STL ascii");
    assert_eq!(g.points.positions.len(), 4);
    assert_eq!(g.triangles, vec![[0, 1, 2], [1, 3, 2]]);

    let mut truncated = bytes.clone();
    truncated.truncate(bytes.len() - 7);
    let err = parse(&truncated, "cut.stl").unwrap_err();
    assert!(
        err.to_string()
            .starts_with("cut.stl: byte 80: binary STL declares 3 triangles"),
        "{err}"
    );
}

#[test]
fn column_text_separators_comments_and_sphere_rule() {
    let text = b"# scan\n1,2,3, 0,0,1\n\n  4 5 6 0 1 0  # two\n";
    let g = parse(text, "p.xyz").unwrap();
    assert_eq!(g.points.positions, vec![v(1.0, 2.0, 3.0), v(4.0, 5.0, 6.0)]);
    assert_eq!(
        g.points.normals,
        Some(vec![v(0.0, 0.0, 1.0), v(0.0, 1.0, 0.0)])
    );
    assert!(parse(text, "p.pwn").is_ok());

    let four = b"0 0 0 0.5\n1 1 1 0.25\n";
    assert_eq!(parse(four, "s.txt").unwrap().radii, Some(vec![0.5, 0.25]));
    assert_eq!(parse(four, "s.sph").unwrap().radii, Some(vec![0.5, 0.25]));
    let g = parse(four, "s.xyz").unwrap();
    assert_eq!((g.radii, g.points.values), (None, Some(vec![0.5, 0.25])));

    let err = parse(b"0 0 0\n1 1\n", "p.xyz").unwrap_err();
    assert_eq!(
        err.to_string(),
        "p.xyz: line 2: point 1: expected 3 numbers, found 2"
    );
    let err = parse(b"0 0 0\n", "s.sph").unwrap_err();
    assert_eq!(
        err.to_string(),
        "s.sph: line 1: sphere 0: expected 4 numbers, found 3"
    );
}

#[test]
fn non_finite_policies() {
    let text = b"ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\n\
element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 nan 0\n0 1 inf\n1 1 0\n3 0 1 3\n3 0 3 2\n";
    let err = parse(text, "nan.ply").unwrap_err();
    assert_eq!(
        err.to_string(),
        "nan.ply: line 11: vertex 1 is not finite (2 vertices with 2 NaN or infinite values; the non-finite policy can drop or keep them)"
    );
    let g = parse_with(text, "nan.ply", NonFinitePolicy::Drop).unwrap();
    assert_eq!(g.points.positions, vec![v(0.0, 0.0, 0.0), v(1.0, 1.0, 0.0)]);
    assert!(g.triangles.is_empty());
    assert_eq!(g.info.non_finite.dropped_vertices, 2);
    assert_eq!(g.info.non_finite.dropped_triangles, 2);

    let g = parse_with(text, "nan.ply", NonFinitePolicy::Keep).unwrap();
    assert_eq!(g.points.positions.len(), 4);
    assert_eq!(g.info.non_finite.vertices, 2);
    assert_eq!(g.info.non_finite.coordinates, 2);

    let xyz = b"0 0 0\n1 1 1\nNaN 2 2\n3 3 3\n";
    let g = parse_with(xyz, "p.xyz", NonFinitePolicy::Drop).unwrap();
    assert_eq!(
        g.points.positions,
        vec![v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0), v(3.0, 3.0, 3.0)]
    );
    let err = parse(xyz, "p.xyz").unwrap_err();
    assert!(
        err.to_string()
            .starts_with("p.xyz: line 3: vertex 2 is not finite"),
        "{err}"
    );
}

#[test]
fn format_detection_is_case_insensitive_and_names_unknown_files() {
    assert_eq!(
        Format::from_path(Path::new("a/B.PLY")).unwrap(),
        Format::Ply
    );
    assert_eq!(
        Format::from_path(Path::new("x.Spheres")).unwrap(),
        Format::Sph
    );
    let err = Format::from_path(Path::new("scan.e57")).unwrap_err();
    assert!(
        err.to_string().starts_with("scan.e57: unknown file format"),
        "{err}"
    );
    let err = Format::from_path(Path::new("noext")).unwrap_err();
    assert!(err.to_string().starts_with("noext:"), "{err}");
    let err = parse(b"", "empty.obj").unwrap_err();
    assert_eq!(err.to_string(), "empty.obj: byte 0: empty file");
}

fn tetra() -> TriMesh {
    let mut m = TriMesh::new(
        vec![
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(0.0, 1.0, 0.0),
            v(0.0, 0.0, 1.0),
        ],
        vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
    );
    m.values = Some(vec![1.0, 2.0, 3.0, 4.0]);
    m
}

#[test]
fn writers_refuse_data_their_format_cannot_hold() {
    let dir = tempfile::tempdir().unwrap();
    let options = WriteOptions::default();
    let mesh = tetra();
    for name in ["m.xyz", "m.sph", "m.txt"] {
        let path = dir.path().join(name);
        let err = write_mesh(&path, &mesh, &options).unwrap_err();
        assert!(matches!(err, IoError::Unsupported { .. }), "{name}: {err}");
        assert!(err.to_string().contains(name), "{err}");
        assert!(!path.exists());
    }
    let cloud = PointCloud::from_positions(vec![v(0.0, 0.0, 0.0)]);
    let err = write_point_cloud(&dir.path().join("c.stl"), &cloud, &options).unwrap_err();
    assert!(matches!(err, IoError::Unsupported { .. }), "{err}");
    let mut valued = cloud.clone();
    valued.values = Some(vec![1.0]);
    let err = write_point_cloud(&dir.path().join("c.obj"), &valued, &options).unwrap_err();
    assert!(matches!(err, IoError::Unsupported { .. }), "{err}");
    let spheres = SphereSet {
        centres: vec![v(0.0, 0.0, 0.0)],
        radii: vec![1.0],
    };
    let err = write_spheres(&dir.path().join("s.obj"), &spheres, &options).unwrap_err();
    assert!(matches!(err, IoError::Unsupported { .. }), "{err}");
    let mut bad = cloud.clone();
    bad.values = Some(vec![]);
    let err = write_point_cloud(&dir.path().join("c.ply"), &bad, &options).unwrap_err();
    assert!(matches!(err, IoError::InvalidData { .. }), "{err}");
}

/// A mesh written to OBJ, OFF or STL is its geometry: the per-vertex values those formats
/// have no place for (and in STL the vertex normals) are left out, the rest reads back.
#[test]
fn meshes_with_values_write_their_geometry_to_obj_off_and_stl() {
    let dir = tempfile::tempdir().unwrap();
    let mut mesh = tetra();
    mesh.normals = Some(vec![v(0.0, 0.0, 1.0); 4]);
    for name in ["m.obj", "m.off", "m.stl"] {
        let path = dir.path().join(name);
        write_mesh(&path, &mesh, &WriteOptions::default()).unwrap();
        let back = read_mesh(&path, &ReadOptions::default()).unwrap();
        // STL merges its corners into vertices in order of first use: compare corners.
        let corners = |m: &TriMesh| -> Vec<[DVec3; 3]> {
            m.triangles
                .iter()
                .map(|t| t.map(|i| m.vertices[i as usize]))
                .collect()
        };
        assert_eq!(corners(&back), corners(&mesh), "{name}");
        assert_eq!(back.values, None, "{name}");
        let normals = if name == "m.stl" {
            None
        } else {
            mesh.normals.clone()
        };
        assert_eq!(back.normals, normals, "{name}");
    }
}

/// The numbers of the `DataArray` named `name` in a VTK XML file.
fn vtk_array(text: &str, name: &str) -> Vec<f64> {
    let start = text
        .find(&format!("Name=\"{name}\""))
        .unwrap_or_else(|| panic!("no array {name}"));
    let body = &text[start..];
    let body = &body[body.find('>').unwrap() + 1..body.find("</DataArray>").unwrap()];
    body.split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect()
}

/// `.vtp` and `.vtu` hold a mesh's points, triangles, normals and values exactly (ParaView's
/// `Normals`, the values as `quality`), and a point cloud as vertex cells; they are written,
/// never read.
#[test]
fn vtk_xml_holds_meshes_and_points_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let mut mesh = tetra();
    mesh.vertices[1] = v(0.1, 1.0 / 3.0, -2e-300);
    mesh.normals = Some(vec![v(0.0, 0.0, 1.0); 4]);
    for (name, grid) in [("m.vtp", "PolyData"), ("m.vtu", "UnstructuredGrid")] {
        let path = dir.path().join(name);
        write_mesh(&path, &mesh, &WriteOptions::default()).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains(&format!("<VTKFile type=\"{grid}\"")),
            "{text}"
        );
        assert!(
            text.contains("Normals=\"normals\" Scalars=\"quality\""),
            "{text}"
        );
        let points: Vec<f64> = mesh.vertices.iter().flat_map(|p| p.to_array()).collect();
        assert_eq!(vtk_array(&text, "Points"), points);
        assert_eq!(vtk_array(&text, "quality"), mesh.values.clone().unwrap());
        let corners: Vec<f64> = mesh
            .triangles
            .iter()
            .flatten()
            .map(|&c| f64::from(c))
            .collect();
        assert_eq!(vtk_array(&text, "connectivity"), corners);
        assert_eq!(vtk_array(&text, "offsets"), [3.0, 6.0, 9.0, 12.0]);
        if grid == "UnstructuredGrid" {
            assert_eq!(vtk_array(&text, "types"), [5.0; 4]);
        } else {
            assert!(text.contains("NumberOfPolys=\"4\""), "{text}");
        }
        let err = read_mesh(&path, &ReadOptions::default()).unwrap_err();
        assert!(
            err.to_string().contains("VTK XML is written for viewers"),
            "{err}"
        );
    }
    let cloud = PointCloud::from_positions(vec![v(1.0, 2.0, 3.0), v(4.0, 5.0, 6.0)]);
    let path = dir.path().join("c.vtp");
    write_point_cloud(&path, &cloud, &WriteOptions::default()).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("NumberOfVerts=\"2\""), "{text}");
    assert_eq!(vtk_array(&text, "connectivity"), [0.0, 1.0]);
}

#[test]
fn read_spheres_needs_radii_and_read_mesh_keeps_attributes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.ply");
    let options = WriteOptions {
        ply_encoding: PlyEncoding::Ascii,
        ..WriteOptions::default()
    };
    write_mesh(&path, &tetra(), &options).unwrap();
    assert_eq!(read_mesh(&path, &ReadOptions::default()).unwrap(), tetra());
    assert_eq!(
        read_point_cloud(&path, &ReadOptions::default())
            .unwrap()
            .len(),
        4
    );
    let err = read_spheres(&path, &ReadOptions::default()).unwrap_err();
    assert!(matches!(err, IoError::NoRadius { .. }), "{err}");
    let missing = dir.path().join("missing.ply");
    let err = read_geometry(&missing, &ReadOptions::default()).unwrap_err();
    assert!(
        matches!(err, IoError::Read { .. }) && err.to_string().contains("missing.ply"),
        "{err}"
    );
}

#[test]
fn atomic_output_refuses_inputs_and_leaves_old_files_on_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.ply");
    let cloud = PointCloud::from_positions(vec![v(1.0, 2.0, 3.0)]);
    write_point_cloud(&input, &cloud, &WriteOptions::default()).unwrap();
    let before = std::fs::read(&input).unwrap();

    // The same file through another spelling of its path.
    let other_spelling = dir.path().join(".").join("sub").join("..").join("in.ply");
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let options = WriteOptions {
        inputs: vec![input.clone()],
        precision: Precision::F32,
        ..WriteOptions::default()
    };
    let err = write_point_cloud(&other_spelling, &cloud, &options).unwrap_err();
    assert!(matches!(err, IoError::OutputIsInput { .. }), "{err}");
    // An output that does not exist yet is resolved through its directory.
    let fresh = dir.path().join("sub").join("..").join("fresh.ply");
    write_point_cloud(&fresh, &cloud, &options).unwrap();
    assert!(dir.path().join("fresh.ply").exists());

    // A failing encoder leaves the previous output and no temporary file behind.
    let err = write_atomic(&input, &[], |w| {
        w.write_all(b"partial")?;
        Err(std::io::Error::other("disk full"))
    })
    .unwrap_err();
    assert!(
        matches!(err, IoError::Write { .. }) && err.to_string().contains("in.ply"),
        "{err}"
    );
    assert_eq!(std::fs::read(&input).unwrap(), before);
    let leftovers: Vec<PathBuf> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");

    let unwritable = dir.path().join("no/such/dir/out.ply");
    let err = write_point_cloud(&unwritable, &cloud, &WriteOptions::default()).unwrap_err();
    assert!(matches!(err, IoError::Write { .. }), "{err}");
    assert!(err.to_string().contains("no/such/dir/out.ply"), "{err}");
}

#[cfg(unix)]
#[test]
fn atomic_output_keeps_permissions_of_a_replaced_file() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("keep.xyz");
    std::fs::write(&path, b"0 0 0\n").unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).unwrap();
    let cloud = PointCloud::from_positions(vec![v(1.0, 2.0, 3.0)]);
    write_point_cloud(&path, &cloud, &WriteOptions::default()).unwrap();
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640);
    let fresh = dir.path().join("fresh.xyz");
    write_point_cloud(&fresh, &cloud, &WriteOptions::default()).unwrap();
    let mode = std::fs::metadata(&fresh).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode & 0o600, 0o600, "the owner can read and write");
}

#[test]
fn ply_elements_without_properties_take_no_space() {
    let text = b"ply\nformat ascii 1.0\nelement marker 5\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
    let g = parse(text, "m.ply").unwrap();
    assert_eq!(g.points.positions, vec![v(1.0, 2.0, 3.0)]);
    let binary = b"ply\nformat binary_little_endian 1.0\nelement marker 1000000000000000000\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    assert!(parse(binary, "m.ply").unwrap().points.is_empty());
}
