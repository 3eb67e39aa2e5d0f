//! `reconstruct`: `sphcover recon` on arrays. The options are the command line's, checked by
//! the same [`ReconOptions`]; the pipeline is the same [`sphcover_recon::reconstruct_until`],
//! so the mesh written to PLY is the command line's byte for byte.

use numpy::{PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use sphcover_core::PointCloud;
use sphcover_recon::{
    BudgetFit, Method, NoiseOption, ReconError, ReconOptions, ReconParams, ReconStats,
    Reconstruction, ScanFile, SequentialStreamedTiles, SequentialTiles, StreamedTile,
    StreamedTileProduct, StreamedTileRunner, TileFunction, TileInput, TileRunner, Tiling,
    ToleranceNote, TrimOption, fit_memory_budget, reconstruct_streamed, reconstruct_tiled_with,
    reconstruct_until, streamed_tile_function, tile_function,
};

use crate::arrays::{colors_from_py, points_from_py, points_to_py, values_from_py, vec_to_py};
use crate::cover::Cover;
use crate::errors::{bad_input, option_error, recon_error, warn};
use crate::memory::byte_size;
use crate::run::{run, stage_times};

/// The method named as on the command line.
fn method(name: &str) -> PyResult<Method> {
    Ok(match name {
        "integrated" => Method::Integrated,
        "graphcut" => Method::GraphCut,
        "diffusion" => Method::Diffusion,
        "pu" => Method::PartitionOfUnity,
        other => {
            return Err(bad_input(format!(
                "method {other:?} is not one of 'integrated', 'graphcut', 'diffusion', 'pu'"
            )));
        }
    })
}

/// `trim`: None (the default: leave out what the scanner never saw), False (keep
/// everything), True (3 sample spacings) or a distance.
fn trim(value: Option<&Bound<'_, PyAny>>) -> PyResult<TrimOption> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(TrimOption::Unseen);
    };
    if let Ok(flag) = value.cast::<pyo3::types::PyBool>() {
        return Ok(if flag.is_true() {
            TrimOption::Auto
        } else {
            TrimOption::Off
        });
    }
    Ok(TrimOption::Distance(value.extract::<f64>()?))
}

/// `noise`: None, "auto", "off" or the noise σ.
fn noise_option(value: Option<&Bound<'_, PyAny>>) -> PyResult<Option<NoiseOption>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    if let Ok(text) = value.extract::<String>() {
        return match text.as_str() {
            "auto" => Ok(Some(NoiseOption::Auto)),
            "off" => Ok(Some(NoiseOption::Off)),
            _ => Err(bad_input(format!(
                "noise {text:?} must be \"auto\", \"off\" or a non-negative number"
            ))),
        };
    }
    Ok(Some(NoiseOption::Value(value.extract::<f64>()?)))
}

