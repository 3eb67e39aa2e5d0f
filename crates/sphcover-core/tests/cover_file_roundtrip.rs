//! Cover files: exact round trips in every encoding, the layout other tools see, and errors
//! that name the file and the place.

use proptest::prelude::*;
use sphcover_core::io::{
    CoverFileMeta, IoError, Location, PlyEncoding, Precision, ReadOptions, WriteOptions,
    parse_cover, read_cover, read_spheres, write_cover,
};
use sphcover_core::{
    Cover, DMat3, DVec3, Kernel, LinearFunction, LocalFunctions, Normalisation, QuadraticFunction,
};
use std::path::Path;

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e3..1e3f64,
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        Just(0.0),
        Just(-0.0),
        Just(f64::MIN_POSITIVE),
        Just(5e-324),
    ]
}

fn vec3() -> impl Strategy<Value = DVec3> {
    (finite(), finite(), finite()).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn radius() -> impl Strategy<Value = f64> {
    prop_oneof![1e-6..10.0f64, Just(f64::MIN_POSITIVE), Just(f64::MAX)]
}

fn kernel() -> impl Strategy<Value = Kernel> {
    prop::sample::select(Kernel::ALL.to_vec())
}

fn cover() -> impl Strategy<Value = Cover> {
    (0usize..40, any::<bool>(), kernel()).prop_flat_map(|(n, linear, kernel)| {
        let centres = prop::collection::vec(vec3(), n);
        let radii = prop::collection::vec(radius(), n);
        let funcs = if linear {
            prop::collection::vec((vec3(), finite()), n)
                .prop_map(|v| {
                    LocalFunctions::from_linear(
                        v.into_iter()
                            .map(|(alpha, beta)| LinearFunction { alpha, beta }),
                    )
                })
                .boxed()
        } else {
            prop::collection::vec((vec3(), vec3(), vec3(), finite()), n)
                .prop_map(|v| {
                    LocalFunctions::from_quadratic(v.into_iter().map(|(d, o, b, k)| {
                        // Symmetric A from its diagonal d and off-diagonal o = (xy, xz, yz).
                        let a = DMat3::from_cols(
                            DVec3::new(d.x, o.x, o.y),
                            DVec3::new(o.x, d.y, o.z),
                            DVec3::new(o.y, o.z, d.z),
                        );
                        QuadraticFunction { a, b, k }
                    }))
                })
                .boxed()
        };
        (centres, radii, funcs).prop_map(move |(c, r, f)| Cover::new(c, r, f, kernel).unwrap())
    })
}

fn meta() -> impl Strategy<Value = CoverFileMeta> {
    (
        vec3(),
        radius(),
        prop_oneof![Just(1.0), 1.0..10.0f64],
        prop::collection::vec("[ -~]{0,30}", 0..3),
    )
        .prop_map(|(centre, scale, expansion, notes)| CoverFileMeta {
            normalisation: Normalisation { centre, scale },
            expansion,
            // Surrounding blanks are not kept by PLY comment lines.
            notes: notes.into_iter().map(|n| n.trim().to_string()).collect(),
        })
}

fn encoding() -> impl Strategy<Value = PlyEncoding> {
    prop::sample::select(vec![
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
        PlyEncoding::Ascii,
    ])
}

/// Bit patterns of everything a cover holds (so −0.0 and 0.0 differ).
fn bits(c: &Cover) -> Vec<u64> {
    let mut v: Vec<u64> = c
        .centres()
        .iter()
        .flat_map(|p| p.to_array())
        .map(f64::to_bits)
        .collect();
    v.extend(c.radii().iter().map(|r| r.to_bits()));
    match c.funcs() {
        LocalFunctions::Linear { alpha, beta } => {
            v.extend(alpha.iter().flat_map(|a| a.to_array()).map(f64::to_bits));
            v.extend(beta.iter().map(|b| b.to_bits()));
        }
        LocalFunctions::Quadratic { a, b, k } => {
            v.extend(a.iter().flat_map(|m| m.to_cols_array()).map(f64::to_bits));
            v.extend(b.iter().flat_map(|x| x.to_array()).map(f64::to_bits));
            v.extend(k.iter().map(|x| x.to_bits()));
        }
    }
    v
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn f64_round_trip_is_exact(cover in cover(), meta in meta(), enc in encoding()) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.ply");
        let options = WriteOptions { ply_encoding: enc, ..WriteOptions::default() };
        write_cover(&path, &cover, &meta, &options).unwrap();
        let (back, back_meta) = read_cover(&path).unwrap();
        prop_assert_eq!(bits(&back), bits(&cover));
        prop_assert_eq!(back.kernel(), cover.kernel());
        prop_assert_eq!(back.funcs().is_linear(), cover.funcs().is_linear());
        prop_assert_eq!(back_meta.normalisation.centre.to_array().map(f64::to_bits),
            meta.normalisation.centre.to_array().map(f64::to_bits));
        prop_assert_eq!(back_meta.normalisation.scale.to_bits(), meta.normalisation.scale.to_bits());
        prop_assert_eq!(back_meta.expansion.to_bits(), meta.expansion.to_bits());
        prop_assert_eq!(back_meta.notes, meta.notes);
    }
}

