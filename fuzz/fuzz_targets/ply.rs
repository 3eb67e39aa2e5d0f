//! The Ply reader on arbitrary bytes.

#![no_main]

use libfuzzer_sys::fuzz_target;
use sphcover_core::io::Format;

fuzz_target!(|bytes: &[u8]| {
    sphcover_fuzz::parse_geometry_all_policies(bytes, Format::Ply);
});
