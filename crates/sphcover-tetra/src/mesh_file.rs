//! Writing a tetrahedral mesh to files other tools open.
//!
//! The method is described on [`write_tet_mesh()`].

use std::io::Write;
use std::path::{Path, PathBuf};

use sphcover_core::DVec3;
use sphcover_core::io::{IoError, VtkArray, VtkCells, write_atomic, write_vtk_xml};

use crate::tet_mesh::TetMesh;

/// The layouts [`write_tet_mesh`] can write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TetMeshFormat {
    /// VTK legacy unstructured grid, binary.
    Vtk,
    /// VTK XML unstructured grid, ascii.
    Vtu,
    /// Sorted support-index quadruples, text.
    IndexText,
}

impl TetMeshFormat {
    /// The layout named by the extension of `path` (`.vtk`, `.vtu`, `.txt`, `.tets`).
    pub fn from_path(path: &Path) -> Option<TetMeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "vtk" => Some(TetMeshFormat::Vtk),
            "vtu" => Some(TetMeshFormat::Vtu),
            "txt" | "tets" => Some(TetMeshFormat::IndexText),
            _ => None,
        }
    }
}

/// Writes `mesh` (whose vertices index `centres` and `radii`) to `path` in the layout its
/// extension names, refusing to overwrite any of `inputs`.
///
/// Three layouts, chosen by the output's extension:
/// - `.vtk`: a VTK legacy unstructured grid in binary (big-endian, as the legacy format
///   requires), which ParaView and VisIt open. Points are the centres of the supports that are
///   mesh vertices; point data carries each vertex's support index and radius.
/// - `.vtu`: the same grid as VTK XML (ascii, exact reals), ParaView's native format.
/// - `.txt`/`.tets`: one tetrahedron per line as four 0-based **support** indices in
///   ascending order, rows sorted — the layout of the CGAL reference files the tests compare
///   against, so the output can be diffed with any independent implementation.
///
/// Output goes through [`sphcover_core::io::write_atomic`]: a temporary file renamed on
/// success, never an input overwritten.
pub fn write_tet_mesh(
    path: &Path,
    mesh: &TetMesh,
    centres: &[DVec3],
    radii: &[f64],
    inputs: &[PathBuf],
) -> Result<(), IoError> {
    let Some(format) = TetMeshFormat::from_path(path) else {
        return Err(IoError::Unsupported {
            path: path.to_path_buf(),
            format: "this extension",
            what: "a tetrahedral mesh (use .vtk, .vtu or .txt/.tets)".to_owned(),
        });
    };
    if let Some(&v) = mesh
        .vertices
        .iter()
        .find(|&&v| v as usize >= centres.len() || v as usize >= radii.len())
    {
        return Err(IoError::InvalidData {
            path: path.to_path_buf(),
            message: format!(
                "mesh vertex refers to support {v} but there are {} supports",
                centres.len().min(radii.len())
            ),
        });
    }
    write_atomic(path, inputs, |w| match format {
        TetMeshFormat::Vtk => write_vtk(w, mesh, centres, radii),
        TetMeshFormat::Vtu => {
            let points: Vec<DVec3> = mesh.vertices.iter().map(|&v| centres[v as usize]).collect();
            let radii: Vec<f64> = mesh.vertices.iter().map(|&v| radii[v as usize]).collect();
            let data = [
                VtkArray::Indices("support_index", &mesh.vertices),
                VtkArray::Scalars("radius", &radii),
            ];
            write_vtk_xml(
                w,
                true,
                &points,
                &data,
                VtkCells::Tetrahedra(&mesh.tets),
                true,
            )
        }
        TetMeshFormat::IndexText => write_index_text(w, mesh),
    })
}

fn write_vtk(
    w: &mut dyn Write,
    mesh: &TetMesh,
    centres: &[DVec3],
    radii: &[f64],
) -> std::io::Result<()> {
    let n = mesh.vertices.len();
    let t = mesh.tets.len();
    let mut buf = Vec::with_capacity(64 + n * 40 + t * 24);
    write!(
        buf,
        "# vtk DataFile Version 3.0\nsphcover dual complex\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS {n} double\n"
    )?;
    for &v in &mesh.vertices {
        for c in centres[v as usize].to_array() {
            buf.extend_from_slice(&c.to_be_bytes());
        }
    }
    write!(buf, "\nCELLS {t} {}\n", t * 5)?;
    for tet in &mesh.tets {
        buf.extend_from_slice(&4i32.to_be_bytes());
        for &v in tet {
            buf.extend_from_slice(&(v as i32).to_be_bytes());
        }
    }
    write!(buf, "\nCELL_TYPES {t}\n")?;
    for _ in 0..t {
        // VTK_TETRA
        buf.extend_from_slice(&10i32.to_be_bytes());
    }
    write!(
        buf,
        "\nPOINT_DATA {n}\nSCALARS support_index int 1\nLOOKUP_TABLE default\n"
    )?;
    for &v in &mesh.vertices {
        buf.extend_from_slice(&(v as i32).to_be_bytes());
    }
    write!(buf, "\nSCALARS radius double 1\nLOOKUP_TABLE default\n")?;
    for &v in &mesh.vertices {
        buf.extend_from_slice(&radii[v as usize].to_be_bytes());
    }
    buf.push(b'\n');
    w.write_all(&buf)
}