/// Reconstructs the surface of the points; returns a dict of the mesh's arrays, the per-point
/// confidence and outlier labels, the final cover and the statistics.
#[pyfunction]
#[pyo3(signature = (
    points, normals = None, confidence = None, colors = None, *, method_name = "integrated", eps = None,
    k = None, trim_value = None, depth = None, normal_fit = None, position_fit = None,
    normal_neighbours = 12, estimate_normals = false, refine = true, seed = 0,
    threads = None, progress = None, max_memory = None, noise = None, tiles = None, halo = None,
    map_tiles = None, scratch = None,
))]
#[allow(clippy::too_many_arguments)]
pub fn reconstruct<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    normals: Option<PyReadonlyArray2<'py, f64>>,
    confidence: Option<PyReadonlyArray1<'py, f64>>,
    colors: Option<PyReadonlyArray2<'py, u8>>,
    method_name: &str,
    eps: Option<f64>,
    k: Option<f64>,
    trim_value: Option<&Bound<'py, PyAny>>,
    depth: Option<u32>,
    normal_fit: Option<f64>,
    position_fit: Option<f64>,
    normal_neighbours: usize,
    estimate_normals: bool,
    refine: bool,
    seed: u64,
    threads: Option<usize>,
    progress: Option<&Bound<'py, PyAny>>,
    max_memory: Option<&Bound<'py, PyAny>>,
    noise: Option<&Bound<'py, PyAny>>,
    tiles: Option<[usize; 3]>,
    halo: Option<f64>,
    map_tiles: Option<Py<PyAny>>,
    scratch: Option<std::path::PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let budget = byte_size(max_memory)?;
    let options = ReconOptions {
        method: method(method_name)?,
        eps,
        noise: noise_option(noise)?,
        k,
        trim: trim(trim_value)?,
        depth,
        normal_fit,
        position_fit,
        normal_neighbours,
        refine,
        seed,
        ..ReconOptions::default()
    };
    let mut params = options.params().map_err(option_error)?;
    let tiling = tiles.map(|tiles| Tiling {
        tiles,
        halo: halo.unwrap_or_else(|| Tiling::default_halo(tiles)),
    });
    if let Some(tiling) = &tiling {
        tiling.check().map_err(|e| bad_input(e.to_string()))?;
        if params.method == Method::GraphCut {
            return Err(bad_input(
                ReconError::NotTileable(params.method.name()).to_string(),
            ));
        }
    }
    let positions = points_from_py(&points, "points")?;
    let n = Some(positions.len());
    let normals = match (normals, estimate_normals) {
        (Some(a), false) => Some(points_from_py(&a, "normals")?),
        _ => None,
    };
    let confidence = confidence
        .map(|a| values_from_py(&a, "confidence", n))
        .transpose()?;
    let colors = colors
        .map(|a| colors_from_py(&a, positions.len()))
        .transpose()?;
    let cloud = PointCloud {
        positions,
        normals,
        confidence,
        values: None,
        colors,
    };
    cloud.check().map_err(bad_input)?;
    if threads == Some(0) {
        return Err(bad_input("threads must be at least 1"));
    }
    // Checked before any heavy work, as the command line checks `--max-memory`.
    let memory = match budget {
        Some(budget) => {
            let fit =
                fit_memory_budget(&cloud, &params, budget).map_err(|e| bad_input(e.to_string()))?;
            if let Some(warning) = fit.lowering_message("max_memory") {
                warn(py, &warning)?;
                params.depth = Some(fit.depth);
            }
            Some(fit)
        }
        None => None,
    };
    // Checked again once the cover's graph is built, when its true size is known.
    params.memory_budget = budget;
    let run_params = params.clone();
    let recon = run(py, progress, threads, move |context| {
        let progress = |s| context.stage(s);
        match (tiling, map_tiles) {
            (None, _) => reconstruct_until(&cloud, &run_params, &progress, context.stop()),
            (Some(tiling), None) => reconstruct_tiled_with(
                &cloud,
                &run_params,
                &tiling,
                &SequentialTiles,
                &progress,
                context.stop(),
            ),
            (Some(tiling), Some(map_tiles)) => reconstruct_tiled_with(
                &cloud,
                &run_params,
                &tiling,
                &PythonTiles { map_tiles, scratch },
                &progress,
                context.stop(),
            ),
        }
        .map_err(recon_error)
    })?;
    let note = ToleranceNote::of(&params, &recon.stats).map(|n| (n, n.message("eps", "noise")));
    if let Some((ToleranceNote::BelowFloor { .. }, message)) = &note {
        warn(py, message)?;
    }
    into_dict(py, recon, &params, note.map(|(_, message)| message), memory)
}

/// Reconstructs the surface of a scan file too large for memory, streamed into tiles
/// ([`reconstruct_streamed`]); returns a dict of the mesh's arrays and the statistics.
#[pyfunction]
#[pyo3(signature = (
    path, *, tiles, halo = None, scratch = None, method_name = "integrated", eps = None,
    k = None, trim_value = None, depth = None, normal_fit = None, position_fit = None,
    refine = true, seed = 0, threads = None, progress = None, noise = None, map_tiles = None,
))]
#[allow(clippy::too_many_arguments)]
pub fn reconstruct_file<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
    tiles: [usize; 3],
    halo: Option<f64>,
    scratch: Option<std::path::PathBuf>,
    method_name: &str,
    eps: Option<f64>,
    k: Option<f64>,
    trim_value: Option<&Bound<'py, PyAny>>,
    depth: Option<u32>,
    normal_fit: Option<f64>,
    position_fit: Option<f64>,
    refine: bool,
    seed: u64,
    threads: Option<usize>,
    progress: Option<&Bound<'py, PyAny>>,
    noise: Option<&Bound<'py, PyAny>>,
    map_tiles: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let options = ReconOptions {
        method: method(method_name)?,
        eps,
        noise: noise_option(noise)?,
        k,
        trim: trim(trim_value)?,
        depth,
        normal_fit,
        position_fit,
        refine,
        seed,
        ..ReconOptions::default()
    };
    let params = options.params().map_err(option_error)?;
    let tiling = Tiling {
        tiles,
        halo: halo.unwrap_or_else(|| Tiling::default_halo(tiles)),
    };
    tiling.check().map_err(|e| bad_input(e.to_string()))?;
    if params.method == Method::GraphCut {
        return Err(bad_input(
            ReconError::NotTileable(params.method.name()).to_string(),
        ));
    }
    if threads == Some(0) {
        return Err(bad_input("threads must be at least 1"));
    }
    let scratch = scratch.unwrap_or_else(std::env::temp_dir);
    let source = ScanFile::new(path);
    let run_params = params.clone();
    let recon = run(py, progress, threads, move |context| {
        let progress = |s| context.stage(s);
        let python = map_tiles.map(|map_tiles| PythonStreamedTiles { map_tiles });
        let runner: &dyn StreamedTileRunner = match &python {
            Some(python) => python,
            None => &SequentialStreamedTiles,
        };
        reconstruct_streamed(
            &source,
            runner,
            &run_params,
            &tiling,
            &scratch,
            &progress,
            context.stop(),
        )
        .map_err(recon_error)
    })?;
    let note = ToleranceNote::of(&params, &recon.stats).map(|n| n.message("eps", "noise"));
    let stats = stats_dict(py, &recon.stats)?;
    stats.set_item("eps_requested", params.cover.eps)?;
    stats.set_item("tolerance_note", note)?;
    mesh_dict(py, recon.mesh, stats)
}

