//! `skeleton`: the skeletal sheet of a thin part from a voxel volume and its affine (what
//! nibabel gives: `img.get_fdata()`, `img.affine`) or from scattered samples with values, as
//! `sphcover skeleton` extracts it; and the non-maximum-suppression baseline.

use glam::DAffine3;
use numpy::{PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sphcover_core::{DMat3, DVec3, TriMesh, Volume, VoxelValues};
use sphcover_skeleton::{
    Material, MaterialChoice, NmsParams, SkeletonParams, SkeletonStats, check_voxel_grid,
    extract_skeleton_from_samples_until, extract_skeleton_until, nms_skeleton,
};

use crate::arrays::{points_from_py, points_to_py, rows_to_py, values_from_py, vec_to_py};
use crate::errors::{bad_input, skeleton_error, warn};
use crate::run::{run, stage_times};

/// The ridge pipeline's parameters: the library's defaults and the given options, as
/// `sphcover skeleton` sets them.
fn ridge_params(
    threshold: Option<f64>,
    eps: Option<f64>,
    sigma: Option<f64>,
    seed: u64,
) -> PyResult<SkeletonParams> {
    if let Some(s) = sigma
        && !(s.is_finite() && s > 0.0)
    {
        return Err(bad_input(format!("sigma {s} must be a positive number")));
    }
    let mut params = SkeletonParams::default();
    params.threshold = threshold;
    params.tolerance = eps;
    params.sigma = sigma.unwrap_or(params.sigma);
    params.seed = seed;
    Ok(params)
}

/// The command line's `--material` values.
fn material_choice(name: &str) -> PyResult<MaterialChoice> {
    Ok(match name {
        "auto" => MaterialChoice::Auto,
        "bone" => MaterialChoice::Given(Material::Bone),
        "tissue" => MaterialChoice::Given(Material::Tissue),
        "off" => MaterialChoice::Off,
        other => {
            return Err(bad_input(format!(
                "material {other:?} is not one of 'auto', 'bone', 'tissue', 'off'"
            )));
        }
    })
}

/// The volume of `values[i, j, k]` at `affine · (i, j, k, 1)`.
pub fn volume(
    values: &PyReadonlyArray3<'_, f64>,
    affine: &PyReadonlyArray2<'_, f64>,
) -> PyResult<Volume> {
    let shape = affine.shape();
    if !(shape[1] == 4 && (shape[0] == 3 || shape[0] == 4)) {
        return Err(bad_input(format!(
            "affine must be 4×4 (or 3×4), not {}×{}",
            shape[0], shape[1]
        )));
    }
    let a = affine.as_array();
    let column = |c: usize| DVec3::new(a[[0, c]], a[[1, c]], a[[2, c]]);
    let affine = DAffine3 {
        matrix3: DMat3::from_cols(column(0), column(1), column(2)),
        translation: column(3),
    };
    let v = values.as_array();
    let dims = [v.shape()[0], v.shape()[1], v.shape()[2]];
    // The reversed axes iterate with i fastest: the voxel order of `Volume`.
    let data: Vec<f64> = v.t().iter().copied().collect();
    Volume::new(dims, VoxelValues::F64(data), affine).map_err(|e| bad_input(e.to_string()))
}

/// The sheet of a voxel volume (`method` `"ridge"`), or the ridge points of the baseline
/// (`"nms"`).
#[pyfunction]
#[pyo3(signature = (values, affine, *, threshold = None, material = "auto", sigma = None, eps = None, method = "ridge", seed = 0, threads = None, progress = None))]
#[allow(clippy::too_many_arguments)]
pub fn skeleton_volume<'py>(
    py: Python<'py>,
    values: PyReadonlyArray3<'py, f64>,
    affine: PyReadonlyArray2<'py, f64>,
    threshold: Option<f64>,
    material: &str,
    sigma: Option<f64>,
    eps: Option<f64>,
    method: &str,
    seed: u64,
    threads: Option<usize>,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let volume = volume(&values, &affine)?;
    let check = check_voxel_grid(volume.voxel_size(), volume.affine().matrix3)
        .map_err(|e| bad_input(e.to_string()))?;
    if let Some(resampling) = check.resampling {
        let [nx, ny, nz] = resampling.dims(volume.dims());
        warn(py, &format!("{resampling}; {nx} x {ny} x {nz} voxels"))?;
    }
    if let Some(non_cubic) = check.non_cubic {
        warn(py, &non_cubic.to_string())?;
    }
    match method {
        "ridge" => {
            let mut params = ridge_params(threshold, eps, sigma, seed)?;
            params.material = material_choice(material)?;
            let (sheet, stats) = run(py, progress, threads, move |context| {
                extract_skeleton_until(&volume, &params, &|s| context.stage(s), context.stop())
                    .map_err(skeleton_error)
            })?;
            sheet_dict(py, sheet, &stats)
        }
        "nms" => {
            let params = NmsParams {
                sigma: sigma.unwrap_or(NmsParams::default().sigma),
                threshold,
                ..NmsParams::default()
            };
            let (points, stats) = run(py, progress, threads, move |_| {
                nms_skeleton(&volume, &params).map_err(skeleton_error)
            })?;
            let out = PyDict::new(py);
            out.set_item("points", points_to_py(py, points))?;
            let s = PyDict::new(py);
            s.set_item("threshold", stats.intensity.threshold)?;
            s.set_item("automatic_threshold", stats.intensity.automatic_threshold)?;
            s.set_item("candidates", stats.candidates)?;
            s.set_item("points", stats.points)?;
            out.set_item("stats", s)?;
            Ok(out)
        }
        other => Err(bad_input(format!(
            "method {other:?} is not one of 'ridge', 'nms'"
        ))),
    }
}

