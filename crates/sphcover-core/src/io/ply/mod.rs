//! PLY (Stanford polygon file): ascii and binary, read and write.

pub(crate) mod header;
mod read;
mod write;

pub(crate) use read::{decode_vertex_block, read, read_element_columns};
pub(crate) use write::write;
