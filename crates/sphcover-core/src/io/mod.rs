//! Scan file formats: PLY, OBJ, OFF, STL, XYZ text, sphere sets and LAS (read only).
//!
//! Every reader parses the whole file from memory, checks every count the file declares
//! against the bytes actually present before allocating, and reports every problem as an
//! [`IoError`] naming the file and the line (text) or byte offset (binary) where it is. No
//! byte sequence makes a reader panic or allocate more than a small multiple of the file
//! size. Where a reader sizes an allocation from a declared count (PLY elements, OFF counts,
//! LAS points, binary STL triangles, volume dimensions), the count times the bytes each
//! record takes in memory is also checked against [`ReadOptions::max_bytes`] first, and a
//! file over it is refused with [`IoError::OverMemoryLimit`]; text formats without counts
//! (OBJ, XYZ) and cover files grow their arrays with the records actually present.
//!
//! # Formats and the rules chosen where formats are loose
//!
//! | extension | reads | writes |
//! |---|---|---|
//! | `.ply` | ascii, binary little/big endian; any scalar type; `vertex` (x y z, nx ny nz, `confidence`, `quality`/`value`/`scalar`/`intensity`/`scalar_*` as the values, `radius`) and `face` (`vertex_indices`/`vertex_index` lists); other elements and properties skipped | binary little endian (default), big endian or ascii; `float` or `double` |
//! | `.obj` | `v`, `vn`, `f` (all corner forms, negative indices); other statements ignored | `v`, `vn`, `f` |
//! | `.off` | `OFF` with `N`, `C`, `ST` prefixes (extra per-vertex columns), `#` comments | `OFF` / `NOFF` |
//! | `.stl` | binary and ascii; identical vertices merged | binary |
//! | `.xyz` `.pwn` | `x y z`, `x y z v`, `x y z nx ny nz`, `x y z nx ny nz v` per line | same |
//! | `.txt` | as `.xyz`, except that 4 columns mean a sphere set `x y z r` | same |
//! | `.sph` `.spheres` | sphere sets, `x y z r` per line | same |
//! | `.las`, `.laz` | LAS 1.0–1.4, point formats 0–10, uncompressed or LASzip-compressed (LAZ): positions, intensity as per-vertex values | — |
//!
//! * Text records are one per line (every PLY, OFF and XYZ writer does that), so a record
//!   with a missing or extra number is reported on its own line instead of shifting every
//!   following record.
//! * In the column formats the first data line fixes the column count for the whole file.
//!   A first comment line naming the columns exactly as this crate writes them
//!   (`# x y z r`, `# x y z nx ny nz`, …) fixes it too, which matters only for files with no
//!   data line (an empty sphere set stays a sphere set).
//! * Polygons are fan-triangulated; faces with fewer than 3 corners are skipped and counted
//!   in [`FileInfo::skipped_polygons`].
//! * ASCII PLY `float` fields are parsed as `f32`, the value the header declares.
//! * Non-finite vertices (NaN or infinite position, normal or radius) are handled by
//!   [`NonFinitePolicy`].
//! * Writers print decimal numbers as the shortest text that reads back bit-exactly, and
//!   [`Precision::F64`] (the default) makes every round trip through a file lossless;
//!   [`Precision::F32`] halves binary files and rounds every value to `f32`. STL always
//!   stores `f32`. Text formats without declared types (OBJ, OFF, column text) store an `f32`
//!   as the shortest digits that identify it; they read back as an `f64` that rounds to the
//!   same `f32`.
//! * A writer given data its format cannot hold (faces to XYZ, per-vertex values of a point
//!   cloud to OBJ, a point cloud to STL, …) returns [`IoError::Unsupported`] instead of
//!   dropping data. The one exception is [`write_mesh`]: a mesh written to OBJ, OFF or STL
//!   is its geometry, so per-vertex values (and in STL, vertex normals) that the format has
//!   no place for are left out, as mesh tools do.
//! * Every writer goes through [`write_atomic`]: the output appears complete or not at all.

mod atomic;
mod byte_size;
mod cover_file;
mod encode;
mod error;
#[cfg(feature = "nifti")]
mod inrimage;
mod las;
mod laz;
#[cfg(feature = "nifti")]
mod nifti;
mod non_finite;
mod obj;
mod off;
mod ply;
mod point_stream;
mod stl;
mod text;
mod vertex_property;
#[cfg(feature = "nifti")]
mod volume_file;
mod vtk_xml;
mod xyz;

