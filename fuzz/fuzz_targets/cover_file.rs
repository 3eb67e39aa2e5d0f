//! The cover-file reader (a PLY of supports and local-function coefficients) on arbitrary
//! bytes.

#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    if let Ok((cover, _meta)) = sphcover_core::io::parse_cover(bytes, Path::new("fuzz.ply")) {
        // An accepted cover is consistent: one centre, radius and local function per support.
        assert_eq!(cover.centres().len(), cover.len());
        assert_eq!(cover.radii().len(), cover.len());
        for i in 0..cover.len() {
            assert!(cover.func(i).is_some());
        }
    }
});
