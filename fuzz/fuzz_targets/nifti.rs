//! The NIfTI-1/2 reader, plain and gzip (recognised by content), on arbitrary bytes.

#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let _ = sphcover_core::io::parse_nifti(
        bytes,
        Path::new("fuzz.nii"),
        &sphcover_fuzz::volume_options(),
    );
});