use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::mesh::TriMesh;
use crate::point_cloud::PointCloud;

pub use atomic::write_atomic;
pub use byte_size::{format_byte_size, parse_byte_size};
pub use cover_file::{CoverFileMeta, parse_cover, read_cover, write_cover};
pub use error::{IoError, Location, Problem};
#[cfg(feature = "nifti")]
pub use inrimage::{InrimageInfo, parse_inrimage, read_inrimage, read_inrimage_info};
#[cfg(feature = "nifti")]
pub use nifti::{AffineSource, NiftiInfo, parse_nifti, read_nifti, read_nifti_info};
pub use point_stream::{PointStreamInfo, stream_points};
pub use vertex_property::{parse_ply_with_vertex_property, read_geometry_with_vertex_property};
#[cfg(feature = "nifti")]
pub use volume_file::{SampleType, VolumeInfo, is_volume_path, read_volume, read_volume_info};
pub use vtk_xml::{VtkArray, VtkCells, write_vtk_xml};

/// A file format, named by the file's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// Stanford polygon file (`.ply`).
    Ply,
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// Object File Format (`.off`).
    Off,
    /// Stereolithography (`.stl`).
    Stl,
    /// Points, optionally with normals, one per line (`.xyz`).
    Xyz,
    /// Points with normals, one per line (`.pwn`; read like `.xyz`).
    Pwn,
    /// Columns of numbers (`.txt`): a point cloud like `.xyz`, or a sphere set with 4 columns.
    Txt,
    /// Sphere sets `x y z r`, one per line (`.sph`, `.spheres`).
    Sph,
    /// ASPRS LAS LiDAR point cloud (`.las`, and LASzip-compressed `.laz`; read only).
    Las,
    /// VTK XML PolyData (`.vtp`, write only): surfaces and point clouds for ParaView.
    Vtp,
    /// VTK XML UnstructuredGrid (`.vtu`, write only): triangle sheets (and, from
    /// `sphcover-tetra`, tetrahedral meshes) for ParaView.
    Vtu,
}

impl Format {
    /// The format named by the extension of `path` (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Format, IoError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("ply") => Ok(Format::Ply),
            Some("obj") => Ok(Format::Obj),
            Some("off") => Ok(Format::Off),
            Some("stl") => Ok(Format::Stl),
            Some("xyz") => Ok(Format::Xyz),
            Some("pwn") => Ok(Format::Pwn),
            Some("txt") => Ok(Format::Txt),
            Some("sph" | "spheres") => Ok(Format::Sph),
            Some("las" | "laz") => Ok(Format::Las),
            Some("vtp") => Ok(Format::Vtp),
            Some("vtu") => Ok(Format::Vtu),
            _ => Err(IoError::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }

    /// Short name for messages (`"PLY"`, `"OBJ"`, …).
    pub fn name(self) -> &'static str {
        match self {
            Format::Ply => "PLY",
            Format::Obj => "OBJ",
            Format::Off => "OFF",
            Format::Stl => "STL",
            Format::Xyz => "XYZ",
            Format::Pwn => "PWN",
            Format::Txt => "TXT",
            Format::Sph => "sphere set",
            Format::Las => "LAS",
            Format::Vtp => "VTK PolyData",
            Format::Vtu => "VTK UnstructuredGrid",
        }
    }
}

/// What readers do with vertices whose position, normal or radius holds a NaN or an
/// infinity, and with voxels holding one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NonFinitePolicy {
    /// Fail with [`IoError::NonFinite`] ([`IoError::NonFiniteVoxels`] for a volume), naming
    /// the first such vertex (voxel) and counting them all.
    #[default]
    Refuse,
    /// Remove those vertices (and the triangles using them, reindexing the rest); the counts
    /// are in [`FileInfo::non_finite`]. A volume cannot lose voxels: they take its lowest
    /// finite value, its background (a volume without a finite voxel is still refused); the
    /// count is in [`VolumeInfo::non_finite_voxels`].
    Drop,
    /// Keep them as they are (for inspection); the counts are in [`FileInfo::non_finite`]
    /// ([`VolumeInfo::non_finite_voxels`]).
    Keep,
}

