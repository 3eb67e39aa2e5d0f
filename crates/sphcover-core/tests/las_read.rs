//! LAS reader: files built here byte by byte (versions 1.2 and 1.4, point formats 0, 3, 6),
//! and every way the header can lie.

use std::path::Path;

use glam::DVec3;
use sphcover_core::PointCloud;
use sphcover_core::io::{
    Format, IoError, Location, Problem, ReadOptions, WriteOptions, parse_geometry, read_geometry,
    write_point_cloud,
};

/// A LAS file: header fields the tests vary, and points as raw integers with intensity.
struct Las {
    minor: u8,
    format: u8,
    record_length: u16,
    scale: [f64; 3],
    offset: [f64; 3],
    points: Vec<([i32; 3], u16)>,
    legacy_count: Option<u32>,
    count64: Option<u64>,
    vlr_bytes: usize,
}

impl Las {
    fn new(minor: u8, format: u8, record_length: u16) -> Las {
        Las {
            minor,
            format,
            record_length,
            scale: [0.01, 0.01, 0.001],
            offset: [1000.0, -2000.0, 5.0],
            points: vec![
                ([0, 0, 0], 7),
                ([100, -250, 3000], 65535),
                ([-7, 12, -1], 0),
            ],
            legacy_count: None,
            count64: None,
            vlr_bytes: 0,
        }
    }

    fn bytes(&self) -> Vec<u8> {
        let header_size: usize = if self.minor >= 4 { 375 } else { 227 };
        let mut h = vec![0u8; header_size];
        h[0..4].copy_from_slice(b"LASF");
        h[24] = 1;
        h[25] = self.minor;
        h[26..32].copy_from_slice(b"tester");
        h[94..96].copy_from_slice(&(header_size as u16).to_le_bytes());
        let offset = (header_size + self.vlr_bytes) as u32;
        h[96..100].copy_from_slice(&offset.to_le_bytes());
        h[104] = self.format;
        h[105..107].copy_from_slice(&self.record_length.to_le_bytes());
        let n = self.points.len();
        let legacy = self
            .legacy_count
            .unwrap_or(if self.minor >= 4 && self.format >= 6 {
                0
            } else {
                n as u32
            });
        h[107..111].copy_from_slice(&legacy.to_le_bytes());
        for axis in 0..3 {
            h[131 + 8 * axis..139 + 8 * axis].copy_from_slice(&self.scale[axis].to_le_bytes());
            h[155 + 8 * axis..163 + 8 * axis].copy_from_slice(&self.offset[axis].to_le_bytes());
        }
        if self.minor >= 4 {
            let c = self.count64.unwrap_or(n as u64);
            h[247..255].copy_from_slice(&c.to_le_bytes());
        }
        h.extend(std::iter::repeat_n(0xAB, self.vlr_bytes));
        for (raw, intensity) in &self.points {
            let mut r = vec![0x5Au8; self.record_length as usize];
            for axis in 0..3 {
                r[4 * axis..4 * axis + 4].copy_from_slice(&raw[axis].to_le_bytes());
            }
            r[12..14].copy_from_slice(&intensity.to_le_bytes());
            h.extend(r);
        }
        h
    }

    fn expected(&self) -> Vec<DVec3> {
        self.points
            .iter()
            .map(|(raw, _)| {
                DVec3::from_array(std::array::from_fn(|a| {
                    f64::from(raw[a]) * self.scale[a] + self.offset[a]
                }))
            })
            .collect()
    }
}

fn parse(bytes: &[u8]) -> Result<sphcover_core::io::Geometry, IoError> {
    parse_geometry(
        bytes,
        Format::Las,
        Path::new("t.las"),
        &ReadOptions::default(),
    )
}

fn malformed(bytes: &[u8]) -> (Location, Problem) {
    match parse(bytes) {
        Err(IoError::Malformed { path, at, problem }) => {
            assert_eq!(path, Path::new("t.las"));
            (at, problem)
        }
        other => panic!("expected Malformed, got {other:?}"),
    }
}

#[test]
fn reads_versions_and_point_formats() {
    for (minor, format, length) in [
        (2u8, 0u8, 20u16),
        (2, 3, 34),
        (4, 0, 20),
        (4, 3, 34),
        (4, 6, 30),
        (4, 10, 67),
        (0, 1, 28),
    ] {
        for extra in [0u16, 5] {
            let las = Las::new(minor, format, length + extra);
            let g = parse(&las.bytes()).unwrap();
            assert_eq!(
                g.points.positions,
                las.expected(),
                "1.{minor} format {format}"
            );
            assert_eq!(g.points.values, Some(vec![7.0, 65535.0, 0.0]));
            assert!(g.triangles.is_empty());
            assert_eq!(g.info.format, Format::Las);
            assert_eq!(
                g.info.variant,
                format!("LAS 1.{minor}, point format {format}")
            );
            let vertex = &g.info.elements[0];
            assert_eq!((vertex.name.as_str(), vertex.count), ("vertex", 3));
            let names: Vec<_> = vertex.properties.iter().map(|p| p.name.as_str()).collect();
            assert_eq!(&names[..4], ["x", "y", "z", "intensity"]);
            assert_eq!(names.contains(&"gps_time"), format != 0);
            assert_eq!(names.contains(&"red"), format == 3 || format == 10);
            assert_eq!(names.last() == Some(&"extra_bytes"), extra > 0);
            assert_eq!(g.info.comments, vec!["system: tester".to_string()]);
        }
    }
}

