//! PLY (Stanford polygon file): ascii and binary, read and write.

mod header;
mod read;
mod write;

pub(crate) use read::read;
pub(crate) use write::write;
