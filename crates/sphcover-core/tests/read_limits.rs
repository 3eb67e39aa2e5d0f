//! The readers' memory limit (`ReadOptions::max_bytes`) and their refusal of declared sizes
//! a file cannot hold, on files made here: decompression bombs (a small `.nii.gz` or
//! `.inr.gz` whose header declares gigabytes over a gzip stream of zeros that really inflates
//! to them), gzip streams that go on past the declared data, and point and mesh files
//! declaring more records than the limit allows or than their size holds, and text files
//! whose records pass it.
#![cfg(feature = "nifti")]

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use sphcover_core::io::{
    Format, IoError, Location, Problem, ReadOptions, VolumeInfo, parse_geometry, read_volume,
    read_volume_info,
};
use sphcover_core::synthetic::{gzip_with_zeros, inrimage_header, nifti_header};

const MIB: u64 = 1 << 20;

fn limited(bytes: u64) -> ReadOptions {
    ReadOptions {
        max_bytes: Some(bytes),
        ..ReadOptions::default()
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// A refusal over the limit: its declared text, bytes and limit.
fn over_limit(result: Result<impl std::fmt::Debug, IoError>) -> (String, u64, u64, String) {
    match result {
        Err(e) => {
            assert!(e.is_bad_input(), "{e}");
            let message = e.to_string();
            match e {
                IoError::OverMemoryLimit {
                    declared,
                    bytes,
                    limit,
                    ..
                } => (declared, bytes, limit, message),
                other => panic!("expected OverMemoryLimit, got {other}"),
            }
        }
        Ok(value) => panic!("expected OverMemoryLimit, got {value:?}"),
    }
}

/// `bytes` of `format` read within a limit of exactly `need` bytes, then refused one byte
/// below it: the refusal's declared text, bytes, limit and message.
fn needs_exactly(bytes: &[u8], format: Format, need: u64) -> (String, u64, u64, String) {
    let path = Path::new("a").with_extension(format!("{format:?}").to_lowercase());
    parse_geometry(bytes, format, &path, &limited(need)).unwrap();
    over_limit(parse_geometry(bytes, format, &path, &limited(need - 1)))
}

#[test]
fn the_zero_bomb_inflates_to_what_it_declares_at_about_a_thousand_to_one() {
    let head = b"head bytes".to_vec();
    let file = gzip_with_zeros(&head, 64);
    let mut decoded = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&file[..]), &mut decoded)
        .expect("a valid gzip member: CRC and size check");
    assert_eq!(decoded.len() as u64, head.len() as u64 + 64 * MIB);
    assert_eq!(&decoded[..head.len()], &head[..]);
    assert!(decoded[head.len()..].iter().all(|&b| b == 0));
    // Close to the 1032:1 bound of DEFLATE, as `gzip -9` makes zeros.
    let ratio = decoded.len() as f64 / file.len() as f64;
    assert!(ratio > 1000.0, "{ratio}");
}

#[test]
fn a_nifti_bomb_is_refused_from_its_header_with_the_sizes_and_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    // 1024³ int16: 2 GiB decoded in a 2 MB file; 4 GiB as float32 values.
    let file = gzip_with_zeros(&nifti_header([1024, 1024, 1024], 4, 16), 2048);
    assert!(file.len() < 2_200_000, "{}", file.len());
    let path = write(dir.path(), "bomb.nii.gz", &file);
    let start = Instant::now();
    let (declared, bytes, limit, message) = over_limit(read_volume(&path, &limited(64 * MIB)));
    assert_eq!(
        declared,
        "1024 x 1024 x 1024 voxels of int16 (2.0 GiB decoded, held as float32)"
    );
    assert_eq!(bytes, 4 << 30);
    assert_eq!(limit, 64 * MIB);
    assert_eq!(
        message,
        format!(
            "{}: declares 1024 x 1024 x 1024 voxels of int16 (2.0 GiB decoded, held as float32): 4.0 GiB in memory, above the memory limit 64.0 MiB",
            path.display()
        )
    );
    // Only the header was inflated: inflating 2 GiB takes seconds.
    assert!(
        start.elapsed() < Duration::from_secs(1),
        "{:?}",
        start.elapsed()
    );

    // The header alone reads, whatever the limit.
    let info = read_volume_info(&path).unwrap();
    assert_eq!(info.dims(), [1024, 1024, 1024]);
    assert!(matches!(info, VolumeInfo::Nifti(ref n) if n.gzip));
}

