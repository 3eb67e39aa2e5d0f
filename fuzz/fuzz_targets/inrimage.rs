//! The INRIMAGE-4 reader, plain and gzip (recognised by content), on arbitrary bytes.

#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let _ = sphcover_core::io::parse_inrimage(
        bytes,
        Path::new("fuzz.inr"),
        &sphcover_fuzz::volume_options(),
    );
});