/// Options of the readers.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// What to do with non-finite vertices.
    pub non_finite: NonFinitePolicy,
    /// The most memory, in bytes, a reader may set aside for the records or voxels a file
    /// declares (its count times each one's size in memory), checked from the header before
    /// anything is allocated or decompressed: a file declaring more is refused with
    /// [`IoError::OverMemoryLimit`]. `None` (the default) sets no limit besides what the
    /// file's size can hold.
    pub max_bytes: Option<u64>,
}

/// Encoding of PLY output.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `binary_little_endian`: compact, fast, what most tools write.
    #[default]
    BinaryLittleEndian,
    /// `binary_big_endian`.
    BinaryBigEndian,
    /// `ascii`, human-readable.
    Ascii,
}

/// Precision of written real numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// `f32` (PLY `float`): half the size; every value is rounded to `f32`.
    F32,
    /// `f64` (PLY `double`): lossless round trips. The default, because `sphcover` computes
    /// in `f64` and a read–write cycle should never change a file's data.
    #[default]
    F64,
}

/// Options of the writers.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WriteOptions {
    /// PLY encoding (ignored by other formats).
    pub ply_encoding: PlyEncoding,
    /// Precision of real numbers (STL always stores `f32`).
    pub precision: Precision,
    /// Files the output must not overwrite (the inputs of the command).
    pub inputs: Vec<PathBuf>,
}

/// A set of balls.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SphereSet {
    /// Ball centres.
    pub centres: Vec<DVec3>,
    /// Ball radii, one per centre.
    pub radii: Vec<f64>,
}

/// One element (group of records) a file declares, as `sphcover info` shows it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ElementInfo {
    /// Element name (`vertex`, `face`, or the PLY file's own names).
    pub name: String,
    /// Number of records.
    pub count: u64,
    /// Properties of each record, in file order.
    pub properties: Vec<PropertyInfo>,
}

/// One property of an element.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PropertyInfo {
    /// Property name (`x`, `nx`, `vertex_indices`, …).
    pub name: String,
    /// Type as the file declares it (`float`, `list uchar int`, …; `text` for text formats).
    pub type_name: String,
}

/// Non-finite vertices found in a file, and what was done with them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NonFiniteReport {
    /// Vertices with at least one non-finite position, normal or radius value.
    pub vertices: u64,
    /// Non-finite values among those positions, normals and radii.
    pub coordinates: u64,
    /// Vertices removed ([`NonFinitePolicy::Drop`]).
    pub dropped_vertices: u64,
    /// Triangles removed because they used a removed vertex.
    pub dropped_triangles: u64,
}

/// What a file declares and what reading it found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileInfo {
    /// The format.
    pub format: Format,
    /// The format with its variant, e.g. `"PLY binary little-endian"`, `"STL ascii"`.
    pub variant: String,
    /// Declared elements and their properties (PLY); what was found (other formats).
    pub elements: Vec<ElementInfo>,
    /// Header comments (PLY `comment` and `obj_info` lines, STL header text).
    pub comments: Vec<String>,
    /// Polygons read, before triangulation.
    pub polygons: u64,
    /// Polygons skipped for having fewer than 3 corners.
    pub skipped_polygons: u64,
    /// Non-finite vertices.
    pub non_finite: NonFiniteReport,
    /// Size of the file in bytes.
    pub file_size: u64,
}

/// Everything a reader returns: the vertices with their attributes, triangles, radii and a
/// description of the file.
#[derive(Clone, Debug, PartialEq)]
pub struct Geometry {
    /// Vertices and their per-vertex attributes.
    pub points: PointCloud,
    /// Triangles (polygons fan-triangulated) as indices into `points`.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex radii, when the file is a sphere set.
    pub radii: Option<Vec<f64>>,
    /// What the file declares.
    pub info: FileInfo,
}

/// A reader's product before the non-finite policy: the geometry and where each vertex came
/// from in the file, so that the first non-finite one can be located.
#[derive(Debug)]
pub(crate) struct Parsed {
    pub points: PointCloud,
    pub triangles: Vec<[u32; 3]>,
    pub radii: Option<Vec<f64>>,
    pub info: FileInfo,
    pub origins: VertexOrigins,
}

