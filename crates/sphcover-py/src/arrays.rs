//! NumPy arrays to and from the libraries' vectors.
//!
//! Outputs never copy: a `Vec<DVec3>` becomes the `f64` buffer of an `(n, 3)` array that
//! NumPy then owns (mapped in place to `[f64; 3]` rows, which have the size and alignment of
//! `DVec3`, then flattened), and a `Vec<[u32; 3]>` likewise an `(m, 3)` `uint32` array. Inputs are borrowed as
//! slices while the interpreter is held; work that runs with the interpreter released takes
//! one copy of them, because a borrow of a NumPy buffer cannot outlive the lock.

use ndarray::{Array1, Array2};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use sphcover_core::DVec3;

/// An `(n, 3)` float64 array of the points `v`, without copying them.
pub fn points_to_py(py: Python<'_>, v: Vec<DVec3>) -> Bound<'_, PyArray2<f64>> {
    // Collected in place: the standard library reuses the allocation when the items keep
    // their size and alignment.
    let rows: Vec<[f64; 3]> = v.into_iter().map(|p| p.to_array()).collect();
    rows_to_py(py, rows)
}

/// An `(m, K)` array of the rows `v` (triangles, tetrahedra, points), without copying them.
pub fn rows_to_py<T: numpy::Element, const K: usize>(
    py: Python<'_>,
    v: Vec<[T; K]>,
) -> Bound<'_, PyArray2<T>> {
    let m = v.len();
    Array2::from_shape_vec((m, K), v.into_flattened())
        .expect("m rows of K values have that shape")
        .into_pyarray(py)
}

/// A one-dimensional array of `v`, without copying it.
pub fn vec_to_py<T: numpy::Element>(py: Python<'_>, v: Vec<T>) -> Bound<'_, PyArray1<T>> {
    Array1::from_vec(v).into_pyarray(py)
}

/// The rows of an `(n, 3)` array as points; `name` names the argument in the error.
pub fn points_from_py(a: &PyReadonlyArray2<'_, f64>, name: &str) -> PyResult<Vec<DVec3>> {
    let shape = a.shape();
    if shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (n, 3), not ({}, {})",
            shape[0], shape[1]
        )));
    }
    Ok(match a.as_slice() {
        Ok(flat) => flat.chunks_exact(3).map(DVec3::from_slice).collect(),
        Err(_) => a
            .as_array()
            .rows()
            .into_iter()
            .map(|r| DVec3::new(r[0], r[1], r[2]))
            .collect(),
    })
}

/// The rows of an `(m, 3)` array (triangles' vertex indices, colours) as triples.
pub fn rows_from_py<T: numpy::Element + Copy>(
    a: &PyReadonlyArray2<'_, T>,
    name: &str,
) -> PyResult<Vec<[T; 3]>> {
    let shape = a.shape();
    if shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (m, 3), not ({}, {})",
            shape[0], shape[1]
        )));
    }
    Ok(a.as_array()
        .rows()
        .into_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect())
}

/// An `(n, 3)` uint8 array of red, green, blue as colours of `n` points.
pub fn colors_from_py(a: &PyReadonlyArray2<'_, u8>, n: usize) -> PyResult<Vec<[u8; 3]>> {
    let colors = rows_from_py(a, "colors")?;
    if colors.len() != n {
        return Err(PyValueError::new_err(format!(
            "colors has {} rows for {n} points",
            colors.len()
        )));
    }
    Ok(colors)
}

/// A one-dimensional array as a vector of `expected` entries (when given).
pub fn values_from_py(
    a: &PyReadonlyArray1<'_, f64>,
    name: &str,
    expected: Option<usize>,
) -> PyResult<Vec<f64>> {
    let v = a.as_array().to_vec();
    if let Some(n) = expected
        && v.len() != n
    {
        return Err(PyValueError::new_err(format!(
            "{name} has {} entries for {n} points",
            v.len()
        )));
    }
    Ok(v)
}
