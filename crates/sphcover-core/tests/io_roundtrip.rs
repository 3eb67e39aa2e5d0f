//! Round trips through every writer and reader are lossless: bit-exact with `f64` output,
//! exact after rounding the input to `f32` with `f32` output (and for STL), with attributes
//! and faces present or absent.

use proptest::collection::vec;
use proptest::option;
use proptest::prelude::*;
use sphcover_core::io::{
    IoError, PlyEncoding, Precision, ReadOptions, SphereSet, WriteOptions, read_geometry,
    read_mesh, read_point_cloud, read_spheres, write_mesh, write_point_cloud, write_spheres,
};
use sphcover_core::{DVec3, PointCloud, TriMesh};

const ENCODINGS: [PlyEncoding; 3] = [
    PlyEncoding::BinaryLittleEndian,
    PlyEncoding::BinaryBigEndian,
    PlyEncoding::Ascii,
];

/// Any finite `f64`, with extremes, subnormals, signed zeros and plain numbers all likely.
fn coord64() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        (-1000i32..1000).prop_map(f64::from),
        -1.0f64..1.0,
        Just(-0.0),
    ]
}

/// A finite value that stays finite once rounded to `f32`.
fn coord32() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![
        any::<f32>()
            .prop_filter("finite", |v| v.is_finite())
            .prop_map(f64::from),
        -1e30f64..1e30,
        -1.0f64..1.0,
        (-1000i32..1000).prop_map(f64::from),
    ]
}

