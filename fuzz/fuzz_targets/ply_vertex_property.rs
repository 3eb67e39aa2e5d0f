//! The PLY reader that also extracts one scalar vertex property (`render --color-by`).

#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use sphcover_core::io::{ReadOptions, parse_ply_with_vertex_property};

fuzz_target!(|bytes: &[u8]| {
    for property in ["confidence", "x", "quality"] {
        if let Ok((g, values)) = parse_ply_with_vertex_property(
            bytes,
            Path::new("fuzz.ply"),
            property,
            &ReadOptions::default(),
        ) {
            sphcover_fuzz::check_geometry(&g);
            if let Some(values) = values {
                assert_eq!(values.len(), g.points.positions.len());
            }
        }
    }
});
