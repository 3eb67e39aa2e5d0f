//! `read` and `write`: every format the command line reads and writes, through the core's
//! readers and writers (the format is the file's extension).

use std::path::PathBuf;

use ndarray::{Array2, Array3, ShapeBuilder};
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sphcover_core::io::{
    self, Format, NonFinitePolicy, PlyEncoding, Precision, ReadOptions, SphereSet, WriteOptions,
};
use sphcover_core::{PointCloud, TriMesh, VoxelValues};

use crate::arrays::{
    colors_from_py, points_from_py, points_to_py, rows_from_py, rows_to_py, values_from_py,
    vec_to_py,
};
use crate::cover::Cover;
use crate::errors::{bad_input, io_error};
use crate::memory::{ReadLimit, byte_size};

/// Reads `path` into a dict: a volume (`kind` `"volume"`, `values` as an `(nx, ny, nz)`
/// array indexed `[i, j, k]`, `affine` 4×4), a cover file (`"cover"`, `cover`), or geometry
/// (`"geometry"`: `points` and, when present, `normals`, `confidence`, `values`, `colors`
/// (`(n, 3)` uint8), `radii`, `triangles`).
#[pyfunction]
#[pyo3(signature = (path, drop_non_finite = false, max_memory = None))]
pub fn read<'py>(
    py: Python<'py>,
    path: PathBuf,
    drop_non_finite: bool,
    max_memory: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let limit = ReadLimit::new(byte_size(max_memory)?);
    let options = limit.apply(ReadOptions {
        non_finite: if drop_non_finite {
            NonFinitePolicy::Drop
        } else {
            NonFinitePolicy::Refuse
        },
        ..ReadOptions::default()
    });
    let out = PyDict::new(py);
    out.set_item("path", path.display().to_string())?;
    if io::is_volume_path(&path) {
        let (volume, info) = py
            .detach(|| io::read_volume(&path, &options))
            .map_err(|e| limit.error(e))?;
        let [nx, ny, nz] = volume.dims();
        let affine = volume.affine();
        // x fastest: the column-major (Fortran) layout of an (nx, ny, nz) array.
        let shape = (nx, ny, nz).f();
        let values = match volume.into_values() {
            VoxelValues::F32(v) => Array3::from_shape_vec(shape, v)
                .expect("a volume holds nx·ny·nz values")
                .into_pyarray(py)
                .into_any(),
            VoxelValues::F64(v) => Array3::from_shape_vec(shape, v)
                .expect("a volume holds nx·ny·nz values")
                .into_pyarray(py)
                .into_any(),
        };
        let m = affine.matrix3;
        let t = affine.translation;
        let rows = [
            [m.x_axis.x, m.y_axis.x, m.z_axis.x, t.x],
            [m.x_axis.y, m.y_axis.y, m.z_axis.y, t.y],
            [m.x_axis.z, m.y_axis.z, m.z_axis.z, t.z],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let affine = Array2::from_shape_vec((4, 4), rows.into_iter().flatten().collect())
            .expect("4 rows of 4");
        out.set_item("kind", "volume")?;
        out.set_item("values", values)?;
        out.set_item("affine", affine.into_pyarray(py))?;
        out.set_item("format", info.format_description())?;
        return Ok(out);
    }
    let geometry = py
        .detach(|| io::read_geometry(&path, &options))
        .map_err(|e| limit.error(e))?;
    if geometry.info.format == Format::Ply
        && geometry.radii.is_some()
        && let Ok((cover, meta)) = py.detach(|| io::read_cover(&path))
    {
        out.set_item("kind", "cover")?;
        out.set_item(
            "cover",
            Cover::new(cover, meta.normalisation, meta.expansion),
        )?;
        out.set_item("notes", meta.notes)?;
        return Ok(out);
    }
    out.set_item("kind", "geometry")?;
    out.set_item("format", geometry.info.variant.clone())?;
    let PointCloud {
        positions,
        normals,
        confidence,
        values,
        colors,
    } = geometry.points;
    out.set_item("points", points_to_py(py, positions))?;
    if let Some(n) = normals {
        out.set_item("normals", points_to_py(py, n))?;
    }
    if let Some(c) = confidence {
        out.set_item("confidence", vec_to_py(py, c))?;
    }
    if let Some(v) = values {
        out.set_item("values", vec_to_py(py, v))?;
    }
    if let Some(c) = colors {
        out.set_item("colors", rows_to_py(py, c))?;
    }
    if let Some(r) = geometry.radii {
        out.set_item("radii", vec_to_py(py, r))?;
    }
    out.set_item("triangles", rows_to_py(py, geometry.triangles))?;
    Ok(out)
}

