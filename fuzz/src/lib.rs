//! What the fuzz targets share: every reader must return `Ok` or a typed error for any bytes,
//! never panic, hang or allocate without bound.

use std::path::Path;

use sphcover_core::io::{self, Format, NonFinitePolicy, ReadOptions};

/// The memory limit of the volume targets: a volume within it is read, one above it must
/// be refused from its header, so with `-malloc_limit_mb=80` (the runs of `README.md`) an
/// allocation past it is a finding.
pub const VOLUME_LIMIT: u64 = 64 << 20;

/// Reader options of the volume targets: [`VOLUME_LIMIT`].
pub fn volume_options() -> ReadOptions {
    ReadOptions {
        max_bytes: Some(VOLUME_LIMIT),
        ..ReadOptions::default()
    }
}

/// A gzip file built from a fuzz input, so that the fuzzer mutates the decompressed bytes
/// (mutating compressed bytes mostly breaks the stream before the reader sees anything).
/// Byte 0: bits 0–6 are a count of MiB of zeros appended to the rest of the input before
/// compressing (0 to 127, so headers can declare up to twice [`VOLUME_LIMIT`] in data that
/// is really there; the stream is about 1000:1, as a bomb's); bit 7 cuts the 8-byte gzip
/// trailer off (a stream whose data is complete but whose end is missing). The rest is the
/// file's decompressed content.
pub fn gzip_input(bytes: &[u8]) -> Vec<u8> {
    let Some((&control, content)) = bytes.split_first() else {
        return Vec::new();
    };
    let mut file = sphcover_core::synthetic::gzip_with_zeros(content, u64::from(control & 0x7f));
    if control & 0x80 != 0 {
        file.truncate(file.len() - 8);
    }
    file
}

/// Feeds `bytes` to the geometry reader of `format` under each non-finite policy (they take
/// different paths through the reindexing of triangles).
pub fn parse_geometry_all_policies(bytes: &[u8], format: Format) {
    let path = Path::new("fuzz.input");
    for non_finite in [
        NonFinitePolicy::Refuse,
        NonFinitePolicy::Drop,
        NonFinitePolicy::Keep,
    ] {
        let options = ReadOptions {
            non_finite,
            ..ReadOptions::default()
        };
        if let Ok(g) = io::parse_geometry(bytes, format, path, &options) {
            check_geometry(&g);
        }
    }
}

/// What every successfully read geometry must satisfy: arrays of one length, triangle
/// indices in range.
pub fn check_geometry(g: &io::Geometry) {
    let n = g.points.positions.len();
    if let Some(normals) = &g.points.normals {
        assert_eq!(normals.len(), n);
    }
    if let Some(radii) = &g.radii {
        assert_eq!(radii.len(), n);
    }
    for t in &g.triangles {
        assert!(
            t.iter().all(|&i| (i as usize) < n),
            "triangle {t:?} of {n} vertices"
        );
    }
}