#[test]
fn an_inrimage_bomb_is_refused_from_its_header() {
    let dir = tempfile::tempdir().unwrap();
    let file = gzip_with_zeros(&inrimage_header([1024, 1024, 1024]), 2048);
    let path = write(dir.path(), "bomb.inr.gz", &file);
    let (declared, bytes, _, message) = over_limit(read_volume(&path, &limited(64 * MIB)));
    assert_eq!(
        declared,
        "1024 x 1024 x 1024 voxels of int16 (2.0 GiB decoded, held as float32)"
    );
    assert_eq!(bytes, 4 << 30);
    assert!(message.starts_with(&format!("{}: declares", path.display())));
    assert_eq!(read_volume_info(&path).unwrap().dims(), [1024, 1024, 1024]);
}

#[test]
fn the_limit_counts_the_values_in_memory_and_is_inclusive() {
    let dir = tempfile::tempdir().unwrap();
    // 64³ uint8, stored as float32: 1 MiB of values from 256 KiB of data.
    let mut file = nifti_header([64, 64, 64], 2, 8);
    file.extend((0..64 * 64 * 64).map(|i| (i % 251) as u8));
    let plain = write(dir.path(), "small.nii", &file);
    let (whole, _) = read_volume(&plain, &ReadOptions::default()).unwrap();
    let (exact, _) = read_volume(&plain, &limited(MIB)).unwrap();
    assert_eq!(exact, whole);
    let (_, bytes, limit, _) = over_limit(read_volume(&plain, &limited(MIB - 1)));
    assert_eq!((bytes, limit), (MIB, MIB - 1));
}

#[test]
fn a_gzip_stream_that_goes_on_past_the_declared_data_is_refused_one_byte_later() {
    let dir = tempfile::tempdir().unwrap();
    // 64³ uint8 declared (256 KiB) over 1 GiB of zeros; no memory limit.
    let head = nifti_header([64, 64, 64], 2, 8);
    let path = write(dir.path(), "long.nii.gz", &gzip_with_zeros(&head, 1024));
    let start = Instant::now();
    match read_volume(&path, &ReadOptions::default()) {
        Err(IoError::Malformed { at, problem, .. }) => {
            assert_eq!(at, Location::Byte(352 + 64 * 64 * 64));
            assert!(problem.to_string().contains("goes on after"), "{problem}");
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
    // Not inflated to its end (a gigabyte takes seconds).
    assert!(
        start.elapsed() < Duration::from_secs(1),
        "{:?}",
        start.elapsed()
    );

    // INRIMAGE alike; the same data without the excess reads.
    // 64 x 64 x 128 int16: 1 MiB of data, 2 MiB of float32 values.
    let head = inrimage_header([64, 64, 128]);
    let path = write(dir.path(), "long.inr.gz", &gzip_with_zeros(&head, 2));
    match read_volume(&path, &ReadOptions::default()) {
        Err(IoError::Malformed { at, .. }) => assert_eq!(at, Location::Byte(256 + MIB)),
        other => panic!("expected a refusal, got {other:?}"),
    }
    let path = write(dir.path(), "exact.inr.gz", &gzip_with_zeros(&head, 1));
    let (volume, _) = read_volume(&path, &limited(2 * MIB)).unwrap();
    assert_eq!(volume.dims(), [64, 64, 128]);
    assert_eq!(volume.value_range(), Some((0.0, 0.0)));
}

#[test]
fn a_gzip_header_declaring_more_than_deflate_can_hold_is_malformed_not_over_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    // 1024³ int16 over 1 MiB of zeros: 2 GiB cannot come out of a 1 KB file.
    let path = write(
        dir.path(),
        "liar.nii.gz",
        &gzip_with_zeros(&nifti_header([1024, 1024, 1024], 4, 16), 1),
    );
    for options in [ReadOptions::default(), limited(64 * MIB)] {
        let err = read_volume(&path, &options).unwrap_err();
        assert!(matches!(err, IoError::Malformed { .. }), "{err}");
        assert!(err.to_string().contains("gzip file can hold"), "{err}");
    }
}

/// A binary little-endian PLY of `n` float vertices and, when `faces`, `n / 3` triangles.
fn ply(n: usize, faces: bool) -> Vec<u8> {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\n{}end_header\n",
        if faces {
            format!(
                "element face {}\nproperty list uchar int vertex_indices\n",
                n / 3
            )
        } else {
            String::new()
        }
    )
    .into_bytes();
    for i in 0..n {
        for c in [i as f32, 0.5, -1.0] {
            bytes.extend(c.to_le_bytes());
        }
    }
    if faces {
        for f in 0..n / 3 {
            bytes.push(3);
            for v in 0..3 {
                bytes.extend(((3 * f + v) as i32).to_le_bytes());
            }
        }
    }
    bytes
}

