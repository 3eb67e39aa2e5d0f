//! The regular triangulation of weighted points and the dual complex of a union of balls
//! (thesis §3.5), as `sphcover tetra` builds it.

use std::path::PathBuf;

use numpy::{PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sphcover_core::DVec3;
use sphcover_tetra::{
    DualComplexParams, RegularTriangulation, TetMesh, TriangulationParams, VertexStatus,
    write_tet_mesh,
};

use crate::arrays::{points_from_py, rows_to_py, values_from_py, vec_to_py};
use crate::errors::{bad_input, io_error, tetra_error};
use crate::run::run;

/// The regular (weighted Delaunay) triangulation of the balls, weights `r²`: its finite
/// tetrahedra as `(m, 4)` point indices, and per point whether it is a vertex (`0`), hidden
/// (`1`) or a duplicate of another centre (`2`).
#[pyfunction]
#[pyo3(signature = (centres, radii, *, seed = None))]
pub fn regular_triangulation<'py>(
    py: Python<'py>,
    centres: PyReadonlyArray2<'py, f64>,
    radii: PyReadonlyArray1<'py, f64>,
    seed: Option<u64>,
) -> PyResult<Bound<'py, PyDict>> {
    let centres = points_from_py(&centres, "centres")?;
    let radii = values_from_py(&radii, "radii", Some(centres.len()))?;
    let (tets, status) = run(py, None, None, move |_| {
        let points: Vec<[f64; 3]> = centres.iter().map(|c| c.to_array()).collect();
        let weights: Vec<f64> = radii.iter().map(|r| r * r).collect();
        let params = seed.map_or_else(TriangulationParams::default, |seed| TriangulationParams {
            seed,
            ..Default::default()
        });
        let tri = RegularTriangulation::new(&points, &weights, &params).map_err(tetra_error)?;
        let tets: Vec<[u32; 4]> = tri.finite_tets().map(|t| tri.tet(t)).collect();
        let status: Vec<u8> = tri.vertex_status().iter().map(status_code).collect();
        Ok((tets, status))
    })?;
    let out = PyDict::new(py);
    out.set_item("tets", rows_to_py(py, tets))?;
    out.set_item("status", vec_to_py(py, status))?;
    Ok(out)
}

fn status_code(s: &VertexStatus) -> u8 {
    match s {
        VertexStatus::Vertex => 0,
        VertexStatus::Hidden => 1,
        VertexStatus::Duplicate => 2,
    }
}

/// The dual complex of a union of balls: the tetrahedral mesh of the cover.
#[pyclass(module = "sphcover._sphcover", frozen)]
#[derive(Debug)]
pub struct DualComplex {
    mesh: TetMesh,
    hidden: Vec<bool>,
    centres: Vec<DVec3>,
    radii: Vec<f64>,
}

#[pymethods]
impl DualComplex {
    fn __repr__(&self) -> String {
        format!(
            "DualComplex({} tetrahedra, {} edges, {} hidden balls)",
            self.mesh.tets.len(),
            self.mesh.edges.len(),
            self.hidden.iter().filter(|&&h| h).count()
        )
    }

    /// The tetrahedra, `(m, 4)` ball indices, positively oriented.
    #[getter]
    fn tets<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<u32>> {
        rows_to_py(py, self.mesh.tets.clone())
    }

    /// The edges, `(e, 2)` ball indices.
    #[getter]
    fn edges<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<u32>> {
        rows_to_py(py, self.mesh.edges.clone())
    }

    /// Per ball: `True` when it is no vertex of the complex (hidden or a duplicate centre).
    #[getter]
    fn hidden<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        vec_to_py(py, self.hidden.clone())
    }

    /// The Euler characteristic `V − E + F − T` of the complex.
    #[getter]
    fn euler_characteristic(&self) -> i64 {
        self.mesh.euler_characteristic()
    }

    /// Writes the mesh: `.vtk` (VTK legacy unstructured grid, for ParaView) or `.txt`/`.tets`
    /// (one tetrahedron per line, ascending indices, rows sorted), as `sphcover tetra` does.
    fn write(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| write_tet_mesh(&path, &self.mesh, &self.centres, &self.radii, &[]))
            .map_err(io_error)
    }
}

/// The dual complex of the balls, triangulated with radii times `shrink` (thesis §3.5.2).
#[pyfunction]
#[pyo3(signature = (centres, radii, *, shrink = 0.75, seed = 0))]
pub fn dual_complex(
    py: Python<'_>,
    centres: PyReadonlyArray2<'_, f64>,
    radii: PyReadonlyArray1<'_, f64>,
    shrink: f64,
    seed: u64,
) -> PyResult<DualComplex> {
    if !(shrink.is_finite() && shrink > 0.0) {
        return Err(bad_input(format!(
            "shrink {shrink} must be a positive number"
        )));
    }
    let centres = points_from_py(&centres, "centres")?;
    let radii = values_from_py(&radii, "radii", Some(centres.len()))?;
    run(py, None, None, move |_| {
        let complex =
            sphcover_tetra::dual_complex(&centres, &radii, &DualComplexParams { shrink, seed })
                .map_err(tetra_error)?;
        Ok(DualComplex {
            mesh: TetMesh::from_dual_complex(&complex),
            hidden: complex.hidden(),
            centres,
            radii,
        })
    })
}
