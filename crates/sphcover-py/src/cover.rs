//! `Cover`: a spherical cover with its unit frame, evaluated at NumPy points; and the covers
//! `sphcover cover` builds: of oriented points, of a voxel volume, of scattered samples with
//! values.

use std::path::PathBuf;

use numpy::{PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use sphcover_core::io::{self, CoverFileMeta};
use sphcover_core::{
    CentreOrder, Cover as CoreCover, Elimination, Normalisation, PointCloud, PuEvaluator,
    SurfaceCoverParams, Threshold, VolumeCoverParams, VolumeCoverVariant, build_scattered_cover,
    build_surface_cover_from_cloud, build_volume_cover,
};

use crate::arrays::{points_from_py, points_to_py, values_from_py, vec_to_py};
use crate::errors::{bad_input, failure, io_error};
use crate::files::write_options;
use crate::run::run;

/// `f` at `m` points, `(m,)`, and its gradient, `(m, 3)`.
type ValuesAndGradients<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray2<f64>>);

/// A spherical cover: balls, each carrying a local function, blended by partition of unity
/// into one implicit function `f` (positive inside, negative outside).
///
/// The supports live in a unit frame (`x_unit = (x − unit_centre) / unit_scale`); `centres`
/// and `radii` are given in the input's coordinates, and `evaluate` takes input coordinates.
#[pyclass(module = "sphcover._sphcover", frozen)]
#[derive(Debug)]
pub struct Cover {
    cover: CoreCover,
    frame: Normalisation,
    expansion: f64,
}

impl Cover {
    /// Wraps a cover in the unit frame `frame` with the default expansion factor `expansion`.
    pub fn new(cover: CoreCover, frame: Normalisation, expansion: f64) -> Cover {
        Cover {
            cover,
            frame,
            expansion,
        }
    }

    /// The centres and radii in input coordinates.
    pub fn balls(&self) -> (Vec<sphcover_core::DVec3>, Vec<f64>) {
        let centres = self
            .cover
            .centres()
            .iter()
            .map(|&c| self.frame.to_input(c))
            .collect();
        let radii = self
            .cover
            .radii()
            .iter()
            .map(|&r| self.frame.length_to_input(r))
            .collect();
        (centres, radii)
    }
}

#[pymethods]
impl Cover {
    /// Number of supports.
    fn __len__(&self) -> usize {
        self.cover.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Cover({} supports, kernel {:?}, expansion {})",
            self.cover.len(),
            self.cover.kernel(),
            self.expansion
        )
    }

    /// The support centres, `(n, 3)`, in input coordinates.
    #[getter]
    fn centres<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_to_py(py, self.balls().0)
    }

    /// The support radii, `(n,)`, in input units.
    #[getter]
    fn radii<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec_to_py(py, self.balls().1)
    }

    /// The centre of the unit frame in input coordinates.
    #[getter]
    fn unit_centre(&self) -> (f64, f64, f64) {
        self.frame.centre.into()
    }

    /// The length in input units of one unit of the unit frame.
    #[getter]
    fn unit_scale(&self) -> f64 {
        self.frame.scale
    }

    /// The default expansion factor σ ≥ 1 of the supports when evaluating.
    #[getter]
    fn expansion(&self) -> f64 {
        self.expansion
    }

    /// `f` and its gradient at the rows of `x` (`(m, 3)`, input coordinates): `f` is in the
    /// unit frame's units, the gradient is with respect to input coordinates. Points that no
    /// support reaches get NaN. `sigma` overrides the expansion factor.
    #[pyo3(signature = (x, sigma = None))]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f64>,
        sigma: Option<f64>,
    ) -> PyResult<ValuesAndGradients<'py>> {
        let mut points = points_from_py(&x, "x")?;
        self.frame.points_to_unit(&mut points);
        let sigma = sigma.unwrap_or(self.expansion);
        let evaluator =
            PuEvaluator::new(&self.cover, sigma).map_err(|e| bad_input(e.to_string()))?;
        let results = py.detach(|| evaluator.values_gradients(&points));
        let scale = self.frame.scale;
        let nan = sphcover_core::DVec3::splat(f64::NAN);
        let values = results
            .iter()
            .map(|r| r.map_or(f64::NAN, |vg| vg.value))
            .collect();
        let gradients = results
            .iter()
            .map(|r| r.map_or(nan, |vg| vg.gradient / scale))
            .collect();
        Ok((vec_to_py(py, values), points_to_py(py, gradients)))
    }

    /// Writes the cover file (PLY: centres, radii, local functions, unit frame), which
    /// `read` and `sphcover tetra` read back.
    #[pyo3(signature = (path, ascii = false, notes = Vec::new()))]
    fn write(
        &self,
        py: Python<'_>,
        path: PathBuf,
        ascii: bool,
        notes: Vec<String>,
    ) -> PyResult<()> {
        let meta = CoverFileMeta {
            normalisation: self.frame,
            expansion: self.expansion,
            notes,
        };
        py.detach(|| io::write_cover(&path, &self.cover, &meta, &write_options(ascii)))
            .map_err(io_error)
    }
}

