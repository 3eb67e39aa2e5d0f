//! Bad input never panics: every file of the malformed corpus gives an error naming the file
//! and a line or byte, and random bytes or random mutations of valid files never make a
//! reader panic.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use proptest::collection::vec;
use proptest::prelude::*;
use sphcover_core::io::{
    Format, NonFinitePolicy, PlyEncoding, Precision, ReadOptions, SphereSet, WriteOptions,
    parse_geometry, read_geometry, write_mesh, write_point_cloud, write_spheres,
};
use sphcover_core::{DVec3, PointCloud, TriMesh};

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/malformed")
}

fn corpus() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(corpus_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().is_some_and(|n| n != "README.md"))
        .collect();
    files.sort();
    files
}

/// True when `message` holds "line N" or "byte N".
fn has_location(message: &str) -> bool {
    ["line ", "byte "].iter().any(|key| {
        message.match_indices(key).any(|(i, _)| {
            message[i + key.len()..]
                .chars()
                .next()
                .is_some_and(|c| c.is_ascii_digit())
        })
    })
}

#[test]
fn every_malformed_file_fails_with_file_name_and_location() {
    let files = corpus();
    assert!(
        files.len() >= 25,
        "only {} files in the corpus",
        files.len()
    );
    let readme = std::fs::read_to_string(corpus_dir().join("README.md")).unwrap();
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            readme.contains(&format!("`{name}`")),
            "{name} is not described in README.md"
        );
        let result = std::panic::catch_unwind(|| read_geometry(&path, &ReadOptions::default()));
        let Ok(result) = result else {
            panic!("{name}: the reader panicked");
        };
        let Err(err) = result else {
            panic!("{name}: read without error");
        };
        let message = err.to_string();
        assert!(
            message.contains(&name),
            "{name}: message without the file name: {message}"
        );
        assert!(
            has_location(&message),
            "{name}: message without a location: {message}"
        );
    }
}

#[test]
fn corpus_errors_name_the_right_place() {
    let read = |name: &str| {
        read_geometry(&corpus_dir().join(name), &ReadOptions::default())
            .unwrap_err()
            .to_string()
    };
    let tail = |name: &str| read(name).split_once(": ").unwrap().1.to_string();
    assert_eq!(
        tail("ply_missing_field.ply"),
        "line 13: vertex 2: expected 6 numbers, found 5"
    );
    assert!(
        tail("ply_truncated_binary.ply")
            .contains("vertex 5 truncated (the file declares 10 vertex records)")
    );
    assert_eq!(
        tail("ply_face_index_out_of_range.ply"),
        "line 14: face 1: vertex index 3 out of range (the file has 3 vertices)"
    );
    assert!(
        tail("ply_nan_binary.ply")
            .contains(": vertex 1 is not finite (1 vertex with 1 NaN or infinite value;")
    );
    assert_eq!(
        tail("obj_face_zero_index.obj"),
        "line 4: face 0: vertex index 0 out of range (the file has 3 vertices)"
    );
    assert!(tail("stl_binary_nan.stl").starts_with("byte 108: vertex 1 is not finite"));
    assert_eq!(
        tail("sph_three_columns.sph"),
        "line 2: sphere 1: expected 4 numbers, found 3"
    );
}

#[test]
fn absurd_counts_fail_fast_without_allocating() {
    // 10^18 vertex records of 12 bytes would be 12 EB: the size check must come first, or
    // the allocation aborts the test process.
    for name in [
        "ply_absurd_vertex_count.ply",
        "ply_absurd_face_count.ply",
        "off_absurd_counts.off",
        "stl_count_too_large.stl",
        "ply_huge_list_length.ply",
    ] {
        assert!(read_geometry(&corpus_dir().join(name), &ReadOptions::default()).is_err());
    }
}