/// Writes points (with `triangles`: a mesh; with `radii`: a sphere set) and their attributes
/// to `path` in the format its extension names; PLY binary little-endian with `f64` numbers
/// unless `ascii` or `single` say otherwise. A format that cannot hold part of the data is
/// refused, as the command line refuses it.
#[pyfunction]
#[pyo3(signature = (path, points, triangles = None, normals = None, confidence = None, values = None, radii = None, colors = None, ascii = false, single = false))]
#[allow(clippy::too_many_arguments)]
pub fn write_geometry(
    py: Python<'_>,
    path: PathBuf,
    points: PyReadonlyArray2<'_, f64>,
    triangles: Option<PyReadonlyArray2<'_, u32>>,
    normals: Option<PyReadonlyArray2<'_, f64>>,
    confidence: Option<PyReadonlyArray1<'_, f64>>,
    values: Option<PyReadonlyArray1<'_, f64>>,
    radii: Option<PyReadonlyArray1<'_, f64>>,
    colors: Option<PyReadonlyArray2<'_, u8>>,
    ascii: bool,
    single: bool,
) -> PyResult<()> {
    let positions = points_from_py(&points, "points")?;
    let n = Some(positions.len());
    let normals = normals.map(|a| points_from_py(&a, "normals")).transpose()?;
    let confidence = confidence
        .map(|a| values_from_py(&a, "confidence", n))
        .transpose()?;
    let values = values
        .map(|a| values_from_py(&a, "values", n))
        .transpose()?;
    let radii = radii.map(|a| values_from_py(&a, "radii", n)).transpose()?;
    let colors = colors
        .map(|a| colors_from_py(&a, positions.len()))
        .transpose()?;
    let triangles = triangles
        .map(|a| rows_from_py(&a, "triangles"))
        .transpose()?;
    let options = WriteOptions {
        ply_encoding: if ascii {
            PlyEncoding::Ascii
        } else {
            PlyEncoding::BinaryLittleEndian
        },
        precision: if single {
            Precision::F32
        } else {
            Precision::F64
        },
        inputs: Vec::new(),
    };
    let result = match (triangles, radii) {
        (Some(_), Some(_)) => {
            return Err(bad_input(
                "a file holds triangles or sphere radii, not both",
            ));
        }
        (Some(triangles), None) => {
            if confidence.is_some() {
                return Err(bad_input(
                    "a mesh has per-vertex values, not a separate confidence: pass it as values",
                ));
            }
            let mesh = TriMesh {
                vertices: positions,
                triangles,
                normals,
                values,
                colors,
            };
            py.detach(|| io::write_mesh(&path, &mesh, &options))
        }
        (None, Some(radii)) => {
            if normals.is_some() || confidence.is_some() || values.is_some() || colors.is_some() {
                return Err(bad_input("a sphere set holds centres and radii only"));
            }
            let spheres = SphereSet {
                centres: positions,
                radii,
            };
            py.detach(|| io::write_spheres(&path, &spheres, &options))
        }
        (None, None) => {
            let cloud = PointCloud {
                positions,
                normals,
                confidence,
                values,
                colors,
            };
            py.detach(|| io::write_point_cloud(&path, &cloud, &options))
        }
    };
    result.map_err(io_error)
}

/// Write options of the command line's outputs: binary little-endian or ascii PLY, `f64`.
pub fn write_options(ascii: bool) -> WriteOptions {
    WriteOptions {
        ply_encoding: if ascii {
            PlyEncoding::Ascii
        } else {
            PlyEncoding::BinaryLittleEndian
        },
        ..WriteOptions::default()
    }
}