#[test]
fn skips_variable_length_records() {
    let mut las = Las::new(2, 3, 34);
    las.vlr_bytes = 54 + 100;
    let g = parse(&las.bytes()).unwrap();
    assert_eq!(g.points.positions, las.expected());
}

#[test]
fn count_1_4_prefers_64_bit_and_falls_back_to_legacy() {
    let mut las = Las::new(4, 3, 34);
    las.legacy_count = Some(0);
    assert_eq!(parse(&las.bytes()).unwrap().points.len(), 3);
    las.legacy_count = Some(3);
    las.count64 = Some(0);
    assert_eq!(parse(&las.bytes()).unwrap().points.len(), 3);
    // A 1.2 file has no 64-bit count: the bytes at 247 are point data, not a count.
    let las = Las::new(2, 0, 20);
    assert_eq!(parse(&las.bytes()).unwrap().points.len(), 3);
}

#[test]
fn refuses_bad_signature_version_and_layout() {
    let good = Las::new(2, 3, 34).bytes();
    let mut b = good.clone();
    b[0..4].copy_from_slice(b"LASG");
    let (at, p) = malformed(&b);
    assert_eq!(at, Location::Byte(0));
    assert!(p.to_string().contains("LASF"), "{p}");

    let mut b = good.clone();
    b[25] = 5;
    assert_eq!(malformed(&b).0, Location::Byte(24));

    let mut b = good.clone();
    b[104] = 11;
    assert_eq!(malformed(&b).0, Location::Byte(104));

    let mut b = good.clone();
    b[105..107].copy_from_slice(&33u16.to_le_bytes());
    let (at, p) = malformed(&b);
    assert_eq!(at, Location::Byte(105));
    assert!(p.to_string().contains("34"), "{p}");

    let mut b = good.clone();
    b[96..100].copy_from_slice(&100u32.to_le_bytes());
    assert_eq!(malformed(&b).0, Location::Byte(96));

    let mut b = good.clone();
    b[139..147].copy_from_slice(&0.0f64.to_le_bytes());
    assert_eq!(malformed(&b).0, Location::Byte(139));

    let mut b = good;
    b[171..179].copy_from_slice(&f64::NAN.to_le_bytes());
    assert_eq!(malformed(&b).0, Location::Byte(171));

    // A 1.4 file must have the 375-byte header.
    let mut b = Las::new(4, 0, 20).bytes();
    b[94..96].copy_from_slice(&227u16.to_le_bytes());
    assert_eq!(malformed(&b).0, Location::Byte(94));
}

#[test]
fn refuses_laz_with_a_hint() {
    let mut b = Las::new(2, 3, 34).bytes();
    b[104] = 3 | 0x80;
    let (at, p) = malformed(&b);
    assert_eq!(at, Location::Byte(104));
    assert!(
        p.to_string()
            .contains("LAZ is compressed; decompress with laszip"),
        "{p}"
    );
    // The .laz extension reaches the LAS reader, which tells what is wrong.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scan.laz");
    std::fs::write(&path, &b).unwrap();
    let e = read_geometry(&path, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("scan.laz"), "{e}");
    assert!(e.to_string().contains("laszip"), "{e}");
}

#[test]
fn truncated_files_and_absurd_counts_are_refused_before_allocating() {
    let las = Las::new(2, 3, 34);
    let good = las.bytes();
    // Cut inside the header, and inside every record.
    for cut in [3, 4, 100, 226] {
        let (at, _) = malformed(&good[..cut]);
        assert!(matches!(at, Location::Byte(_)));
    }
    for cut in 227..good.len() {
        let (at, p) = malformed(&good[..cut]);
        let complete = (cut - 227) / 34;
        assert_eq!(at, Location::Byte(227 + 34 * complete as u64), "cut {cut}");
        assert_eq!(
            p,
            Problem::Truncated {
                element: "vertex".into(),
                index: complete as u64,
                declared: 3
            }
        );
    }
    let mut absurd = Las::new(2, 0, 20);
    absurd.legacy_count = Some(u32::MAX);
    assert!(
        matches!(malformed(&absurd.bytes()).1, Problem::Truncated { declared, .. } if declared == u64::from(u32::MAX))
    );
    let mut absurd = Las::new(4, 6, 30);
    absurd.count64 = Some(u64::MAX);
    assert!(matches!(
        malformed(&absurd.bytes()).1,
        Problem::Truncated {
            declared: u64::MAX,
            ..
        }
    ));
    // An offset past the end of the file.
    let mut b = Las::new(2, 0, 20).bytes();
    b[96..100].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(
        malformed(&b).1,
        Problem::Truncated { index: 0, .. }
    ));
}

#[test]
fn reads_from_disk_and_refuses_to_write_las() {
    let dir = tempfile::tempdir().unwrap();
    let las = Las::new(2, 3, 34);
    let path = dir.path().join("scan.LAS");
    std::fs::write(&path, las.bytes()).unwrap();
    let g = read_geometry(&path, &ReadOptions::default()).unwrap();
    assert_eq!(g.points.positions, las.expected());
    let out = dir.path().join("out.las");
    let cloud = PointCloud::from_positions(vec![DVec3::ZERO]);
    let e = write_point_cloud(&out, &cloud, &WriteOptions::default()).unwrap_err();
    assert!(
        matches!(e, IoError::Unsupported { format: "LAS", .. }),
        "{e}"
    );
    assert!(!out.exists());
}

#[test]
fn no_byte_sequence_panics() {
    let good = Las::new(4, 3, 34).bytes();
    for i in 0..good.len().min(400) {
        for v in [0u8, 0xFF, 0x80, 1] {
            let mut b = good.clone();
            b[i] = v;
            let _ = parse(&b);
        }
    }
}
