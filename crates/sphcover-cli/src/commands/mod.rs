//! One module per subcommand.

pub mod cover;
pub mod info;
pub mod recon;
pub mod render;
pub mod skeleton;
pub mod tetra;

use std::path::Path;

use sphcover_core::io::{PlyEncoding, WriteOptions};

/// Writer options for outputs made from `input`: ascii or binary little-endian PLY, and
/// `input` guarded against being overwritten.
pub(crate) fn write_options(input: &Path, ascii: bool) -> WriteOptions {
    WriteOptions {
        ply_encoding: if ascii {
            PlyEncoding::Ascii
        } else {
            PlyEncoding::BinaryLittleEndian
        },
        inputs: vec![input.to_path_buf()],
        ..WriteOptions::default()
    }
}
