//! What the fuzz targets share: every reader must return `Ok` or a typed error for any bytes,
//! never panic, hang or allocate without bound.

use std::path::Path;

use sphcover_core::io::{self, Format, NonFinitePolicy, ReadOptions};

/// The memory limit of the volume targets: a volume within it is read, one above it must
/// be refused from its header, so a finding over `-rss_limit_mb` (512 in the runs of
/// `README.md`) means the limit was not honoured.
pub const VOLUME_LIMIT: u64 = 64 << 20;

/// Reader options of the volume targets: [`VOLUME_LIMIT`].
pub fn volume_options() -> ReadOptions {
    ReadOptions {
        max_bytes: Some(VOLUME_LIMIT),
        ..ReadOptions::default()
    }
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