/// A streamed run's tiles run by a Python callable `map_tiles(tasks) -> products`: a list of
/// tasks as bytes in, a list of the same length of `streamed_tile_function`'s products
/// (bytes) out, in order. The workers read the tile files' directory.
struct PythonStreamedTiles {
    map_tiles: Py<PyAny>,
}

impl StreamedTileRunner for PythonStreamedTiles {
    fn run(
        &self,
        tasks: &[StreamedTile],
        _params: &ReconParams,
    ) -> Result<Vec<StreamedTileProduct>, ReconError> {
        let blobs: Vec<Vec<u8>> = tasks.iter().map(StreamedTile::to_bytes).collect();
        map_through(&self.map_tiles, tasks.len(), |py| {
            PyList::new(py, blobs.iter().map(|b| PyBytes::new(py, b)))
        })?
        .into_iter()
        .map(|b| {
            let b = b.ok_or_else(|| ReconError::TileRunner("map_tiles returned None".into()))?;
            StreamedTileProduct::from_bytes(&b)
        })
        .collect()
    }
}

/// Calls `map_tiles` on the list `items` builds and checks that it returns `count` results,
/// each bytes or None.
fn map_through(
    map_tiles: &Py<PyAny>,
    count: usize,
    items: impl for<'py> FnOnce(Python<'py>) -> PyResult<Bound<'py, PyList>>,
) -> Result<Vec<Option<Vec<u8>>>, ReconError> {
    let returned = Python::attach(|py| {
        let results = map_tiles.bind(py).call1((items(py)?,))?;
        results
            .try_iter()?
            .map(|item| item?.extract::<Option<Vec<u8>>>())
            .collect::<PyResult<Vec<_>>>()
    })
    .map_err(|e| ReconError::TileRunner(format!("map_tiles raised {e}")))?;
    if returned.len() != count {
        return Err(ReconError::TileRunner(format!(
            "map_tiles returned {} results for {count} tiles",
            returned.len()
        )));
    }
    Ok(returned)
}

/// One streamed tile's task ([`sphcover_recon::streamed_tile_function`]) from its bytes, with
/// the options of `reconstruct_file` that the tiles read: the product as bytes. What a
/// worker of a distributed engine runs; it reads and writes the run's tile files.
#[pyfunction]
#[pyo3(signature = (
    task, *, method_name = "integrated", eps = None, k = None, normal_fit = None,
    position_fit = None, seed = 0, noise = None, threads = None,
))]
#[allow(clippy::too_many_arguments)]
pub fn streamed_tile_bytes<'py>(
    py: Python<'py>,
    task: &[u8],
    method_name: &str,
    eps: Option<f64>,
    k: Option<f64>,
    normal_fit: Option<f64>,
    position_fit: Option<f64>,
    seed: u64,
    noise: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyBytes>> {
    let params = tile_params(method_name, eps, k, normal_fit, position_fit, seed, noise)?;
    let task = StreamedTile::from_bytes(task).map_err(|e| bad_input(e.to_string()))?;
    let product = run(py, None, threads, move |_| {
        streamed_tile_function(&task, &params)
            .map(|p| p.to_bytes())
            .map_err(recon_error)
    })?;
    Ok(PyBytes::new(py, &product))
}

