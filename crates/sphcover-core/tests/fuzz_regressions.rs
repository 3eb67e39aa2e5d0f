//! Inputs found by the fuzz targets in `fuzz/` that once made a reader panic, rebuilt here
//! from their essential bytes so that CI (which has no fuzzer) keeps checking them. Each
//! reader must refuse them with a typed error.

use std::path::Path;

use sphcover_core::io::{self, Format, ReadOptions};

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