fn small_cover() -> Cover {
    let centres = vec![DVec3::new(0.1, 0.2, 0.3), DVec3::new(-0.4, 0.0, 0.25)];
    let funcs = LocalFunctions::from_linear(
        centres
            .iter()
            .map(|&c| LinearFunction::from_global(DVec3::new(0.0, 0.0, -1.0), 0.1, c)),
    );
    Cover::new(centres, vec![0.05, 0.125], funcs, Kernel::QuadraticBSpline).unwrap()
}

#[test]
fn f32_files_are_half_the_size_and_close() {
    let dir = tempfile::tempdir().unwrap();
    let (p64, p32) = (dir.path().join("a.ply"), dir.path().join("b.ply"));
    let cover = small_cover();
    let meta = CoverFileMeta::default();
    write_cover(&p64, &cover, &meta, &WriteOptions::default()).unwrap();
    let f32_options = WriteOptions {
        precision: Precision::F32,
        ..WriteOptions::default()
    };
    write_cover(&p32, &cover, &meta, &f32_options).unwrap();
    let (back, _) = read_cover(&p32).unwrap();
    for (a, b) in back.radii().iter().zip(cover.radii()) {
        assert_eq!(*a, f64::from(*b as f32));
    }
    let header = String::from_utf8_lossy(&std::fs::read(&p32).unwrap()).into_owned();
    assert!(header.contains("property float radius"));
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    assert!(size(&p32) < size(&p64));
}

#[test]
fn layout_is_a_vertex_sphere_set_with_documented_header() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.ply");
    let meta = CoverFileMeta {
        normalisation: Normalisation {
            centre: DVec3::new(1.0, 2.0, 3.0),
            scale: 0.5,
        },
        expansion: 4.0,
        notes: vec!["eps 0.0025".into()],
    };
    let options = WriteOptions {
        ply_encoding: PlyEncoding::Ascii,
        ..WriteOptions::default()
    };
    write_cover(&path, &small_cover(), &meta, &options).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let expected_header = "ply\nformat ascii 1.0\ncomment sphcover cover 1\ncomment kernel bspline2\n\
        comment expansion 4\ncomment normalisation 1 2 3 0.5\ncomment note eps 0.0025\n\
        element vertex 2\nproperty double x\nproperty double y\nproperty double z\n\
        property double radius\nproperty double ax\nproperty double ay\nproperty double az\n\
        property double b\nend_header\n";
    assert!(text.starts_with(expected_header), "{text}");
    // Generic readers see the supports as spheres.
    let spheres = read_spheres(&path, &ReadOptions::default()).unwrap();
    assert_eq!(spheres.radii, [0.05, 0.125]);
}

fn malformed(text: &str) -> (Location, String) {
    match parse_cover(text.as_bytes(), Path::new("bad.ply")) {
        Err(IoError::Malformed { path, at, problem }) => {
            assert_eq!(path, Path::new("bad.ply"));
            (at, problem.to_string())
        }
        other => panic!("expected a malformed-file error, got {other:?}"),
    }
}

