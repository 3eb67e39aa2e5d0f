//! The native half of the `sphcover` Python package (`sphcover._sphcover`): NumPy arrays in
//! and out of the sphcover libraries. The pure-Python half (`python/sphcover`) wraps these
//! functions with keyword signatures, result classes, conversions to Open3D and trimesh, and
//! progress bars; `docs/python.md` is the user's guide.
//!
//! Every long call runs with the interpreter released on a thread of its own, and Ctrl-C ends
//! it within a twentieth of a second (module `run`). Errors are [`BadInputError`] and
//! [`SphcoverError`] with the libraries' messages (module `errors`).
#![deny(missing_docs)]
// PyO3's macros expand to `unsafe` FFI glue (the module's init function, argument
// extraction); the code of this crate itself has no `unsafe` block.
#![allow(unsafe_code)]

mod arrays;
mod cover;
mod errors;
mod files;
mod memory;
mod operators;
mod reconstruction;
mod run;
mod skeleton;
mod triangulation;

use pyo3::prelude::*;

pub use errors::{BadInputError, SphcoverError};

/// The module `sphcover._sphcover`.
#[pymodule]
#[pyo3(name = "_sphcover")]
fn sphcover_native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("BadInputError", py.get_type::<BadInputError>())?;
    m.add("SphcoverError", py.get_type::<SphcoverError>())?;
    m.add_class::<cover::Cover>()?;
    m.add_class::<triangulation::DualComplex>()?;
    m.add_function(wrap_pyfunction!(files::read, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_geometry, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruction::reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruction::reconstruct_file, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruction::tile_function_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruction::streamed_tile_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(skeleton::skeleton_volume, m)?)?;
    m.add_function(wrap_pyfunction!(skeleton::skeleton_samples, m)?)?;
    m.add_function(wrap_pyfunction!(cover::surface_cover, m)?)?;
    m.add_function(wrap_pyfunction!(cover::volume_cover, m)?)?;
    m.add_function(wrap_pyfunction!(cover::scattered_cover, m)?)?;
    m.add_function(wrap_pyfunction!(operators::operator_matrices, m)?)?;
    m.add_function(wrap_pyfunction!(triangulation::regular_triangulation, m)?)?;
    m.add_function(wrap_pyfunction!(triangulation::dual_complex, m)?)?;
    m.add_function(wrap_pyfunction!(keep_freed_memory, m)?)?;
    Ok(())
}

/// Keeps freed memory in the process for reuse, as `sphcover recon` does: glibc's mmap
/// threshold to 32 MiB and its trim threshold to 1 GiB, so each stage of a reconstruction
/// reuses the pages earlier ones freed instead of faulting them in afresh. Faster, with a
/// slightly higher peak resident set; the setting is the whole process's, hence opt-in.
/// A no-op where the C library is not glibc.
#[pyfunction]
fn keep_freed_memory() {
    sphcover_recon::keep_freed_memory();
}