/// The sheet of scattered samples with values (ridge method).
#[pyfunction]
#[pyo3(signature = (points, values, *, threshold = None, sigma = None, eps = None, seed = 0, threads = None, progress = None))]
#[allow(clippy::too_many_arguments)]
pub fn skeleton_samples<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    values: PyReadonlyArray1<'py, f64>,
    threshold: Option<f64>,
    sigma: Option<f64>,
    eps: Option<f64>,
    seed: u64,
    threads: Option<usize>,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let positions = points_from_py(&points, "points")?;
    let values = values_from_py(&values, "values", Some(positions.len()))?;
    let params = ridge_params(threshold, eps, sigma, seed)?;
    let (sheet, stats) = run(py, progress, threads, move |context| {
        extract_skeleton_from_samples_until(
            &positions,
            &values,
            &params,
            &|s| context.stage(s),
            context.stop(),
        )
        .map_err(skeleton_error)
    })?;
    sheet_dict(py, sheet, &stats)
}

/// The sheet's arrays (per-vertex values: the ridge strength) and the statistics, with the
/// names of the command line's `--report` JSON.
fn sheet_dict<'py>(
    py: Python<'py>,
    sheet: TriMesh,
    s: &SkeletonStats,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("vertices", points_to_py(py, sheet.vertices))?;
    out.set_item("faces", rows_to_py(py, sheet.triangles))?;
    if let Some(n) = sheet.normals {
        out.set_item("normals", points_to_py(py, n))?;
    }
    if let Some(v) = sheet.values {
        out.set_item("values", vec_to_py(py, v))?;
    }
    let d = PyDict::new(py);
    d.set_item("threshold", s.intensity.threshold)?;
    d.set_item("automatic_threshold", s.intensity.automatic_threshold)?;
    d.set_item("tolerance", s.tolerance)?;
    d.set_item("object_voxels", s.cover.object_points)?;
    d.set_item("supports", s.cover.supports)?;
    d.set_item("tetrahedra", s.tetrahedra)?;
    d.set_item("ridge_points", s.ridge_points)?;
    d.set_item("triangles", s.triangles)?;
    d.set_item("vertices", s.vertices)?;
    d.set_item("components", s.components)?;
    d.set_item("euler_characteristic", s.euler_characteristic)?;
    d.set_item("tunnels_closed", s.tunnels)?;
    d.set_item("perforations_cut", s.perforations)?;
    d.set_item("flap_triangles_collapsed", s.flap_triangles)?;
    d.set_item("slice_centred_vertices", s.slice_centred_vertices)?;
    d.set_item("hessian_slice_stretch", s.hessian_slice_stretch)?;
    d.set_item("rim_slice_stretch", s.rim_slice_stretch)?;
    d.set_item("off_plate_triangles_collapsed", s.off_plate_triangles)?;
    d.set_item("thickness_exceeds_r_max", s.thickness_exceeds_r_max())?;
    match &s.material {
        Some(m) => {
            let material = PyDict::new(py);
            material.set_item("name", m.material.map(Material::name))?;
            material.set_item("automatic", m.automatic)?;
            material.set_item("air_hu", m.levels.air)?;
            material.set_item("soft_tissue_hu", m.levels.soft_tissue)?;
            material.set_item("window", m.window.map(|(lo, hi)| vec![lo, hi]))?;
            d.set_item("material", material)?;
        }
        None => d.set_item("material", py.None())?,
    }
    match &s.resampled {
        Some(r) => {
            let resampled = PyDict::new(py);
            resampled.set_item("factors", r.resampling.factors.to_vec())?;
            resampled.set_item("input_dims", r.original_dims.to_vec())?;
            resampled.set_item("dims", r.dims.to_vec())?;
            resampled.set_item("voxel_size", r.resampling.voxel_size().to_array().to_vec())?;
            resampled.set_item("seconds", r.time.as_secs_f64())?;
            d.set_item("resampled", resampled)?;
        }
        None => d.set_item("resampled", py.None())?,
    }
    d.set_item("stages_seconds", stage_times(py, &s.stages)?)?;
    out.set_item("stats", d)?;
    Ok(out)
}