fn write_index_text(w: &mut dyn Write, mesh: &TetMesh) -> std::io::Result<()> {
    let mut rows: Vec<[u32; 4]> = mesh
        .tets
        .iter()
        .map(|t| {
            let mut s = t.map(|v| mesh.vertices[v as usize]);
            s.sort_unstable();
            s
        })
        .collect();
    rows.sort_unstable();
    let mut buf = String::with_capacity(rows.len() * 24);
    for r in rows {
        use std::fmt::Write as _;
        let _ = writeln!(buf, "{} {} {} {}", r[0], r[1], r[2], r[3]);
    }
    w.write_all(buf.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DualComplexParams, dual_complex};

    fn unit_tet() -> (Vec<DVec3>, Vec<f64>, TetMesh) {
        let centres = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            DVec3::splat(10.0), // far away: not in any tetrahedron of the complex
        ];
        let radii = vec![1.0, 1.0, 1.0, 1.0, 0.1];
        let dc = dual_complex(
            &centres,
            &radii,
            &DualComplexParams {
                shrink: 1.0,
                ..DualComplexParams::default()
            },
        )
        .unwrap();
        let mesh = TetMesh::from_dual_complex(&dc);
        (centres, radii, mesh)
    }

    #[test]
    fn index_text_lists_support_indices() {
        let (centres, radii, mesh) = unit_tet();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("m.tets");
        write_tet_mesh(&out, &mesh, &centres, &radii, &[]).unwrap();
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "0 1 2 3\n");
    }

    #[test]
    fn vtk_has_the_declared_sections_and_sizes() {
        let (centres, radii, mesh) = unit_tet();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("m.vtk");
        write_tet_mesh(&out, &mesh, &centres, &radii, &[]).unwrap();
        let bytes = std::fs::read(&out).unwrap();
        let header = b"# vtk DataFile Version 3.0\nsphcover dual complex\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n";
        assert!(bytes.starts_with(header));
        let after_points = header.len() + 4 * 3 * 8;
        assert!(bytes[after_points..].starts_with(b"\nCELLS 1 5\n"));
        let expected_len = header.len()
            + 4 * 24
            + b"\nCELLS 1 5\n".len()
            + 20
            + b"\nCELL_TYPES 1\n".len()
            + 4
            + b"\nPOINT_DATA 4\nSCALARS support_index int 1\nLOOKUP_TABLE default\n".len()
            + 16
            + b"\nSCALARS radius double 1\nLOOKUP_TABLE default\n".len()
            + 32
            + 1;
        assert_eq!(bytes.len(), expected_len);
    }

    #[test]
    fn vtu_holds_the_tetrahedra_support_indices_and_radii() {
        let (centres, radii, mesh) = unit_tet();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("m.vtu");
        write_tet_mesh(&out, &mesh, &centres, &radii, &[]).unwrap();
        let text = std::fs::read_to_string(&out).unwrap();
        assert!(
            text.contains("<VTKFile type=\"UnstructuredGrid\""),
            "{text}"
        );
        assert!(
            text.contains("NumberOfPoints=\"4\" NumberOfCells=\"1\""),
            "{text}"
        );
        for array in [
            "support_index",
            "radius",
            "connectivity",
            "offsets",
            "types",
        ] {
            assert!(
                text.contains(&format!("Name=\"{array}\"")),
                "{array}: {text}"
            );
        }
        assert!(
            text.contains("Name=\"types\" NumberOfComponents=\"1\" format=\"ascii\">\n10\n"),
            "{text}"
        );
    }

    #[test]
    fn unknown_extension_and_input_overwrite_are_refused() {
        let (centres, radii, mesh) = unit_tet();
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("m.ply");
        assert!(write_tet_mesh(&bad, &mesh, &centres, &radii, &[]).is_err());
        let input = dir.path().join("in.txt");
        std::fs::write(&input, "keep").unwrap();
        let err = write_tet_mesh(
            &input,
            &mesh,
            &centres,
            &radii,
            std::slice::from_ref(&input),
        );
        assert!(matches!(err, Err(IoError::OutputIsInput { .. })));
        assert_eq!(std::fs::read_to_string(&input).unwrap(), "keep");
    }
}