/// Where the vertices of a parsed file are.
#[derive(Debug)]
pub(crate) enum VertexOrigins {
    /// Fixed-size binary records: vertex `i` starts at `start + i·stride`.
    Stride { start: u64, stride: u64 },
    /// The line of each vertex.
    Lines(Vec<u64>),
    /// The byte offset of each vertex.
    Bytes(Vec<u64>),
}

impl VertexOrigins {
    fn locate(&self, i: usize) -> Location {
        match self {
            VertexOrigins::Stride { start, stride } => Location::Byte(start + stride * i as u64),
            VertexOrigins::Lines(lines) => Location::Line(lines.get(i).copied().unwrap_or(0)),
            VertexOrigins::Bytes(bytes) => Location::Byte(bytes.get(i).copied().unwrap_or(0)),
        }
    }
}

impl FileInfo {
    pub(crate) fn new(format: Format, variant: impl Into<String>, file_size: usize) -> FileInfo {
        FileInfo {
            format,
            variant: variant.into(),
            elements: Vec::new(),
            comments: Vec::new(),
            polygons: 0,
            skipped_polygons: 0,
            non_finite: NonFiniteReport::default(),
            file_size: file_size as u64,
        }
    }
}

/// Appends the fan triangulation of a polygon; false (nothing appended) for a polygon of
/// fewer than 3 corners.
pub(crate) fn push_polygon(corners: &[u32], triangles: &mut Vec<[u32; 3]>) -> bool {
    if corners.len() < 3 {
        return false;
    }
    triangles.extend(corners[1..].windows(2).map(|w| [corners[0], w[0], w[1]]));
    true
}

/// Files at least this large are memory-mapped instead of copied into memory: the copy's
/// page faults cost as much as decoding a binary PLY.
const MAP_THRESHOLD: u64 = 64 << 20;

/// Reads any supported file (format from the extension).
///
/// Large files are memory-mapped; like every program that maps files, the reader assumes
/// that no other process truncates the file while it is being read.
pub fn read_geometry(path: &Path, options: &ReadOptions) -> Result<Geometry, IoError> {
    let format = Format::from_path(path)?;
    let read_error = |source| IoError::Read {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(read_error)?;
    let size = file.metadata().map_err(read_error)?.len();
    if size >= MAP_THRESHOLD
        && let Some(map) = map_file(&file)
    {
        return parse_geometry(&map, format, path, options);
    }
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(&mut &file, &mut bytes).map_err(read_error)?;
    parse_geometry(&bytes, format, path, options)
}

/// Maps a file read-only; `None` where mapping is not possible (the caller reads instead).
#[allow(unsafe_code)]
fn map_file(file: &std::fs::File) -> Option<memmap2::Mmap> {
    // SAFETY: the map is read-only and private to this call; its contents change only if
    // another process writes the file meanwhile, which readers of any kind cannot guard
    // against (the bytes are then simply different, or the process gets SIGBUS when the
    // file is truncated under it).
    unsafe { memmap2::Mmap::map(file) }.ok()
}

/// Parses the bytes of a file held in memory (standard input, an archive member…); `path`
/// only names the file in errors.
pub fn parse_geometry(
    bytes: &[u8],
    format: Format,
    path: &Path,
    options: &ReadOptions,
) -> Result<Geometry, IoError> {
    if bytes.is_empty() {
        return Err(error::Failure::new(Location::Byte(0), Problem::EmptyFile).into_io(path));
    }
    let limit = options.max_bytes;
    let parsed = match format {
        Format::Ply => ply::read(bytes, limit),
        Format::Obj => obj::read(bytes, limit),
        Format::Off => off::read(bytes, limit),
        Format::Stl => stl::read(bytes, limit),
        Format::Las => las::read(bytes, limit),
        Format::Vtp | Format::Vtu => Err(error::Failure::header(
            Location::Byte(0),
            "VTK XML is written for viewers, not read (read PLY instead)",
        )),
        Format::Xyz | Format::Pwn | Format::Txt | Format::Sph => xyz::read(bytes, format, limit),
    }
    .map_err(|failure| failure.into_io(path))?;
    non_finite::apply(parsed, options.non_finite, path)
}

/// Reads the vertices of any supported file as a point cloud (faces are ignored).
pub fn read_point_cloud(path: &Path, options: &ReadOptions) -> Result<PointCloud, IoError> {
    Ok(read_geometry(path, options)?.points)
}

/// Reads a triangle mesh (a file without faces gives a mesh without triangles).
pub fn read_mesh(path: &Path, options: &ReadOptions) -> Result<TriMesh, IoError> {
    let g = read_geometry(path, options)?;
    Ok(TriMesh {
        vertices: g.points.positions,
        triangles: g.triangles,
        normals: g.points.normals,
        values: g.points.values,
        colors: g.points.colors,
    })
}

/// Reads a sphere set; fails with [`IoError::NoRadius`] when the file has no radii.
pub fn read_spheres(path: &Path, options: &ReadOptions) -> Result<SphereSet, IoError> {
    let g = read_geometry(path, options)?;
    match g.radii {
        Some(radii) => Ok(SphereSet {
            centres: g.points.positions,
            radii,
        }),
        None => Err(IoError::NoRadius {
            path: path.to_path_buf(),
        }),
    }
}

/// What a writer is asked to store: borrowed arrays, all of one length except `triangles`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Export<'a> {
    pub positions: &'a [DVec3],
    pub normals: Option<&'a [DVec3]>,
    pub confidence: Option<&'a [f64]>,
    pub values: Option<&'a [f64]>,
    pub radii: Option<&'a [f64]>,
    pub colors: Option<&'a [[u8; 3]]>,
    pub triangles: &'a [[u32; 3]],
}