/// The surface cover of oriented points (thesis §3.4.1), as `sphcover cover` builds it from
/// a point file: supports whose local functions fit the points to `eps` (relative to the
/// longest bounding-box edge); octants whose children cannot be fitted on their own points
/// stay unrefined.
#[pyfunction]
#[pyo3(signature = (points, normals, eps = None, seed = 0))]
pub fn surface_cover(
    py: Python<'_>,
    points: PyReadonlyArray2<'_, f64>,
    normals: PyReadonlyArray2<'_, f64>,
    eps: Option<f64>,
    seed: u64,
) -> PyResult<Cover> {
    if let Some(eps) = eps
        && !(eps.is_finite() && eps > 0.0)
    {
        return Err(bad_input(format!("eps {eps} must be a positive number")));
    }
    let cloud = PointCloud {
        positions: points_from_py(&points, "points")?,
        normals: Some(points_from_py(&normals, "normals")?),
        ..PointCloud::default()
    };
    cloud.check().map_err(bad_input)?;
    let params = SurfaceCoverParams {
        eps: eps.unwrap_or(SurfaceCoverParams::default().eps),
        seed,
        sampling_stop: true,
        ..SurfaceCoverParams::default()
    };
    let (cover, frame, _stats) = run(py, None, None, move |_| {
        build_surface_cover_from_cloud(&cloud, &params).map_err(|e| bad_input(e.to_string()))
    })?;
    if cover.is_empty() {
        return Err(failure("the cover has no support"));
    }
    Ok(Cover::new(cover, frame, 1.0))
}

/// The volume builders' parameters, as `sphcover cover` sets them from its flags.
fn volume_params(
    threshold: Option<f64>,
    eps: Option<f64>,
    linear: bool,
    centre_order: &str,
    elimination: &str,
    seed: u64,
) -> PyResult<VolumeCoverParams> {
    if let Some(eps) = eps
        && !(eps.is_finite() && eps > 0.0)
    {
        return Err(bad_input(format!("eps {eps} must be a positive number")));
    }
    let defaults = VolumeCoverParams::default();
    Ok(VolumeCoverParams {
        threshold: threshold.map_or(defaults.threshold, Threshold::Raw),
        tolerance: eps.unwrap_or(defaults.tolerance),
        variant: if linear {
            VolumeCoverVariant::BoundingBoxLinear
        } else {
            VolumeCoverVariant::ObjectQuadratic
        },
        centre_order: match centre_order {
            "random" => CentreOrder::Random,
            "deepest" => CentreOrder::DeepestFirst,
            "greedy" => CentreOrder::MostUncovered,
            other => {
                return Err(bad_input(format!(
                    "centre_order {other:?} is not one of \"random\", \"deepest\", \"greedy\""
                )));
            }
        },
        elimination: match elimination {
            "off" => Elimination::Off,
            "centres" => Elimination::VoxelCentres,
            "corners" => Elimination::CellCorners,
            other => {
                return Err(bad_input(format!(
                    "elimination {other:?} is not one of \"off\", \"centres\", \"corners\""
                )));
            }
        },
        seed,
        ..defaults
    })
}

/// The volume cover of a voxel volume (thesis §3.4.2) in world coordinates, as `sphcover
/// cover` builds it from a NIfTI or INRIMAGE file.
#[pyfunction]
#[pyo3(signature = (values, affine, *, threshold = None, eps = None, linear = false, centre_order = "random", elimination = "corners", seed = 0))]
#[allow(clippy::too_many_arguments)]
pub fn volume_cover(
    py: Python<'_>,
    values: PyReadonlyArray3<'_, f64>,
    affine: PyReadonlyArray2<'_, f64>,
    threshold: Option<f64>,
    eps: Option<f64>,
    linear: bool,
    centre_order: &str,
    elimination: &str,
    seed: u64,
) -> PyResult<Cover> {
    let params = volume_params(threshold, eps, linear, centre_order, elimination, seed)?;
    let volume = crate::skeleton::volume(&values, &affine)?;
    let (cover, _stats) = run(py, None, None, move |_| {
        build_volume_cover(&volume, &params).map_err(|e| bad_input(e.to_string()))
    })?;
    Ok(Cover::new(cover, Normalisation::IDENTITY, 1.0))
}

/// The volume cover of scattered samples with values (points off any grid), as `sphcover
/// cover --value-property` builds it.
#[pyfunction]
#[pyo3(signature = (points, values, *, threshold = None, eps = None, linear = false, centre_order = "random", elimination = "corners", seed = 0))]
#[allow(clippy::too_many_arguments)]
pub fn scattered_cover(
    py: Python<'_>,
    points: PyReadonlyArray2<'_, f64>,
    values: PyReadonlyArray1<'_, f64>,
    threshold: Option<f64>,
    eps: Option<f64>,
    linear: bool,
    centre_order: &str,
    elimination: &str,
    seed: u64,
) -> PyResult<Cover> {
    let params = volume_params(threshold, eps, linear, centre_order, elimination, seed)?;
    let positions = points_from_py(&points, "points")?;
    let values = values_from_py(&values, "values", Some(positions.len()))?;
    let (cover, _stats) = run(py, None, None, move |_| {
        build_scattered_cover(&positions, &values, &params).map_err(|e| bad_input(e.to_string()))
    })?;
    Ok(Cover::new(cover, Normalisation::IDENTITY, 1.0))
}