#[test]
fn ply_counts_times_record_sizes_are_checked_against_the_limit() {
    let path = Path::new("big.ply");
    let n = 30_000;
    // Positions in f64: 24 bytes a vertex (fixed-size records need no per-vertex origin).
    let points = ply(n, false);
    parse_geometry(&points, Format::Ply, path, &limited(24 * n as u64)).unwrap();
    let (declared, bytes, _, message) = over_limit(parse_geometry(
        &points,
        Format::Ply,
        path,
        &limited(24 * n as u64 - 1),
    ));
    assert_eq!(declared, "30000 vertices");
    assert_eq!(bytes, 24 * n as u64);
    assert!(message.starts_with("big.ply: declares 30000 vertices: 703.1 KiB in memory"));
    // Faces count on top of the vertices: 12 bytes a triangle.
    let mesh = ply(n, true);
    let need = 24 * n as u64 + 12 * (n / 3) as u64;
    let g = parse_geometry(&mesh, Format::Ply, path, &limited(need)).unwrap();
    assert_eq!(g.triangles.len(), n / 3);
    let (declared, bytes, _, _) =
        over_limit(parse_geometry(&mesh, Format::Ply, path, &limited(need - 1)));
    assert_eq!(declared, "30000 vertices and 10000 faces");
    assert_eq!(bytes, need);
}

#[test]
fn a_count_the_file_cannot_hold_is_refused_as_truncated_before_the_limit() {
    // 4e9 vertices declared over 3: truncated, whatever the limit.
    let mut bytes = ply(3, false);
    let text = String::from_utf8_lossy(&bytes).replace("vertex 3", "vertex 4000000000");
    let end = text.find("end_header\n").unwrap() + "end_header\n".len();
    let mut file = text.as_bytes()[..end].to_vec();
    file.extend(bytes.split_off(bytes.len() - 36));
    for options in [ReadOptions::default(), limited(1024)] {
        let err = parse_geometry(&file, Format::Ply, Path::new("lie.ply"), &options).unwrap_err();
        assert!(
            matches!(
                err,
                IoError::Malformed {
                    problem: Problem::Truncated { .. },
                    ..
                }
            ),
            "{err}"
        );
    }
    // LAS: a point count beyond the records present.
    let las = las_file(10, 4_000_000_000);
    let err = parse_geometry(&las, Format::Las, Path::new("lie.las"), &limited(1024)).unwrap_err();
    assert!(
        matches!(
            err,
            IoError::Malformed {
                problem: Problem::Truncated { .. },
                ..
            }
        ),
        "{err}"
    );
}

/// A LAS 1.2 file, point format 0 (20-byte records), holding `records` points and declaring
/// `declared`.
fn las_file(records: u32, declared: u32) -> Vec<u8> {
    let mut h = vec![0u8; 227];
    h[0..4].copy_from_slice(b"LASF");
    h[24] = 1;
    h[25] = 2;
    h[94..96].copy_from_slice(&227u16.to_le_bytes());
    h[96..100].copy_from_slice(&227u32.to_le_bytes());
    h[105..107].copy_from_slice(&20u16.to_le_bytes());
    h[107..111].copy_from_slice(&declared.to_le_bytes());
    for axis in 0..3 {
        h[131 + 8 * axis..139 + 8 * axis].copy_from_slice(&0.01f64.to_le_bytes());
    }
    for i in 0..records {
        let mut r = [0u8; 20];
        r[0..4].copy_from_slice(&(i as i32).to_le_bytes());
        h.extend(r);
    }
    h
}