impl Export<'_> {
    fn check(&self, path: &Path) -> Result<(), IoError> {
        let n = self.positions.len();
        let invalid = |message: String| IoError::InvalidData {
            path: path.to_path_buf(),
            message,
        };
        for (name, len) in [
            ("normals", self.normals.map(<[_]>::len)),
            ("confidence", self.confidence.map(<[_]>::len)),
            ("values", self.values.map(<[_]>::len)),
            ("radii", self.radii.map(<[_]>::len)),
            ("colors", self.colors.map(<[_]>::len)),
        ] {
            if let Some(len) = len
                && len != n
            {
                return Err(invalid(format!(
                    "{name} has {len} entries for {n} vertices"
                )));
            }
        }
        if !self.triangles.is_empty() && n > u32::MAX as usize {
            return Err(invalid(format!(
                "{n} vertices are more than 32-bit indices reach"
            )));
        }
        if let Some((t, tri)) = self
            .triangles
            .iter()
            .enumerate()
            .find(|(_, tri)| tri.iter().any(|&v| v as usize >= n))
        {
            return Err(invalid(format!(
                "triangle {t} refers to vertex {tri:?} but there are {n} vertices"
            )));
        }
        Ok(())
    }

    /// Fails when `format` cannot hold part of the data.
    fn check_supported(&self, path: &Path, format: Format) -> Result<(), IoError> {
        let unsupported = |what: &str| IoError::Unsupported {
            path: path.to_path_buf(),
            format: format.name(),
            what: what.to_string(),
        };
        let has_faces = !self.triangles.is_empty();
        let colours_kept = matches!(format, Format::Ply | Format::Vtp | Format::Vtu);
        let problem = match format {
            _ if self.colors.is_some() && !colours_kept => {
                Some("per-vertex colours (write PLY or VTK XML, or clear the attribute)")
            }
            Format::Las => {
                Some("written data: sphcover reads LAS but does not write it (write PLY)")
            }
            Format::Ply | Format::Vtp | Format::Vtu => None,
            Format::Obj | Format::Off => {
                if self.confidence.is_some() {
                    Some("per-vertex confidence (write PLY, or clear the attribute)")
                } else if self.values.is_some() {
                    Some("per-vertex values (write PLY, or clear the attribute)")
                } else if self.radii.is_some() {
                    Some("sphere radii (write PLY, .sph or .txt)")
                } else {
                    None
                }
            }
            Format::Stl => {
                if self.radii.is_some() {
                    Some("sphere radii (write PLY, .sph or .txt)")
                } else if !has_faces && !self.positions.is_empty() {
                    Some("points without triangles (write PLY, OBJ, OFF or XYZ)")
                } else if self.normals.is_some() {
                    Some("per-vertex normals (write PLY, OBJ or OFF, or clear the normals)")
                } else if self.confidence.is_some() || self.values.is_some() {
                    Some("per-vertex attributes (write PLY, or clear them)")
                } else if stl::has_unreferenced_vertex(self.positions.len(), self.triangles) {
                    Some("vertices used by no triangle (write PLY, OBJ or OFF)")
                } else {
                    None
                }
            }
            _ if has_faces => Some("faces (write PLY, OBJ, OFF or STL)"),
            Format::Sph => {
                if self.radii.is_none() {
                    Some("points without radii (a sphere set needs a radius per point)")
                } else if self.normals.is_some()
                    || self.confidence.is_some()
                    || self.values.is_some()
                {
                    Some("per-vertex attributes besides radii (write PLY)")
                } else {
                    None
                }
            }
            _ => {
                if self.confidence.is_some() {
                    Some("per-vertex confidence (write PLY, or clear the attribute)")
                } else if self.radii.is_some() && format != Format::Txt {
                    Some("sphere radii (write PLY, .sph or .txt)")
                } else if self.radii.is_some() && (self.normals.is_some() || self.values.is_some())
                {
                    Some("per-vertex attributes besides radii (write PLY)")
                } else if format == Format::Txt
                    && self.radii.is_none()
                    && self.values.is_some()
                    && self.normals.is_none()
                {
                    Some(
                        "points with values alone: 4 columns in .txt mean spheres (write .xyz or PLY)",
                    )
                } else {
                    None
                }
            }
        };
        match problem {
            Some(what) => Err(unsupported(what)),
            None => Ok(()),
        }
    }
}

