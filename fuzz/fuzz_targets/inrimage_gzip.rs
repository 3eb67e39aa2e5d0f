//! The INRIMAGE-4 reader on gzip files whose decompressed content the fuzzer writes
//! ([`sphcover_fuzz::gzip_input`]): headers over streams that really inflate to what they
//! declare, up to twice the memory limit, or past it.

#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let file = sphcover_fuzz::gzip_input(bytes);
    let _ = sphcover_core::io::parse_inrimage(
        &file,
        Path::new("fuzz.inr.gz"),
        &sphcover_fuzz::volume_options(),
    );
});