/// Valid files of every format and variant, as bytes.
fn samples() -> &'static [(Format, Vec<u8>)] {
    static SAMPLES: OnceLock<Vec<(Format, Vec<u8>)>> = OnceLock::new();
    SAMPLES.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let positions: Vec<DVec3> = (0..6)
            .map(|i| DVec3::new(i as f64 * 0.5, (i * i) as f64, -(i as f64)))
            .collect();
        let normals: Vec<DVec3> = positions.iter().map(|p| p.normalize_or_zero()).collect();
        let values: Vec<f64> = (0..6).map(|i| i as f64 / 7.0).collect();
        let colors: Vec<[u8; 3]> = (0..6u8).map(|i| [40 * i, 255 - i, 7]).collect();
        let mesh = TriMesh {
            vertices: positions.clone(),
            triangles: vec![[0, 1, 2], [2, 3, 4], [4, 5, 0], [1, 3, 5]],
            normals: Some(normals.clone()),
            values: Some(values.clone()),
            colors: Some(colors.clone()),
        };
        let cloud = PointCloud {
            positions: positions.clone(),
            normals: Some(normals.clone()),
            confidence: Some(values.clone()),
            values: Some(values.clone()),
            colors: Some(colors),
        };
        let spheres = SphereSet {
            centres: positions.clone(),
            radii: values.clone(),
        };
        let mut out = Vec::new();
        let mut keep = |name: &str| {
            let path = dir.path().join(name);
            out.push((Format::from_path(&path).unwrap(), std::fs::read(&path).unwrap()));
        };
        for (k, encoding) in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian, PlyEncoding::BinaryBigEndian]
            .into_iter()
            .enumerate()
        {
            for precision in [Precision::F32, Precision::F64] {
                let options = WriteOptions { ply_encoding: encoding, precision, inputs: Vec::new() };
                let name = format!("m{k}{precision:?}.ply");
                write_mesh(&dir.path().join(&name), &mesh, &options).unwrap();
                keep(&name);
                let name = format!("c{k}{precision:?}.ply");
                write_point_cloud(&dir.path().join(&name), &cloud, &options).unwrap();
                keep(&name);
            }
        }
        let plain = TriMesh { values: None, ..mesh.clone() };
        let options = WriteOptions::default();
        for name in ["m.obj", "m.off"] {
            write_mesh(&dir.path().join(name), &plain, &options).unwrap();
            keep(name);
        }
        let bare = TriMesh { normals: None, ..plain.clone() };
        write_mesh(&dir.path().join("m.stl"), &bare, &options).unwrap();
        keep("m.stl");
        let mut xyz_cloud = cloud.clone();
        xyz_cloud.confidence = None;
        xyz_cloud.colors = None;
        for name in ["c.xyz", "c.pwn", "c.txt"] {
            write_point_cloud(&dir.path().join(name), &xyz_cloud, &options).unwrap();
            keep(name);
        }
        for name in ["s.sph", "s.txt"] {
            write_spheres(&dir.path().join(name), &spheres, &options).unwrap();
            keep(name);
        }
        let ascii_stl = b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
        out.push((Format::Stl, ascii_stl.to_vec()));
        out
    })
}

const FORMATS: [Format; 8] = [
    Format::Ply,
    Format::Obj,
    Format::Off,
    Format::Stl,
    Format::Xyz,
    Format::Pwn,
    Format::Txt,
    Format::Sph,
];

const POLICIES: [NonFinitePolicy; 3] = [
    NonFinitePolicy::Refuse,
    NonFinitePolicy::Drop,
    NonFinitePolicy::Keep,
];

/// Parses with every policy; only a panic fails the test (errors are expected).
fn parse_all_ways(bytes: &[u8], format: Format) {
    for policy in POLICIES {
        let options = ReadOptions {
            non_finite: policy,
            ..ReadOptions::default()
        };
        if let Ok(g) = parse_geometry(bytes, format, Path::new("fuzz"), &options) {
            // Whatever is accepted is consistent.
            assert!(g.points.check().is_ok());
            let n = g.points.len();
            assert!(g.triangles.iter().flatten().all(|&v| (v as usize) < n));
            if let Some(r) = &g.radii {
                assert_eq!(r.len(), n);
            }
        }
    }
}

#[derive(Clone, Debug)]
enum Mutation {
    Set(usize, u8),
    Insert(usize, u8),
    Remove(usize),
    Truncate(usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Set(i, b)),
        (
            any::<usize>(),
            prop_oneof![any::<u8>(), Just(b' '), Just(b'\n'), Just(b'-'), Just(b'9')]
        )
            .prop_map(|(i, b)| Mutation::Insert(i, b)),
        any::<usize>().prop_map(Mutation::Remove),
        any::<usize>().prop_map(Mutation::Truncate),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    if bytes.is_empty() {
        return;
    }
    match *m {
        Mutation::Set(i, b) => {
            let n = bytes.len();
            bytes[i % n] = b;
        }
        Mutation::Insert(i, b) => {
            let n = bytes.len();
            bytes.insert(i % (n + 1), b);
        }
        Mutation::Remove(i) => {
            let n = bytes.len();
            bytes.remove(i % n);
        }
        Mutation::Truncate(i) => {
            let n = bytes.len();
            bytes.truncate(i % (n + 1));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn random_bytes_never_panic(bytes in vec(any::<u8>(), 0..600), f in 0..FORMATS.len()) {
        parse_all_ways(&bytes, FORMATS[f]);
    }

    #[test]
    fn random_bodies_after_valid_headers_never_panic(body in vec(any::<u8>(), 0..600), k in 0..4usize) {
        let header: &[u8] = match k {
            0 => b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty list uchar uint extra\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n",
            1 => b"ply\nformat binary_big_endian 1.0\nelement vertex 5\nproperty double x\nproperty short y\nproperty uchar z\nproperty float radius\nelement face 2\nproperty list int float vertex_index\nend_header\n",
            2 => b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n",
            _ => b"OFF\n3 2 0\n",
        };
        let mut bytes = header.to_vec();
        bytes.extend_from_slice(&body);
        let format = if k == 3 { Format::Off } else { Format::Ply };
        parse_all_ways(&bytes, format);
    }

    #[test]
    fn mutated_valid_files_never_panic(s in any::<prop::sample::Index>(), mutations in vec(mutation(), 1..6)) {
        let samples = samples();
        let (format, bytes) = &samples[s.index(samples.len())];
        let mut bytes = bytes.clone();
        for m in &mutations {
            apply(&mut bytes, m);
        }
        parse_all_ways(&bytes, *format);
    }
}

#[test]
fn valid_samples_parse() {
    for (format, bytes) in samples() {
        parse_geometry(bytes, *format, Path::new("sample"), &ReadOptions::default()).unwrap();
    }
}
