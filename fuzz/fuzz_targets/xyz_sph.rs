//! The column readers (`.xyz`, `.pwn`, `.txt`, and sphere sets `.sph`) on arbitrary bytes;
//! the first byte chooses the format so that one corpus serves all four.

#![no_main]

use libfuzzer_sys::fuzz_target;
use sphcover_core::io::Format;

fuzz_target!(|bytes: &[u8]| {
    let Some((&choice, rest)) = bytes.split_first() else {
        return;
    };
    let format = match choice % 4 {
        0 => Format::Xyz,
        1 => Format::Pwn,
        2 => Format::Txt,
        _ => Format::Sph,
    };
    sphcover_fuzz::parse_geometry_all_policies(rest, format);
});
