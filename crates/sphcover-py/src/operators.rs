//! The discrete differential operators of a set of balls (thesis §4) as compressed sparse
//! rows, which the Python side hands to `scipy.sparse.csr_matrix`.

use numpy::{PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sphcover_core::SphereIntersectionGraph;
use sphcover_ops::{
    CsrMatrix, FluxKind, MassKind, OperatorMatrices, PairGeometry, QuadraticFitOperators,
    ThesisOperators,
};

use crate::arrays::{points_from_py, values_from_py, vec_to_py};
use crate::errors::bad_input;
use crate::run::run;

/// `Grad` (`3n × n`), `Div` (`n × 3n`) and `Lap` (`n × n`) of the balls, vector fields
/// interleaved (`(n, 3)` arrays flattened row by row). `variant` `"thesis"` is the thesis'
/// form with `mass` `"thesis"` or `"moment"` and `flux` `"neighbour"` or `"central"`;
/// `"consistent"` is the second-order least-squares family (exact on quadratics). The
/// neighbours are the sphere intersection graph with radii times `shrink`.
#[pyfunction]
#[pyo3(signature = (centres, radii, *, variant = "thesis", mass = "thesis", flux = "neighbour", shrink = 1.0))]
pub fn operator_matrices<'py>(
    py: Python<'py>,
    centres: PyReadonlyArray2<'py, f64>,
    radii: PyReadonlyArray1<'py, f64>,
    variant: &str,
    mass: &str,
    flux: &str,
    shrink: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let centres = points_from_py(&centres, "centres")?;
    let radii = values_from_py(&radii, "radii", Some(centres.len()))?;
    let mass = match mass {
        "thesis" => MassKind::Thesis,
        "moment" => MassKind::MomentMatched,
        other => {
            return Err(bad_input(format!(
                "mass {other:?} is not one of 'thesis', 'moment'"
            )));
        }
    };
    let flux = match flux {
        "neighbour" | "neighbor" => FluxKind::Neighbour,
        "central" => FluxKind::Central,
        other => {
            return Err(bad_input(format!(
                "flux {other:?} is not one of 'neighbour', 'central'"
            )));
        }
    };
    let consistent = match variant {
        "thesis" => false,
        "consistent" => true,
        other => {
            return Err(bad_input(format!(
                "variant {other:?} is not one of 'thesis', 'consistent'"
            )));
        }
    };
    let matrices = run(py, None, None, move |_| {
        let graph = SphereIntersectionGraph::build(&centres, &radii, shrink)
            .map_err(|e| bad_input(e.to_string()))?;
        let geometry =
            PairGeometry::build(&centres, &radii, &graph).map_err(|e| bad_input(e.to_string()))?;
        Ok(if consistent {
            QuadraticFitOperators::new(&geometry).matrices()
        } else {
            ThesisOperators::new(&geometry, mass, flux).matrices()
        })
    })?;
    let OperatorMatrices { grad, div, lap } = matrices;
    let out = PyDict::new(py);
    out.set_item("grad", csr_parts(py, grad)?)?;
    out.set_item("div", csr_parts(py, div)?)?;
    out.set_item("lap", csr_parts(py, lap)?)?;
    Ok(out)
}

/// `(data, indices, indptr, shape)`, the arguments of `scipy.sparse.csr_matrix`.
fn csr_parts(py: Python<'_>, m: CsrMatrix) -> PyResult<Bound<'_, PyAny>> {
    let indptr: Vec<i64> = m.offsets.iter().map(|&o| o as i64).collect();
    let indices: Vec<i64> = m.columns.iter().map(|&c| i64::from(c)).collect();
    let parts = (
        vec_to_py(py, m.values),
        vec_to_py(py, indices),
        vec_to_py(py, indptr),
        (m.rows, m.cols),
    );
    Ok(parts.into_pyobject(py)?.into_any())
}
