//! LAS reader: files built here byte by byte (versions 1.2 and 1.4, point formats 0, 3, 6),
//! every way the header can lie, and LAZ twins of LAS files.

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

/// `las` with the red, green, blue of record `i` set to `rgb(i)` at byte `at` of the record.
fn with_colours(las: &Las, at: usize, rgb: impl Fn(usize) -> [u16; 3]) -> Vec<u8> {
    let mut bytes = las.bytes();
    let start = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as usize;
    for i in 0..las.points.len() {
        let record = start + i * las.record_length as usize;
        for (k, c) in rgb(i).into_iter().enumerate() {
            bytes[record + at + 2 * k..record + at + 2 * k + 2].copy_from_slice(&c.to_le_bytes());
        }
    }
    bytes
}

#[test]
fn colours_are_read_as_bytes_whether_written_with_8_or_16_bits() {
    let sixteen = |i: usize| [[0, 0, 0], [65535, 257 * 128, 256], [0x7F00, 0x80FF, 65280]][i];
    let eight = |i: usize| [[0, 0, 0], [255, 128, 1], [12, 200, 255]][i];
    for (minor, format, length, at) in [(2u8, 2u8, 26u16, 20), (2, 3, 34, 28), (4, 7, 36, 30)] {
        let las = Las::new(minor, format, length);
        let g = parse(&with_colours(&las, at, sixteen)).unwrap();
        assert_eq!(
            g.points.colors,
            Some(vec![[0, 0, 0], [255, 128, 1], [127, 128, 254]]),
            "16-bit, format {format}"
        );
        let g = parse(&with_colours(&las, at, eight)).unwrap();
        assert_eq!(
            g.points.colors,
            Some(vec![[0, 0, 0], [255, 128, 1], [12, 200, 255]])
        );
        // Colour fields a writer zeroed are no colours.
        let g = parse(&with_colours(&las, at, |_| [0; 3])).unwrap();
        assert_eq!(g.points.colors, None, "black, format {format}");
        let laz = laz_twin(&with_colours(&las, at, eight));
        let g = parse(&laz).unwrap();
        assert_eq!(
            g.points.colors,
            Some(vec![[0, 0, 0], [255, 128, 1], [12, 200, 255]])
        );
    }
    for (minor, format, length) in [(2u8, 0u8, 20u16), (2, 1, 28), (4, 6, 30)] {
        let g = parse(&Las::new(minor, format, length).bytes()).unwrap();
        assert_eq!(g.points.colors, None, "format {format} has no colour");
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

/// The LAZ twin of a LAS file: the same header and records, the records compressed by
/// LASzip (the `laz` crate's compressor) behind a `laszip encoded` record.
fn laz_twin(las: &[u8]) -> Vec<u8> {
    use laz::{LasZipCompressor, LazItemRecordBuilder, LazVlr};
    let u16_at = |at: usize| usize::from(u16::from_le_bytes([las[at], las[at + 1]]));
    let u32_at = |at: usize| u32::from_le_bytes(las[at..at + 4].try_into().unwrap());
    let offset = u32_at(96) as usize;
    let format = las[104];
    let record_length = u16_at(105);
    let count = match u32_at(107) {
        // Point formats 6 to 10 leave the legacy count 0 for the 64-bit one of LAS 1.4.
        0 => u64::from_le_bytes(las[247..255].try_into().unwrap()) as usize,
        n => n as usize,
    };
    let base = [20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67][usize::from(format)];
    let items =
        LazItemRecordBuilder::default_for_point_format_id(format, (record_length - base) as u16)
            .unwrap();
    let vlr = LazVlr::from_laz_items(items);
    let mut description = Vec::new();
    vlr.write_to(&mut description).unwrap();
    let mut out = las[..offset].to_vec();
    out.extend([0u8; 2]);
    let mut user_id = [0u8; 16];
    user_id[..LazVlr::USER_ID.len()].copy_from_slice(LazVlr::USER_ID.as_bytes());
    out.extend(user_id);
    out.extend(LazVlr::RECORD_ID.to_le_bytes());
    out.extend((description.len() as u16).to_le_bytes());
    out.extend([0u8; 32]);
    out.extend(&description);
    let points_at = out.len() as u32;
    out[96..100].copy_from_slice(&points_at.to_le_bytes());
    out[100..104].copy_from_slice(&(u32_at(100) + 1).to_le_bytes());
    out[104] = format | 0x80;
    // The compressor writes the chunk table's offset from the start of its stream: the file.
    let mut file = std::io::Cursor::new(out);
    file.set_position(u64::from(points_at));
    let mut compressor = LasZipCompressor::new(file, vlr).unwrap();
    compressor
        .compress_many(&las[offset..offset + count * record_length])
        .unwrap();
    compressor.done().unwrap();
    compressor.into_inner().into_inner()
}

/// LAZ files read exactly as their LAS twins: the bundled urban LiDAR tile (point format 3,
/// 13,511 points) as another writer compressed it (`fixtures/real/urban.laz`, laspy with
/// lazrs), that tile and the files built here as compressed here, through `.laz` paths too.
#[test]
fn laz_reads_identically_to_its_las_twin() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real");
    let las = read_geometry(&fixtures.join("urban.las"), &ReadOptions::default()).unwrap();
    let laz = read_geometry(&fixtures.join("urban.laz"), &ReadOptions::default()).unwrap();
    assert_eq!(laz.points, las.points);
    assert_eq!(laz.points.len(), 13_511);
    assert_eq!(laz.info.variant, "LAZ 1.2, point format 3");
    assert_eq!(laz.info.elements, las.info.elements);

    let urban =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/urban.las"))
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (name, las) in [
        ("urban", urban),
        ("v12f0", Las::new(2, 0, 20).bytes()),
        ("v12f3extra", Las::new(2, 3, 40).bytes()),
        ("v14f6", Las::new(4, 6, 30).bytes()),
    ] {
        let laz = laz_twin(&las);
        assert!(
            laz.len() < las.len() || las.len() < 2000,
            "{name}: {} vs {}",
            laz.len(),
            las.len()
        );
        let plain = parse_geometry(
            &las,
            Format::Las,
            Path::new("a.las"),
            &ReadOptions::default(),
        )
        .unwrap();
        let path = dir.path().join(format!("{name}.laz"));
        std::fs::write(&path, &laz).unwrap();
        let compressed = read_geometry(&path, &ReadOptions::default()).unwrap();
        assert_eq!(compressed.points, plain.points, "{name}");
        assert!(
            compressed.info.variant.starts_with("LAZ 1."),
            "{}",
            compressed.info.variant
        );
        assert_eq!(compressed.info.elements, plain.info.elements, "{name}");
    }
}

/// A LAZ header declaring more points than the limit allows is refused before anything is
/// decompressed; compressed data that is cut or lacks its LASzip record is malformed.
#[test]
fn laz_counts_are_checked_and_broken_compression_is_refused() {
    let las = Las::new(2, 3, 34).bytes();
    let laz = laz_twin(&las);
    let limited = ReadOptions {
        max_bytes: Some(100),
        ..ReadOptions::default()
    };
    match parse_geometry(&laz, Format::Las, Path::new("a.laz"), &limited) {
        Err(IoError::OverMemoryLimit { declared, .. }) => {
            assert_eq!(declared, "3 compressed records of 34 bytes")
        }
        other => panic!("{other:?}"),
    }
    let mut lying = laz.clone();
    lying[107..111].copy_from_slice(&4_000_000_000u32.to_le_bytes());
    assert!(matches!(
        parse_geometry(&lying, Format::Las, Path::new("a.laz"), &limited),
        Err(IoError::OverMemoryLimit { .. })
    ));
    // Without a limit, a count the compressed data does not hold fails where the data
    // ends, having allocated only what was there.
    let (_, problem) = malformed(&lying);
    assert!(
        problem.to_string().contains("compressed point data"),
        "{problem}"
    );
    let cut = &laz[..laz.len() - 10];
    let (_, problem) = malformed(cut);
    assert!(
        problem.to_string().contains("chunk table offset"),
        "{problem}"
    );
    // A chunk table declaring billions of chunks is refused before `laz` allocates them.
    let mut swollen = laz.clone();
    let data_at = u32::from_le_bytes(laz[96..100].try_into().unwrap()) as usize;
    let table_at = i64::from_le_bytes(laz[data_at..data_at + 8].try_into().unwrap()) as usize;
    swollen[table_at + 4..table_at + 8].copy_from_slice(&u32::MAX.to_le_bytes());
    let (_, problem) = malformed(&swollen);
    assert!(
        problem.to_string().contains("declares 4294967295 chunks"),
        "{problem}"
    );
    // The compression bit without the record that describes it.
    let mut bare = las.clone();
    bare[104] |= 0x80;
    let (at, problem) = malformed(&bare);
    assert_eq!(at, Location::Byte(227));
    assert!(
        problem.to_string().contains("no `laszip encoded` record"),
        "{problem}"
    );
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