/// The parameters the tiles' tasks read, from the options a worker gets.
fn tile_params(
    method_name: &str,
    eps: Option<f64>,
    k: Option<f64>,
    normal_fit: Option<f64>,
    position_fit: Option<f64>,
    seed: u64,
    noise: Option<&Bound<'_, PyAny>>,
) -> PyResult<ReconParams> {
    let options = ReconOptions {
        method: method(method_name)?,
        eps,
        noise: noise_option(noise)?,
        k,
        normal_fit,
        position_fit,
        seed,
        ..ReconOptions::default()
    };
    options.params().map_err(option_error)
}

/// Tiles run by a Python callable `map_tiles(inputs) -> functions`: a list of tile inputs
/// in, a list of the same length of `tile_function`'s results (bytes, or None for a tile
/// without a cover) out, in the same order. A distributed engine's map (Dask's `client.map`
/// and `client.gather`) fits it. The inputs are bytes, or with a scratch directory the paths
/// of files holding them, written one at a time so that this process never holds them all.
struct PythonTiles {
    map_tiles: Py<PyAny>,
    scratch: Option<std::path::PathBuf>,
}

impl PythonTiles {
    /// The inputs as the callable gets them: bytes, or paths of files in the scratch
    /// directory (removed again when `files` is dropped).
    fn inputs(
        &self,
        count: usize,
        input: &(dyn Fn(usize) -> TileInput + Sync),
    ) -> Result<TileInputs, ReconError> {
        let Some(dir) = &self.scratch else {
            return Ok(TileInputs::Bytes(
                (0..count).map(|t| input(t).to_bytes()).collect(),
            ));
        };
        let mut files = ScratchFiles(Vec::with_capacity(count));
        for t in 0..count {
            let path = dir.join(format!("sphcover-tile-{}-{t:05}.in", std::process::id()));
            sphcover_core::io::write_atomic(&path, &[], |w| w.write_all(&input(t).to_bytes()))
                .map_err(|e| ReconError::TileRunner(format!("{}: {e}", path.display())))?;
            files.0.push(path);
        }
        Ok(TileInputs::Files(files))
    }
}

enum TileInputs {
    Bytes(Vec<Vec<u8>>),
    Files(ScratchFiles),
}

/// Tile input files, removed when dropped (after the run, or when it fails).
struct ScratchFiles(Vec<std::path::PathBuf>);

impl Drop for ScratchFiles {
    fn drop(&mut self) {
        for path in &self.0 {
            let _ = std::fs::remove_file(path);
        }
    }
}

impl TileRunner for PythonTiles {
    fn run(
        &self,
        count: usize,
        input: &(dyn Fn(usize) -> TileInput + Sync),
        _params: &ReconParams,
    ) -> Result<Vec<Option<TileFunction>>, ReconError> {
        // Built without the interpreter: the calling thread keeps reporting progress.
        let inputs = self.inputs(count, input)?;
        map_through(&self.map_tiles, count, |py| match &inputs {
            TileInputs::Bytes(blobs) => PyList::new(py, blobs.iter().map(|b| PyBytes::new(py, b))),
            TileInputs::Files(files) => PyList::new(py, files.0.iter()),
        })?
        .into_iter()
        .map(|r| r.map(|b| TileFunction::from_bytes(&b)).transpose())
        .collect()
    }
}

/// One tile's function ([`sphcover_recon::tile_function`]) from its input as bytes, with the
/// options of `reconstruct` that the tiles' stages read (the others act on the whole
/// surface); bytes, or None for a tile with too few samples for a cover. What a worker of a
/// distributed engine runs.
#[pyfunction]
#[pyo3(signature = (
    tile, *, method_name = "integrated", eps = None, k = None, normal_fit = None,
    position_fit = None, seed = 0, noise = None, threads = None,
))]
#[allow(clippy::too_many_arguments)]
pub fn tile_function_bytes<'py>(
    py: Python<'py>,
    tile: &[u8],
    method_name: &str,
    eps: Option<f64>,
    k: Option<f64>,
    normal_fit: Option<f64>,
    position_fit: Option<f64>,
    seed: u64,
    noise: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
) -> PyResult<Option<Bound<'py, PyBytes>>> {
    let params = tile_params(method_name, eps, k, normal_fit, position_fit, seed, noise)?;
    let input = TileInput::from_bytes(tile).map_err(|e| bad_input(e.to_string()))?;
    let function = run(py, None, threads, move |_| {
        tile_function(&input, &params)
            .map(|f| f.map(|f| f.to_bytes()))
            .map_err(recon_error)
    })?;
    Ok(function.map(|b| PyBytes::new(py, &b)))
}