#[test]
fn las_stl_and_off_counts_are_checked_against_the_limit() {
    // LAS: 32 bytes a point (position and intensity).
    let las = las_file(1000, 1000);
    let (declared, bytes, _, _) = needs_exactly(&las, Format::Las, 32_000);
    assert_eq!((declared.as_str(), bytes), ("1000 points", 32_000));

    // Binary STL: 44 bytes a triangle (the triangle and half a merged vertex).
    let n = 1000u32;
    let mut stl = vec![0u8; 80];
    stl.extend(n.to_le_bytes());
    for t in 0..n {
        stl.extend([0u8; 12]);
        for c in 0..9 {
            stl.extend(((t * 9 + c) as f32).to_le_bytes());
        }
        stl.extend([0u8; 2]);
    }
    let (declared, _, _, _) = needs_exactly(&stl, Format::Stl, 44_000);
    assert_eq!(declared, "1000 triangles");

    // OFF: position and line number, 32 bytes a vertex; 12 a face.
    let mut off = String::from("OFF\n300 100 0\n");
    for i in 0..300 {
        off.push_str(&format!("{i} 0 1\n"));
    }
    for f in 0..100 {
        off.push_str(&format!("3 {} {} {}\n", 3 * f, 3 * f + 1, 3 * f + 2));
    }
    let need = 300 * 32 + 100 * 12;
    let (declared, _, _, _) = needs_exactly(off.as_bytes(), Format::Off, need);
    assert_eq!(declared, "300 vertices and 100 faces");
}

/// XYZ and OBJ declare no count: what their records take is counted as they are read, twice
/// over for the arrays' room to grow, and the read stops at the record that passes the limit.
#[test]
fn text_records_are_counted_against_the_limit_as_they_are_read() {
    // XYZ with normals: position, normal and line number, 56 bytes a point.
    let mut xyz = String::new();
    for i in 0..1000 {
        xyz.push_str(&format!("{i} 0 1 0 0 1\n"));
    }
    let need = 2 * 1000 * 56;
    let whole = parse_geometry(
        xyz.as_bytes(),
        Format::Xyz,
        Path::new("a.xyz"),
        &limited(need),
    )
    .unwrap();
    assert_eq!(whole.points.len(), 1000);
    let (declared, bytes, limit, message) = needs_exactly(xyz.as_bytes(), Format::Xyz, need);
    assert_eq!(
        declared,
        "1000 points by line 1000 (text, with room for its arrays to grow)"
    );
    assert_eq!((bytes, limit), (need, need - 1));
    assert!(
        message.starts_with("a.xyz: declares 1000 points by line 1000"),
        "{message}"
    );

    // OBJ: 36 bytes a vertex, 12 a triangle of its faces (a quad is two).
    let mut obj = String::new();
    for i in 0..400 {
        obj.push_str(&format!("v {i} 0 1\n"));
    }
    for f in 0..100 {
        obj.push_str(&format!(
            "f {} {} {} {}\n",
            4 * f + 1,
            4 * f + 2,
            4 * f + 3,
            4 * f + 4
        ));
    }
    let need = 2 * (400 * 36 + 100 * 2 * 12);
    let (declared, _, _, _) = needs_exactly(obj.as_bytes(), Format::Obj, need);
    assert_eq!(
        declared,
        "400 vertices and 100 faces by line 500 (text, with room for its arrays to grow)"
    );
}

#[test]
fn without_a_limit_nothing_changes() {
    for bytes in [ply(3000, true), ply(10, false)] {
        let a = parse_geometry(
            &bytes,
            Format::Ply,
            Path::new("a.ply"),
            &ReadOptions::default(),
        )
        .unwrap();
        let b =
            parse_geometry(&bytes, Format::Ply, Path::new("a.ply"), &limited(u64::MAX)).unwrap();
        assert_eq!(a, b);
    }
}
