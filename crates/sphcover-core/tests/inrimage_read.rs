//! INRIMAGE-4 reader: files built here (plain and gzip, both byte orders, every sample
//! type), and headers and data that lie.

use std::io::Write;
use std::path::Path;

use glam::DVec3;
use sphcover_core::io::{
    IoError, Location, Problem, ReadOptions, SampleType, VolumeInfo, is_volume_path,
    parse_inrimage, read_volume,
};

/// A header padded to `blocks` × 256 bytes.
fn header(lines: &[&str], blocks: usize) -> Vec<u8> {
    let mut h = b"#INRIMAGE-4#{\n".to_vec();
    for l in lines {
        h.extend_from_slice(l.as_bytes());
        h.push(b'\n');
    }
    let end = b"##}\n";
    let total = 256 * blocks;
    assert!(h.len() + end.len() <= total);
    h.resize(total - end.len(), b'\n');
    h.extend_from_slice(end);
    h
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn parse(
    bytes: &[u8],
) -> Result<(sphcover_core::Volume, sphcover_core::io::InrimageInfo), IoError> {
    parse_inrimage(bytes, Path::new("t.inr"), &ReadOptions::default())
}

fn malformed(bytes: &[u8]) -> (Location, Problem) {
    match parse(bytes) {
        Err(IoError::Malformed { path, at, problem }) => {
            assert_eq!(path, Path::new("t.inr"));
            (at, problem)
        }
        other => panic!("expected Malformed, got {:?}", other.map(|(_, i)| i)),
    }
}

/// Values of a 3 × 2 × 2 volume that every type holds.
const VALUES: [f64; 12] = [
    0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 100.0, 17.0, 42.0, 9.0,
];

fn encode(ty: SampleType, big: bool, v: f64) -> Vec<u8> {
    macro_rules! e {
        ($x:expr) => {
            if big {
                $x.to_be_bytes().to_vec()
            } else {
                $x.to_le_bytes().to_vec()
            }
        };
    }
    match ty {
        SampleType::U8 => e!(v as u8),
        SampleType::I8 => e!(v as i8),
        SampleType::U16 => e!(v as u16),
        SampleType::I16 => e!(v as i16),
        SampleType::U32 => e!(v as u32),
        SampleType::I32 => e!(v as i32),
        SampleType::F32 => e!(v as f32),
        SampleType::F64 => e!(v),
    }
}

fn file(ty: SampleType, big: bool, extra: &[&str], blocks: usize) -> Vec<u8> {
    let (type_name, bits) = match ty {
        SampleType::U8 => ("unsigned fixed", 8),
        SampleType::I8 => ("signed fixed", 8),
        SampleType::U16 => ("unsigned fixed", 16),
        SampleType::I16 => ("signed fixed", 16),
        SampleType::U32 => ("unsigned fixed", 32),
        SampleType::I32 => ("signed fixed", 32),
        SampleType::F32 => ("float", 32),
        SampleType::F64 => ("float", 64),
    };
    let type_line = format!("TYPE={type_name}");
    let bits_line = format!("PIXSIZE={bits} bits");
    let cpu = if big { "CPU=sun" } else { "CPU=decm" };
    let mut lines = vec![
        "XDIM=3",
        "YDIM=2",
        "ZDIM=2",
        "VDIM=1",
        &type_line,
        &bits_line,
        "SCALE=2**0",
        cpu,
    ];
    lines.extend_from_slice(extra);
    let mut f = header(&lines, blocks);
    for &v in &VALUES {
        f.extend(encode(ty, big, v));
    }
    f
}

const TYPES: [SampleType; 8] = [
    SampleType::U8,
    SampleType::I8,
    SampleType::U16,
    SampleType::I16,
    SampleType::U32,
    SampleType::I32,
    SampleType::F32,
    SampleType::F64,
];

#[test]
fn reads_every_type_byte_order_and_compression() {
    for ty in TYPES {
        for big in [false, true] {
            for blocks in [1, 2] {
                let plain = file(
                    ty,
                    big,
                    &[
                        "VX=0.5",
                        "VY=2",
                        "VZ=1.25",
                        "TX=10",
                        "TY=-3",
                        "TZ=0.5",
                        "#made by a test",
                    ],
                    blocks,
                );
                for (bytes, gz) in [(plain.clone(), false), (gzip(&plain), true)] {
                    let (vol, info) = parse(&bytes).unwrap_or_else(|e| panic!("{ty:?} {big}: {e}"));
                    assert_eq!(vol.dims(), [3, 2, 2]);
                    let got: Vec<f64> = (0..vol.len()).map(|i| vol.value(i)).collect();
                    assert_eq!(got, VALUES, "{ty:?} big {big}");
                    assert_eq!(info.sample_type, ty);
                    assert_eq!((info.big_endian, info.gzip), (big, gz));
                    assert_eq!(info.header_size, 256 * blocks as u64);
                    assert_eq!(info.comments, vec!["made by a test".to_string()]);
                    assert_eq!(vol.voxel_size(), DVec3::new(0.5, 2.0, 1.25));
                    assert_eq!(vol.voxel_centre([0, 0, 0]), DVec3::new(10.0, -3.0, 0.5));
                    assert_eq!(vol.voxel_centre([2, 1, 1]), DVec3::new(11.0, -1.0, 1.75));
                    // x fastest: value at (i, j, k) is sample i + 3 j + 6 k.
                    assert_eq!(vol.value(vol.index(2, 1, 1)), 9.0);
                    assert_eq!(vol.value(vol.index(2, 0, 1)), 100.0);
                }
            }
        }
    }
}

#[test]
fn defaults_voxel_size_one_origin_zero_and_z_one() {
    let mut f = header(
        &["XDIM=2", "YDIM=2", "TYPE=unsigned fixed", "PIXSIZE=8 bits"],
        1,
    );
    f.extend([1, 2, 3, 4]);
    let (vol, info) = parse(&f).unwrap();
    assert_eq!(vol.dims(), [2, 2, 1]);
    assert_eq!(info.voxel_size, DVec3::ONE);
    assert_eq!(vol.voxel_centre([1, 1, 0]), DVec3::new(1.0, 1.0, 0.0));
    assert!(!info.big_endian);
}

#[test]
fn read_volume_dispatches_on_the_name() {
    let dir = tempfile::tempdir().unwrap();
    let plain = file(SampleType::I16, true, &[], 1);
    for (name, bytes) in [("a.inr", plain.clone()), ("b.INR.gz", gzip(&plain))] {
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).unwrap();
        assert!(is_volume_path(&path));
        let (vol, info) = read_volume(&path, &ReadOptions::default()).unwrap();
        assert!(matches!(info, VolumeInfo::Inrimage(_)));
        assert_eq!(vol.value(8), 100.0);
        assert_eq!(info.datatype_name(), "int16");
        assert_eq!(info.frames(), 1);
        assert!(
            info.format_description()
                .starts_with("INRIMAGE-4 big-endian")
        );
    }
    assert!(!is_volume_path(Path::new("x.ply")));
}

