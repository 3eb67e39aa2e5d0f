//! Inputs found by the fuzz targets in `fuzz/` that once made a reader panic, rebuilt here
//! from their essential bytes so that CI (which has no fuzzer) keeps checking them. Each
//! reader must refuse them with a typed error.

use std::path::Path;

use sphcover_core::io::{self, Format, IoError, Location, ReadOptions};

/// A LAS 1.2 public header block (227 bytes) with point format 0 (20-byte records), unit
/// scales and zero offsets, declaring `count` points that start at byte `point_offset`.
fn las_header(count: u32, point_offset: u32) -> Vec<u8> {
    let mut h = vec![0u8; 227];
    h[0..4].copy_from_slice(b"LASF");
    h[24] = 1; // version 1.2
    h[25] = 2;
    h[94..96].copy_from_slice(&227u16.to_le_bytes()); // header size
    h[96..100].copy_from_slice(&point_offset.to_le_bytes());
    h[104] = 0; // point data record format
    h[105..107].copy_from_slice(&20u16.to_le_bytes()); // record length
    h[107..111].copy_from_slice(&count.to_le_bytes());
    for axis in 0..3 {
        let at = 131 + 8 * axis;
        h[at..at + 8].copy_from_slice(&1.0f64.to_le_bytes());
    }
    h
}

#[test]
fn las_with_a_point_offset_in_range_and_no_points_reads_as_empty() {
    // The control case of the regression below: the same header with the point data
    // starting right after it.
    let bytes = las_header(0, 227);
    let result = io::parse_geometry(
        &bytes,
        Format::Las,
        Path::new("empty.las"),
        &ReadOptions::default(),
    );
    let g = result.expect("a LAS file may hold no points");
    assert!(g.points.positions.is_empty());
}

#[test]
fn las_with_no_points_and_a_point_offset_past_the_end_is_refused() {
    let bytes = las_header(0, 58_147);
    let result = io::parse_geometry(
        &bytes,
        Format::Las,
        Path::new("bad.las"),
        &ReadOptions::default(),
    );
    assert!(
        result.is_err(),
        "the point data would start past the end of the file"
    );
}

/// The input of the first `nifti_gzip` run's only report (`fuzz/README.md`): a NIfTI-1
/// header with no magic, in a gzip stream whose trailer is cut off, read under the targets'
/// 64 MiB limit. The report was an RSS limit reached by AddressSanitizer's quarantine of
/// freed memory (live heap 27 MB), not by this input, which alone runs in 38 ms; kept so
/// that CI reads it as the fuzzer did: refused at the header, before any voxel.
#[cfg(feature = "nifti")]
#[test]
fn nifti_gzip_without_a_trailer_and_without_a_magic_is_refused_at_the_header() {
    let mut content = vec![0u8; 1331];
    content[0..4].copy_from_slice(&348i32.to_le_bytes());
    content[40..42].copy_from_slice(&3i16.to_le_bytes());
    let mut file = sphcover_core::synthetic::gzip_with_zeros(&content, 0);
    file.truncate(file.len() - 8);
    let options = ReadOptions {
        max_bytes: Some(64 << 20),
        ..ReadOptions::default()
    };
    match io::parse_nifti(&file, Path::new("fuzz.nii.gz"), &options) {
        Err(IoError::Malformed { at, problem, .. }) => {
            assert_eq!(at, Location::Byte(344));
            assert!(problem.to_string().contains("magic"), "{problem}");
        }
        other => panic!("expected a refusal of the header, got {other:?}"),
    }
}