fn vec3(c: impl Strategy<Value = f64> + Clone) -> impl Strategy<Value = DVec3> + Clone {
    (c.clone(), c.clone(), c).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn cloud(
    c: impl Strategy<Value = f64> + Clone + 'static,
    min: usize,
) -> impl Strategy<Value = PointCloud> {
    (min..12usize).prop_flat_map(move |n| {
        (
            vec(vec3(c.clone()), n),
            option::of(vec(vec3(c.clone()), n)),
            option::of(vec(c.clone(), n)),
            option::of(vec(c.clone(), n)),
            option::of(vec(any::<[u8; 3]>(), n)),
        )
            .prop_map(
                |(positions, normals, confidence, values, colors)| PointCloud {
                    positions,
                    normals,
                    confidence,
                    values,
                    colors,
                },
            )
    })
}

fn mesh(c: impl Strategy<Value = f64> + Clone + 'static) -> impl Strategy<Value = TriMesh> {
    cloud(c, 1).prop_flat_map(|pc| {
        let n = pc.len() as u32;
        vec([0..n, 0..n, 0..n], 0..20).prop_map(move |triangles| TriMesh {
            vertices: pc.positions.clone(),
            triangles,
            normals: pc.normals.clone(),
            values: pc.values.clone(),
            colors: pc.colors.clone(),
        })
    })
}

fn round(v: f64) -> f64 {
    v as f32 as f64
}

fn round_cloud(pc: &PointCloud) -> PointCloud {
    let r3 = |v: &DVec3| DVec3::new(round(v.x), round(v.y), round(v.z));
    PointCloud {
        positions: pc.positions.iter().map(r3).collect(),
        normals: pc.normals.as_ref().map(|n| n.iter().map(r3).collect()),
        confidence: pc
            .confidence
            .as_ref()
            .map(|c| c.iter().copied().map(round).collect()),
        values: pc
            .values
            .as_ref()
            .map(|c| c.iter().copied().map(round).collect()),
        colors: pc.colors.clone(),
    }
}

fn round_mesh(m: &TriMesh) -> TriMesh {
    let pc = round_cloud(&PointCloud {
        positions: m.vertices.clone(),
        normals: m.normals.clone(),
        confidence: None,
        values: m.values.clone(),
        colors: m.colors.clone(),
    });
    TriMesh {
        vertices: pc.positions,
        triangles: m.triangles.clone(),
        normals: pc.normals,
        values: pc.values,
        colors: pc.colors,
    }
}

/// Debug text shows the shortest round-trip digits and the sign of zero: equal text means
/// bit-equal values.
fn same<T: std::fmt::Debug>(a: &T, b: &T) -> Result<(), TestCaseError> {
    prop_assert_eq!(format!("{a:?}"), format!("{b:?}"));
    Ok(())
}

fn options(encoding: PlyEncoding, precision: Precision) -> WriteOptions {
    WriteOptions {
        ply_encoding: encoding,
        precision,
        inputs: Vec::new(),
    }
}

fn read_options() -> ReadOptions {
    ReadOptions::default()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn ply_clouds_round_trip(pc64 in cloud(coord64(), 0), pc32 in cloud(coord32(), 0), e in 0..3usize) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.ply");
        write_point_cloud(&path, &pc64, &options(ENCODINGS[e], Precision::F64)).unwrap();
        same(&read_point_cloud(&path, &read_options()).unwrap(), &pc64)?;
        write_point_cloud(&path, &pc32, &options(ENCODINGS[e], Precision::F32)).unwrap();
        same(&read_point_cloud(&path, &read_options()).unwrap(), &round_cloud(&pc32))?;
    }

    #[test]
    fn ply_meshes_round_trip(m64 in mesh(coord64()), m32 in mesh(coord32()), e in 0..3usize) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.ply");
        write_mesh(&path, &m64, &options(ENCODINGS[e], Precision::F64)).unwrap();
        same(&read_mesh(&path, &read_options()).unwrap(), &m64)?;
        write_mesh(&path, &m32, &options(ENCODINGS[e], Precision::F32)).unwrap();
        let g = read_geometry(&path, &read_options()).unwrap();
        prop_assert_eq!(g.info.polygons, m32.triangles.len() as u64);
        same(&read_mesh(&path, &read_options()).unwrap(), &round_mesh(&m32))?;
    }

    #[test]
    fn sphere_sets_round_trip(
        centres in vec(vec3(coord64()), 0..12),
        radii in vec(0.0f64..1e6, 12),
        e in 0..3usize,
        f32_output in any::<bool>(),
    ) {
        let spheres = SphereSet { radii: radii[..centres.len()].to_vec(), centres };
        let dir = tempfile::tempdir().unwrap();
        for name in ["s.ply", "s.sph", "s.spheres", "s.txt"] {
            let path = dir.path().join(name);
            write_spheres(&path, &spheres, &options(ENCODINGS[e], Precision::F64)).unwrap();
            same(&read_spheres(&path, &read_options()).unwrap(), &spheres)?;
        }
        if f32_output {
            let small = SphereSet {
                centres: spheres.centres.iter().map(|c| c.clamp(DVec3::splat(-1e30), DVec3::splat(1e30))).collect(),
                radii: spheres.radii.clone(),
            };
            let expected = SphereSet {
                centres: small.centres.iter().map(|c| DVec3::new(round(c.x), round(c.y), round(c.z))).collect(),
                radii: small.radii.iter().copied().map(round).collect(),
            };
            let path = dir.path().join("s32.ply");
            write_spheres(&path, &small, &options(ENCODINGS[e], Precision::F32)).unwrap();
            same(&read_spheres(&path, &read_options()).unwrap(), &expected)?;
        }
    }

    #[test]
    fn obj_and_off_round_trip(m in mesh(coord64()), pc in cloud(coord64(), 0), m32 in mesh(coord32())) {
        let dir = tempfile::tempdir().unwrap();
        // Values and colours are left out of meshes in these formats, refused for clouds.
        let mut m = m;
        m.values = None;
        m.colors = None;
        let mut m32 = m32;
        m32.values = None;
        m32.colors = None;
        let mut pc = pc;
        pc.confidence = None;
        pc.values = None;
        if pc.colors.take().is_some() {
            let refused = write_point_cloud(&dir.path().join("colours.obj"), &{
                let mut coloured = pc.clone();
                coloured.colors = Some(vec![[1, 2, 3]; pc.len()]);
                coloured
            }, &WriteOptions::default());
            prop_assert!(matches!(refused, Err(IoError::Unsupported { .. })), "{:?}", refused);
        }
        for name in ["m.obj", "m.off"] {
            let path = dir.path().join(name);
            write_mesh(&path, &m, &WriteOptions::default()).unwrap();
            same(&read_mesh(&path, &read_options()).unwrap(), &m)?;
            // Untyped text stores the shortest digits that identify the f32: they read back
            // as an f64 that rounds to the same f32.
            write_mesh(&path, &m32, &options(PlyEncoding::Ascii, Precision::F32)).unwrap();
            same(&round_mesh(&read_mesh(&path, &read_options()).unwrap()), &round_mesh(&m32))?;
            let path = dir.path().join(name.replace('m', "c"));
            write_point_cloud(&path, &pc, &WriteOptions::default()).unwrap();
            let mut expected = pc.clone();
            if name.ends_with("obj") && pc.is_empty() {
                // An OBJ file without `vn` lines cannot say that an empty cloud had normals.
                expected.normals = None;
            }
            same(&read_point_cloud(&path, &read_options()).unwrap(), &expected)?;
        }
    }

    #[test]
    fn column_text_round_trips(pc in cloud(coord64(), 0), pc32 in cloud(coord32(), 0)) {
        let dir = tempfile::tempdir().unwrap();
        let mut pc = pc;
        pc.confidence = None;
        pc.colors = None;
        let mut pc32 = pc32;
        pc32.confidence = None;
        pc32.colors = None;
        for name in ["c.xyz", "c.pwn", "c.txt"] {
            let path = dir.path().join(name);
            let result = write_point_cloud(&path, &pc, &WriteOptions::default());
            if name == "c.txt" && pc.values.is_some() && pc.normals.is_none() {
                // 4 columns in .txt mean spheres: refused rather than misread later.
                let refused = matches!(result, Err(IoError::Unsupported { .. }));
                prop_assert!(refused);
                continue;
            }
            result.unwrap();
            same(&read_point_cloud(&path, &read_options()).unwrap(), &pc)?;
            if !(name == "c.txt" && pc32.values.is_some() && pc32.normals.is_none()) {
                write_point_cloud(&path, &pc32, &options(PlyEncoding::Ascii, Precision::F32)).unwrap();
                same(&round_cloud(&read_point_cloud(&path, &read_options()).unwrap()), &round_cloud(&pc32))?;
            }
        }
    }

    #[test]
    fn stl_round_trips_through_f32_and_recovers_shared_vertices(
        positions in vec(vec3(coord32()), 1..12),
        extra in vec([any::<u32>(), any::<u32>(), any::<u32>()], 0..12),
    ) {
        // Distinct after rounding, since STL merges bit-equal vertices.
        let mut rounded: Vec<DVec3> = Vec::new();
        for p in positions {
            let r = DVec3::new(round(p.x), round(p.y), round(p.z));
            if !rounded.iter().any(|q| q.to_array().map(f64::to_bits) == r.to_array().map(f64::to_bits)) {
                rounded.push(r);
            }
        }
        let n = rounded.len() as u32;
        // Consecutive triangles first: vertices appear in index order and all are used.
        let mut triangles: Vec<[u32; 3]> = (0..n).map(|i| [i, (i + 1) % n, (i + 2) % n]).collect();
        triangles.extend(extra.iter().map(|t| t.map(|v| v % n)));
        let m = TriMesh::new(rounded, triangles);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.stl");
        write_mesh(&path, &m, &WriteOptions::default()).unwrap();
        same(&read_mesh(&path, &read_options()).unwrap(), &m)?;
    }
}
