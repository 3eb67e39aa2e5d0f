//! VTK XML output, the formats ParaView opens natively: `.vtp` (PolyData) for surfaces and
//! point clouds, `.vtu` (UnstructuredGrid) for triangle sheets and tetrahedral meshes. Data
//! arrays are ascii, every real as the shortest text that reads back exactly (`Float64`, or
//! `Float32` for [`Precision::F32`](super::Precision::F32)), indices as `Int64`.

use std::io::Write;

use glam::DVec3;

use super::encode::write_records;
use super::text::{push_real, push_uint};
use super::{Export, Format};

/// A per-point array of a VTK XML file.
#[derive(Clone, Copy, Debug)]
pub enum VtkArray<'a> {
    /// One real per point.
    Scalars(&'a str, &'a [f64]),
    /// One index per point.
    Indices(&'a str, &'a [u32]),
    /// Three reals per point (ParaView's `Normals` when named `normals`).
    Vectors(&'a str, &'a [DVec3]),
    /// An 8-bit red, green, blue triple per point (`UInt8`, 3 components).
    Colors(&'a str, &'a [[u8; 3]]),
}

/// The cells of a VTK XML file.
#[derive(Clone, Copy, Debug)]
pub enum VtkCells<'a> {
    /// Every point is a vertex cell (a point cloud).
    Vertices,
    /// Triangles (VTK type 5).
    Triangles(&'a [[u32; 3]]),
    /// Tetrahedra (VTK type 10).
    Tetrahedra(&'a [[u32; 4]]),
}

/// Writes one piece: `positions`, their `point_data`, and `cells`; PolyData (`.vtp`) unless
/// `unstructured` (`.vtu`). Tetrahedra need `unstructured`.
pub fn write_vtk_xml(
    w: &mut dyn Write,
    unstructured: bool,
    positions: &[DVec3],
    point_data: &[VtkArray<'_>],
    cells: VtkCells<'_>,
    double: bool,
) -> std::io::Result<()> {
    let n = positions.len();
    let (corners, cell_count, vtk_type): (usize, usize, u8) = match cells {
        VtkCells::Vertices => (1, n, 1),
        VtkCells::Triangles(t) => (3, t.len(), 5),
        VtkCells::Tetrahedra(t) => (4, t.len(), 10),
    };
    let connectivity: &[u32] = match cells {
        VtkCells::Vertices => &[],
        VtkCells::Triangles(t) => t.as_flattened(),
        VtkCells::Tetrahedra(t) => t.as_flattened(),
    };
    let real = if double { "Float64" } else { "Float32" };
    let (grid, piece) = if unstructured {
        (
            "UnstructuredGrid",
            format!("NumberOfPoints=\"{n}\" NumberOfCells=\"{cell_count}\""),
        )
    } else {
        let (verts, polys) = if vtk_type == 1 {
            (n, 0)
        } else {
            (0, cell_count)
        };
        (
            "PolyData",
            format!(
                "NumberOfPoints=\"{n}\" NumberOfVerts=\"{verts}\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"{polys}\""
            ),
        )
    };
    write!(
        w,
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"{grid}\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<{grid}>\n<Piece {piece}>\n<PointData"
    )?;
    for array in point_data {
        match array {
            VtkArray::Vectors(name, _) if *name == "normals" => write!(w, " Normals=\"normals\"")?,
            // The first scalar array is the one a viewer colours by: the colours themselves
            // when the writer put them first.
            VtkArray::Scalars(name, _) | VtkArray::Colors(name, _) => {
                write!(w, " Scalars=\"{name}\"")?;
                break;
            }
            _ => {}
        }
    }
    w.write_all(b">\n")?;
    for array in point_data {
        match *array {
            VtkArray::Scalars(name, values) => {
                data_array(w, real, name, 1, values.len(), |i, b| {
                    push_real(b, values[i], double)
                })?
            }
            VtkArray::Indices(name, values) => {
                data_array(w, "Int64", name, 1, values.len(), |i, b| {
                    push_uint(b, u64::from(values[i]))
                })?
            }
            VtkArray::Vectors(name, values) => {
                data_array(w, real, name, 3, values.len(), |i, b| {
                    push_vector(b, values[i], double)
                })?
            }
            VtkArray::Colors(name, values) => {
                data_array(w, "UInt8", name, 3, values.len(), |i, b| {
                    for (k, c) in values[i].into_iter().enumerate() {
                        if k > 0 {
                            b.push(b' ');
                        }
                        push_uint(b, u64::from(c));
                    }
                })?
            }
        }
    }
    w.write_all(b"</PointData>\n<Points>\n")?;
    data_array(w, real, "Points", 3, n, |i, b| {
        push_vector(b, positions[i], double)
    })?;
    w.write_all(b"</Points>\n")?;

    let block = if unstructured {
        "Cells"
    } else if vtk_type == 1 {
        "Verts"
    } else {
        "Polys"
    };
    writeln!(w, "<{block}>")?;
    let corner = |i: usize| {
        if vtk_type == 1 {
            i as u64
        } else {
            u64::from(connectivity[i])
        }
    };
    data_array(
        w,
        "Int64",
        "connectivity",
        1,
        cell_count * corners,
        |i, b| push_uint(b, corner(i)),
    )?;
    data_array(w, "Int64", "offsets", 1, cell_count, |c, b| {
        push_uint(b, ((c + 1) * corners) as u64)
    })?;
    if unstructured {
        data_array(w, "UInt8", "types", 1, cell_count, |_, b| {
            push_uint(b, u64::from(vtk_type))
        })?;
    }
    write!(w, "</{block}>\n</Piece>\n</{grid}>\n</VTKFile>\n")
}

fn push_vector(b: &mut Vec<u8>, v: DVec3, double: bool) {
    for (k, c) in v.to_array().into_iter().enumerate() {
        if k > 0 {
            b.push(b' ');
        }
        push_real(b, c, double);
    }
}

/// One `DataArray` of `count` tuples, one tuple per line.
fn data_array(
    w: &mut dyn Write,
    ty: &str,
    name: &str,
    components: usize,
    count: usize,
    encode: impl Fn(usize, &mut Vec<u8>) + Sync,
) -> std::io::Result<()> {
    writeln!(
        w,
        "<DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{components}\" format=\"ascii\">"
    )?;
    write_records(w, count, |i, b| {
        encode(i, b);
        b.push(b'\n');
    })?;
    w.write_all(b"</DataArray>\n")
}

/// Writes what a mesh or point writer was given: normals as ParaView's `Normals`, colours as
/// `rgb` (the array a viewer shows first), the values as `quality` (the PLY name), confidence
/// and radii under their names; the triangles, or every point as a vertex cell.
pub(crate) fn write_export(
    w: &mut dyn Write,
    e: &Export<'_>,
    format: Format,
    double: bool,
) -> std::io::Result<()> {
    let mut arrays = Vec::new();
    if let Some(normals) = e.normals {
        arrays.push(VtkArray::Vectors("normals", normals));
    }
    if let Some(colors) = e.colors {
        arrays.push(VtkArray::Colors("rgb", colors));
    }
    for (name, values) in [
        ("quality", e.values),
        ("confidence", e.confidence),
        ("radius", e.radii),
    ] {
        if let Some(values) = values {
            arrays.push(VtkArray::Scalars(name, values));
        }
    }
    let cells = if e.triangles.is_empty() {
        VtkCells::Vertices
    } else {
        VtkCells::Triangles(e.triangles)
    };
    write_vtk_xml(
        w,
        format == Format::Vtu,
        e.positions,
        &arrays,
        cells,
        double,
    )
}