fn write_export(path: &Path, export: Export<'_>, options: &WriteOptions) -> Result<(), IoError> {
    let format = Format::from_path(path)?;
    export.check(path)?;
    export.check_supported(path, format)?;
    let double = options.precision == Precision::F64;
    write_atomic(path, &options.inputs, |w| match format {
        Format::Ply => ply::write(w, &export, options.ply_encoding, double),
        Format::Obj => obj::write(w, &export, double),
        Format::Off => off::write(w, &export, double),
        Format::Stl => stl::write(w, &export),
        // Refused by `check_supported` above; kept as an error rather than a panic.
        Format::Las => Err(std::io::Error::new(
            std::io::ErrorKind::Unsupported,
            "LAS is read only",
        )),
        Format::Xyz | Format::Pwn | Format::Txt | Format::Sph => xyz::write(w, &export, double),
        Format::Vtp | Format::Vtu => vtk_xml::write_export(w, &export, format, double),
    })
}

/// Writes a point cloud in the format named by the extension of `path`.
pub fn write_point_cloud(
    path: &Path,
    cloud: &PointCloud,
    options: &WriteOptions,
) -> Result<(), IoError> {
    let export = Export {
        positions: &cloud.positions,
        normals: cloud.normals.as_deref(),
        confidence: cloud.confidence.as_deref(),
        values: cloud.values.as_deref(),
        radii: None,
        colors: cloud.colors.as_deref(),
        triangles: &[],
    };
    write_export(path, export, options)
}

/// Writes a triangle mesh in the format named by the extension of `path`. Per-vertex values
/// and colours are written where the format has a place for them (PLY, VTK XML) and left out
/// elsewhere; vertex normals everywhere but STL (which stores one normal per triangle,
/// computed).
pub fn write_mesh(path: &Path, mesh: &TriMesh, options: &WriteOptions) -> Result<(), IoError> {
    let format = Format::from_path(path)?;
    let attributes_kept = matches!(format, Format::Ply | Format::Vtp | Format::Vtu);
    let export = Export {
        positions: &mesh.vertices,
        normals: mesh.normals.as_deref().filter(|_| format != Format::Stl),
        confidence: None,
        values: mesh.values.as_deref().filter(|_| attributes_kept),
        radii: None,
        colors: mesh.colors.as_deref().filter(|_| attributes_kept),
        triangles: &mesh.triangles,
    };
    write_export(path, export, options)
}

/// Writes a sphere set: `.ply` (vertex property `radius`), `.sph`, `.spheres` or `.txt`.
pub fn write_spheres(
    path: &Path,
    spheres: &SphereSet,
    options: &WriteOptions,
) -> Result<(), IoError> {
    let export = Export {
        positions: &spheres.centres,
        normals: None,
        confidence: None,
        values: None,
        radii: Some(&spheres.radii),
        colors: None,
        triangles: &[],
    };
    write_export(path, export, options)
}
