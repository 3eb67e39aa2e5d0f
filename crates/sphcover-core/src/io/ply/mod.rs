//! PLY (Stanford polygon file): ascii and binary, read and write.

pub(crate) mod header;
mod read;
mod write;

pub(crate) use read::{read, read_element_columns};
pub(crate) use write::write;