#[test]
fn refuses_bad_headers() {
    let cases: &[(&[&str], &str)] = &[
        (
            &[
                "XDIM=2",
                "YDIM=2",
                "VDIM=3",
                "TYPE=float",
                "PIXSIZE=32 bits",
                "CPU=pc",
            ],
            "VDIM=3",
        ),
        (
            &["YDIM=2", "TYPE=float", "PIXSIZE=32 bits", "CPU=pc"],
            "no XDIM",
        ),
        (
            &[
                "XDIM=0",
                "YDIM=2",
                "TYPE=float",
                "PIXSIZE=32 bits",
                "CPU=pc",
            ],
            "XDIM=0",
        ),
        (
            &[
                "XDIM=2",
                "YDIM=2",
                "TYPE=complex",
                "PIXSIZE=32 bits",
                "CPU=pc",
            ],
            "TYPE=complex",
        ),
        (
            &[
                "XDIM=2",
                "YDIM=2",
                "TYPE=float",
                "PIXSIZE=16 bits",
                "CPU=pc",
            ],
            "PIXSIZE=16",
        ),
        (
            &["XDIM=2", "YDIM=2", "TYPE=float", "PIXSIZE=32 bits"],
            "no CPU",
        ),
        (
            &[
                "XDIM=2",
                "YDIM=2",
                "TYPE=float",
                "PIXSIZE=32 bits",
                "CPU=vax",
            ],
            "CPU=vax",
        ),
        (
            &[
                "XDIM=2",
                "YDIM=2",
                "TYPE=signed fixed",
                "PIXSIZE=8 bits",
                "SCALE=2**3",
            ],
            "SCALE=2**3",
        ),
        (
            &[
                "XDIM=2",
                "YDIM=2",
                "TYPE=float",
                "PIXSIZE=32 bits",
                "CPU=pc",
                "VX=-1",
            ],
            "VX=-1",
        ),
        (
            &[
                "XDIM=2",
                "YDIM=2",
                "TYPE=float",
                "PIXSIZE=32 bits",
                "CPU=pc",
                "TZ=nan",
            ],
            "TZ=nan",
        ),
        (
            &[
                "XDIM=2",
                "YDIM=2",
                "TYPE=float",
                "PIXSIZE=32 bits",
                "CPU=pc",
                "garbage",
            ],
            "garbage",
        ),
    ];
    for (lines, needle) in cases {
        let mut f = header(lines, 1);
        f.extend(vec![0u8; 2 * 2 * 2 * 8]);
        let (at, problem) = malformed(&f);
        assert!(matches!(problem, Problem::Header(_)), "{needle}: {problem}");
        assert!(problem.to_string().contains(needle), "{needle}: {problem}");
        assert!(matches!(at, Location::Byte(b) if b < 256), "{needle}: {at}");
    }
    let (at, p) = malformed(b"#INRIMAGE-3#{\nXDIM=1\n");
    assert_eq!(at, Location::Byte(0));
    assert!(p.to_string().contains("INRIMAGE-4"));
    assert_eq!(malformed(b"").1, Problem::EmptyFile);
    // No "##}": the header never ends.
    let mut f = b"#INRIMAGE-4#{\nXDIM=1\n".to_vec();
    f.resize(4096, b'\n');
    malformed(&f);
}