const HEAD: &str = "ply\nformat ascii 1.0\ncomment kernel wendland\nelement vertex 1\n\
    property double x\nproperty double y\nproperty double z\nproperty double radius\n";

#[test]
fn errors_name_the_place() {
    let linear = "property double ax\nproperty double ay\nproperty double az\nproperty double b\n";
    // A valid file, then variations.
    let ok = format!("{HEAD}{linear}end_header\n0 0 0 1 0 0 1 0\n");
    let (cover, meta) = parse_cover(ok.as_bytes(), Path::new("ok.ply")).unwrap();
    assert_eq!(cover.kernel(), Kernel::WendlandC2);
    assert_eq!(meta, CoverFileMeta::default());

    let (at, msg) = malformed(&ok.replace("comment kernel wendland\n", ""));
    assert!(msg.contains("kernel"), "{msg}");
    assert!(matches!(at, Location::Line(_)));

    let (at, msg) = malformed(&ok.replace("wendland", "cubic"));
    assert_eq!(at, Location::Line(3));
    assert!(msg.contains("unknown kernel"), "{msg}");

    let (at, msg) = malformed(&ok.replace(
        "comment kernel wendland\n",
        "comment kernel wendland\ncomment expansion 0.5\n",
    ));
    assert_eq!(at, Location::Line(4));
    assert!(msg.contains("expansion"), "{msg}");

    let (_, msg) = malformed(&ok.replace(
        "comment kernel wendland\n",
        "comment kernel wendland\ncomment normalisation 0 0 0\n",
    ));
    assert!(msg.contains("normalisation"), "{msg}");

    let (_, msg) = malformed(&ok.replace("property double b\n", ""));
    assert!(msg.contains("no local-function coefficients"), "{msg}");

    let (at, msg) = malformed(&ok.replace("0 0 0 1 0 0 1 0\n", "0 0 0 -1 0 0 1 0\n"));
    assert_eq!(at, Location::Line(14));
    assert!(msg.contains("radius"), "{msg}");

    let (at, msg) = malformed(&ok.replace("0 0 0 1 0 0 1 0\n", "0 0 0 1 0 0 1\n"));
    assert_eq!(at, Location::Line(14));
    assert!(msg.contains("expected 8"), "{msg}");

    // Binary: a bad radius is located by byte offset; a short body is truncated.
    let bin_head = format!(
        "{}{linear}end_header\n",
        HEAD.replace("ascii", "binary_little_endian")
    );
    let mut bytes = bin_head.clone().into_bytes();
    for v in [0.0f64, 0.0, 0.0, f64::NAN, 0.0, 0.0, 1.0, 0.0] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    match parse_cover(&bytes, Path::new("b.ply")) {
        Err(IoError::Malformed { at, .. }) => assert_eq!(at, Location::Byte(bin_head.len() as u64)),
        other => panic!("{other:?}"),
    }
    match parse_cover(&bytes[..bytes.len() - 3], Path::new("b.ply")) {
        Err(IoError::Malformed { problem, .. }) => {
            assert!(problem.to_string().contains("truncated"))
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        read_cover(Path::new("/nonexistent/c.ply")),
        Err(IoError::Read { .. })
    ));
}

#[test]
fn invalid_metadata_is_refused_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.ply");
    let bad = [
        CoverFileMeta {
            expansion: 0.5,
            ..CoverFileMeta::default()
        },
        CoverFileMeta {
            normalisation: Normalisation {
                centre: DVec3::ZERO,
                scale: 0.0,
            },
            ..CoverFileMeta::default()
        },
        CoverFileMeta {
            notes: vec!["two\nlines".into()],
            ..CoverFileMeta::default()
        },
    ];
    for meta in bad {
        let err = write_cover(&path, &small_cover(), &meta, &WriteOptions::default()).unwrap_err();
        assert!(matches!(err, IoError::InvalidData { .. }), "{err}");
        assert!(!path.exists());
    }
}