fn into_dict<'py>(
    py: Python<'py>,
    recon: Reconstruction,
    params: &ReconParams,
    tolerance_note: Option<String>,
    memory: Option<BudgetFit>,
) -> PyResult<Bound<'py, PyDict>> {
    let stats = stats_dict(py, &recon.stats)?;
    stats.set_item("eps_requested", params.cover.eps)?;
    stats.set_item("tolerance_note", tolerance_note)?;
    if let Some(m) = memory {
        let d = PyDict::new(py);
        d.set_item("budget_bytes", m.budget)?;
        d.set_item("estimated_peak_bytes", m.estimate)?;
        d.set_item("depth_lowered_from", m.lowered_from.map(|(depth, _)| depth))?;
        stats.set_item("memory", d)?;
    }
    let Reconstruction {
        mesh,
        confidence,
        outliers,
        cover,
        normalisation,
        ..
    } = recon;
    let out = mesh_dict(py, mesh, stats)?;
    out.set_item("point_confidence", vec_to_py(py, confidence))?;
    out.set_item("outliers", vec_to_py(py, outliers))?;
    out.set_item("cover", Cover::new(cover, normalisation, 1.0))?;
    Ok(out)
}

/// The mesh's arrays and `stats`, as a dict.
fn mesh_dict<'py>(
    py: Python<'py>,
    mesh: sphcover_core::TriMesh,
    stats: Bound<'py, PyDict>,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("vertices", points_to_py(py, mesh.vertices))?;
    out.set_item("faces", crate::arrays::rows_to_py(py, mesh.triangles))?;
    if let Some(n) = mesh.normals {
        out.set_item("normals", points_to_py(py, n))?;
    }
    if let Some(v) = mesh.values {
        out.set_item("confidence", vec_to_py(py, v))?;
    }
    if let Some(c) = mesh.colors {
        out.set_item("colors", crate::arrays::rows_to_py(py, c))?;
    }
    out.set_item("stats", stats)?;
    Ok(out)
}

/// The statistics, with the names of the command line's `--report` JSON.
fn stats_dict<'py>(py: Python<'py>, s: &ReconStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("method", s.method.name())?;
    d.set_item("points", s.points)?;
    d.set_item("non_finite_points", s.non_finite_points)?;
    d.set_item("normals_estimated", s.normals_estimated)?;
    d.set_item("outliers", s.outliers)?;
    d.set_item("supports", s.supports)?;
    d.set_item("supports_over_eps", s.cover.supports_over_eps)?;
    d.set_item("graph_mean_degree", s.graph_mean_degree)?;
    d.set_item("predicted_peak_bytes", s.predicted_peak_bytes)?;
    d.set_item("inconsistent_supports", s.inconsistent_supports)?;
    d.set_item("confirmed_supports", s.confirmed_supports)?;
    d.set_item("unseen_area_fraction", s.unseen_area_fraction)?;
    d.set_item("one_view", s.scan.one_view)?;
    d.set_item("eps", s.eps)?;
    d.set_item("noise_floor", s.noise_floor)?;
    d.set_item("spacing", s.scan.spacing)?;
    d.set_item("noise", s.scan.noise)?;
    d.set_item("depth", s.depth)?;
    d.set_item("vertices", s.vertices)?;
    d.set_item("triangles", s.triangles)?;
    d.set_item("components", s.components)?;
    d.set_item("dropped_components", s.dropped_components)?;
    d.set_item("refined_vertices", s.refinement.as_ref().map(|r| r.moved))?;
    d.set_item("watertight", s.watertight)?;
    d.set_item("open_components", s.open_components)?;
    d.set_item("object_component_open", s.object_component_open)?;
    d.set_item("euler_characteristic", s.euler_characteristic)?;
    d.set_item("tiles", s.tiles.len())?;
    d.set_item("stages_seconds", stage_times(py, &s.stages)?)?;
    d.set_item(
        "total_seconds",
        s.stages.iter().map(|(_, t)| t.as_secs_f64()).sum::<f64>(),
    )?;
    Ok(d)
}