#[test]
fn truncated_data_is_refused_before_allocating() {
    let good = file(SampleType::I16, false, &[], 1);
    for cut in 1..good.len() {
        let (at, p) = malformed(&good[..cut]);
        if cut >= 256 {
            assert_eq!(at, Location::Byte(cut as u64), "cut {cut}");
            assert_eq!(
                p,
                Problem::Truncated {
                    element: "int16 voxel".into(),
                    index: (cut as u64 - 256) / 2,
                    declared: 12
                }
            );
        }
        // The same cut, compressed: the decompressed stream ends early.
        let (_, pz) = malformed(&gzip(&good[..cut]));
        if cut >= 256 {
            assert!(
                matches!(pz, Problem::Truncated { declared: 12, .. }),
                "{pz}"
            );
        }
    }
    // A gzip file declaring more than DEFLATE can produce from its size.
    let mut f = header(
        &[
            "XDIM=100000",
            "YDIM=100000",
            "ZDIM=1000",
            "TYPE=float",
            "PIXSIZE=64 bits",
            "CPU=pc",
        ],
        1,
    );
    f.extend([0u8; 16]);
    assert!(matches!(malformed(&gzip(&f)).1, Problem::Header(_)));
    // Overflowing dims.
    let mut f = header(
        &[
            "XDIM=18446744073709551615",
            "YDIM=4",
            "TYPE=float",
            "PIXSIZE=64 bits",
            "CPU=pc",
        ],
        1,
    );
    f.extend([0u8; 16]);
    malformed(&f);
    // Bytes after the declared data: ignored in a plain file (never read), refused in a gzip
    // stream one byte past the data (a stream that inflates further than its header says
    // is not decompressed to its end).
    let mut long = good.clone();
    long.extend(vec![7u8; 1000]);
    assert_eq!(parse(&long).unwrap().0.value(8), 100.0);
    let (at, problem) = malformed(&gzip(&long));
    assert_eq!(at, Location::Byte(good.len() as u64));
    assert!(problem.to_string().contains("goes on after"), "{problem}");
}

#[test]
fn no_byte_sequence_panics() {
    let good = file(SampleType::F32, false, &["VX=2"], 1);
    for i in 0..good.len() {
        for v in [0u8, b'\n', b'#', b'=', 0xFF] {
            let mut b = good.clone();
            b[i] = v;
            let _ = parse(&b);
        }
    }
}
