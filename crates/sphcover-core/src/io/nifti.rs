//! NIfTI-1 and NIfTI-2 single-file volumes (`.nii`, `.nii.gz`), read in-house.
//!
//! * Both byte orders (told apart by `sizeof_hdr`, which is 348 for NIfTI-1 and 540 for
//!   NIfTI-2); gzip is recognised by its magic bytes, whatever the extension.
//! * Datatypes `uint8`, `int8`, `int16`, `uint16`, `int32`, `uint32`, `float32`, `float64`.
//!   Values are scaled by `scl_slope`/`scl_inter` when the slope is finite and non-zero
//!   (a zero slope means "no scaling", as the standard says). 8- and 16-bit integer and
//!   `float32` images are stored as `f32` (NIfTI-1 slopes are `f32` themselves); 32-bit
//!   integer and `float64` images, and scaled NIfTI-2 images, as `f64`.
//! * World coordinates: the sform when `sform_code > 0`, else the qform (quaternion,
//!   `pixdim[0]` as the handedness factor) when `qform_code > 0`, else `diag(pixdim)` with
//!   the origin at voxel `(0, 0, 0)`.
//! * Volumes with more than three dimensions keep their first frame;
//!   [`NiftiInfo::frames`] says how many there were.
//! * Every count is checked against the data actually present and against the memory limit
//!   before anything large is allocated (the steps in [`super::volume_file`]): an
//!   uncompressed file shorter than its header declares is refused from its size; a gzip
//!   stream is refused up front when it declares more data than DEFLATE can expand its
//!   compressed size to (1032:1), and when it ends early or goes on past the declared data.
//!   Byte offsets in errors count from the start of the decompressed stream.
//! * Not read: the two-file `.hdr`/`.img` pair (magic `ni1`/`ni2`), complex and RGB
//!   datatypes, 64-bit integers.

use std::path::Path;

use glam::{DAffine3, DMat3, DVec3};

use super::ReadOptions;
use super::error::{Failure, IoError, Location, Problem};
use super::volume_file::{DecodeError, SampleDecoder, SampleType, VolumeStream, VoxelData};
use crate::volume::Volume;

impl SampleType {
    /// The sample type of a NIfTI `datatype` code, if supported.
    pub fn from_nifti_code(code: i16) -> Option<SampleType> {
        Some(match code {
            2 => SampleType::U8,
            256 => SampleType::I8,
            4 => SampleType::I16,
            512 => SampleType::U16,
            8 => SampleType::I32,
            768 => SampleType::U32,
            16 => SampleType::F32,
            64 => SampleType::F64,
            _ => return None,
        })
    }

    /// The NIfTI `datatype` code.
    pub fn nifti_code(self) -> i16 {
        match self {
            SampleType::U8 => 2,
            SampleType::I8 => 256,
            SampleType::I16 => 4,
            SampleType::U16 => 512,
            SampleType::I32 => 8,
            SampleType::U32 => 768,
            SampleType::F32 => 16,
            SampleType::F64 => 64,
        }
    }
}

/// Where the voxel→world map of a NIfTI file came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AffineSource {
    /// The `srow_*` rows (`sform_code > 0`).
    Sform,
    /// The quaternion, offsets and `pixdim` (`qform_code > 0`).
    Qform,
    /// `diag(pixdim[1..=3])`, origin at voxel `(0, 0, 0)` (neither code set).
    Pixdim,
}

/// What a NIfTI file declares.
#[derive(Clone, Debug, PartialEq)]
pub struct NiftiInfo {
    /// 1 or 2.
    pub version: u8,
    /// True for big-endian files.
    pub big_endian: bool,
    /// True when the file is gzip-compressed.
    pub gzip: bool,
    /// The stored voxel type.
    pub datatype: SampleType,
    /// Spatial dimensions `[nx, ny, nz]` (missing ones are 1).
    pub dims: [usize; 3],
    /// Number of 3D frames (the product of `dim[4..]`); only the first is read.
    pub frames: u64,
    /// Voxel edge lengths in world units (lengths of the affine's columns).
    pub voxel_size: DVec3,
    /// The voxel→world map.
    pub affine: DAffine3,
    /// Which header fields the affine came from.
    pub affine_source: AffineSource,
    /// `(scl_slope, scl_inter)` when scaling was applied.
    pub scaling: Option<(f64, f64)>,
    /// Offset of the voxel data in the (decompressed) stream.
    pub vox_offset: u64,
    /// The `descrip` field, trimmed.
    pub description: String,
    /// Voxels of the first frame found holding NaN or an infinity, handled as
    /// [`ReadOptions::non_finite`] says (0 when only the header was read).
    pub non_finite_voxels: u64,
}

/// Reads a NIfTI-1 or NIfTI-2 file (`.nii` or `.nii.gz`): its first 3D frame as a
/// [`Volume`] and what its header declares. A first frame whose values would take more than
/// `options.max_bytes` is refused from the header with [`IoError::OverMemoryLimit`].
pub fn read_nifti(path: &Path, options: &ReadOptions) -> Result<(Volume, NiftiInfo), IoError> {
    let mut stream = VolumeStream::open(path)?;
    decode(&mut stream, options).map_err(|e| e.into_io(path))
}

/// Reads only the header of a NIfTI file, with every check [`read_nifti`] makes before it
/// reads the voxels.
pub fn read_nifti_info(path: &Path) -> Result<NiftiInfo, IoError> {
    let mut stream = VolumeStream::open(path)?;
    read_header(&mut stream)
        .map(|(info, _)| info)
        .map_err(|e| e.into_io(path))
}

/// Parses a NIfTI file held in memory (plain or gzip); `path` only names it in errors.
pub fn parse_nifti(
    bytes: &[u8],
    path: &Path,
    options: &ReadOptions,
) -> Result<(Volume, NiftiInfo), IoError> {
    decode(&mut VolumeStream::from_bytes(bytes), options).map_err(|e| e.into_io(path))
}

/// Reads numbers of either byte order from a header buffer.
struct Fields<'a> {
    bytes: &'a [u8],
    big: bool,
}

impl Fields<'_> {
    fn arr<const N: usize>(&self, at: usize) -> [u8; N] {
        let mut a = [0u8; N];
        a.copy_from_slice(&self.bytes[at..at + N]);
        if self.big {
            a.reverse();
        }
        a
    }
    fn i16(&self, at: usize) -> i16 {
        i16::from_le_bytes(self.arr(at))
    }
    fn i32(&self, at: usize) -> i32 {
        i32::from_le_bytes(self.arr(at))
    }
    fn i64(&self, at: usize) -> i64 {
        i64::from_le_bytes(self.arr(at))
    }
    fn f32(&self, at: usize) -> f64 {
        f64::from(f32::from_le_bytes(self.arr(at)))
    }
    fn f64(&self, at: usize) -> f64 {
        f64::from_le_bytes(self.arr(at))
    }
}

/// The header fields the reader uses, from either version, with the byte offset of each
/// (for error messages).
struct Header {
    version: u8,
    datatype: (i16, usize),
    dim: [(i64, usize); 8],
    pixdim: [(f64, usize); 8],
    vox_offset: (f64, usize),
    scl_slope: f64,
    scl_inter: f64,
    qform_code: (i32, usize),
    sform_code: (i32, usize),
    quatern: [f64; 3],
    qoffset: [f64; 3],
    srow: [[f64; 4]; 3],
    srow_at: usize,
    description: String,
    size: usize,
}

fn header_error(at: usize, message: String) -> DecodeError {
    DecodeError::Content(Failure::header(Location::Byte(at as u64), message))
}

fn parse_header(bytes: &[u8], big: bool, version: u8) -> Result<Header, DecodeError> {
    let f = Fields { bytes, big };
    let text = |range: std::ops::Range<usize>| {
        let raw = &bytes[range];
        let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
        String::from_utf8_lossy(&raw[..end]).trim().to_string()
    };
    if version == 1 {
        let magic = &bytes[344..348];
        if magic == b"ni1\0" {
            return Err(header_error(
                344,
                "magic \"ni1\": a two-file .hdr/.img NIfTI pair, which is not supported (convert it to a single .nii)".into(),
            ));
        }
        if magic != b"n+1\0" {
            return Err(header_error(
                344,
                format!("magic {magic:?} is not the NIfTI-1 \"n+1\" (an Analyze 7.5 file?)"),
            ));
        }
        let srow = |row: usize| {
            let at = 280 + 16 * row;
            [f.f32(at), f.f32(at + 4), f.f32(at + 8), f.f32(at + 12)]
        };
        Ok(Header {
            version,
            datatype: (f.i16(70), 70),
            dim: std::array::from_fn(|i| (i64::from(f.i16(40 + 2 * i)), 40 + 2 * i)),
            pixdim: std::array::from_fn(|i| (f.f32(76 + 4 * i), 76 + 4 * i)),
            vox_offset: (f.f32(108), 108),
            scl_slope: f.f32(112),
            scl_inter: f.f32(116),
            qform_code: (i32::from(f.i16(252)), 252),
            sform_code: (i32::from(f.i16(254)), 254),
            quatern: [f.f32(256), f.f32(260), f.f32(264)],
            qoffset: [f.f32(268), f.f32(272), f.f32(276)],
            srow: [srow(0), srow(1), srow(2)],
            srow_at: 280,
            description: text(148..228),
            size: 348,
        })
    } else {
        let magic = &bytes[4..12];
        if magic.starts_with(b"ni2\0") {
            return Err(header_error(
                4,
                "magic \"ni2\": a two-file .hdr/.img NIfTI pair, which is not supported (convert it to a single .nii)".into(),
            ));
        }
        if magic != b"n+2\0\r\n\x1a\n" {
            return Err(header_error(
                4,
                format!("magic {magic:?} is not the NIfTI-2 \"n+2\""),
            ));
        }
        let srow = |row: usize| {
            let at = 400 + 32 * row;
            [f.f64(at), f.f64(at + 8), f.f64(at + 16), f.f64(at + 24)]
        };
        let vox_offset = f.i64(168);
        Ok(Header {
            version,
            datatype: (f.i16(12), 12),
            dim: std::array::from_fn(|i| (f.i64(16 + 8 * i), 16 + 8 * i)),
            pixdim: std::array::from_fn(|i| (f.f64(104 + 8 * i), 104 + 8 * i)),
            // i64 → f64 is exact below 2^53; larger offsets are refused as absurd anyway.
            vox_offset: (vox_offset as f64, 168),
            scl_slope: f.f64(176),
            scl_inter: f.f64(184),
            qform_code: (f.i32(344), 344),
            sform_code: (f.i32(348), 348),
            quatern: [f.f64(352), f.f64(360), f.f64(368)],
            qoffset: [f.f64(376), f.f64(384), f.f64(392)],
            srow: [srow(0), srow(1), srow(2)],
            srow_at: 400,
            description: text(240..320),
            size: 540,
        })
    }
}

/// The voxel→world map and where it came from.
fn affine_of(h: &Header) -> Result<(DAffine3, AffineSource), DecodeError> {
    let (source, affine, field_at) = if h.sform_code.0 > 0 {
        let r = h.srow;
        let m = DMat3::from_cols(
            DVec3::new(r[0][0], r[1][0], r[2][0]),
            DVec3::new(r[0][1], r[1][1], r[2][1]),
            DVec3::new(r[0][2], r[1][2], r[2][2]),
        );
        let t = DVec3::new(r[0][3], r[1][3], r[2][3]);
        (
            AffineSource::Sform,
            DAffine3::from_mat3_translation(m, t),
            h.srow_at,
        )
    } else {
        let mut d = [0.0; 3];
        for (axis, v) in d.iter_mut().enumerate() {
            let (p, at) = h.pixdim[axis + 1];
            if !(p.is_finite() && p != 0.0) {
                return Err(header_error(
                    at,
                    format!(
                        "pixdim[{}] = {p} is not a finite non-zero voxel size",
                        axis + 1
                    ),
                ));
            }
            *v = p.abs();
        }
        if h.qform_code.0 > 0 {
            let qfac = if h.pixdim[0].0 < 0.0 { -1.0 } else { 1.0 };
            let rot = quaternion_matrix(h.quatern);
            let m = rot * DMat3::from_diagonal(DVec3::new(d[0], d[1], qfac * d[2]));
            let t = DVec3::from_array(h.qoffset);
            let at = if h.version == 1 { 256 } else { 352 };
            (
                AffineSource::Qform,
                DAffine3::from_mat3_translation(m, t),
                at,
            )
        } else {
            let m = DMat3::from_diagonal(DVec3::from_array(d));
            (
                AffineSource::Pixdim,
                DAffine3::from_mat3_translation(m, DVec3::ZERO),
                h.pixdim[1].1,
            )
        }
    };
    if !crate::volume::is_invertible_affine(&affine) {
        let name = match source {
            AffineSource::Sform => "srow_x/srow_y/srow_z (sform)",
            AffineSource::Qform => "quatern_b/c/d, qoffset and pixdim (qform)",
            AffineSource::Pixdim => "pixdim",
        };
        return Err(header_error(
            field_at,
            format!("{name} give a voxel-to-world map that is not finite and invertible"),
        ));
    }
    Ok((affine, source))
}

/// The rotation of the NIfTI quaternion `(b, c, d)`, `a = √(1 − b² − c² − d²)`; a
/// quaternion whose `(b, c, d)` part has length 1 or more is normalised with `a = 0` (the
/// rule of the reference library `nifti1_io`).
fn quaternion_matrix(q: [f64; 3]) -> DMat3 {
    let [mut b, mut c, mut d] = q;
    let s = b * b + c * c + d * d;
    let a = if 1.0 - s < 1e-7 {
        let n = 1.0 / s.sqrt();
        b *= n;
        c *= n;
        d *= n;
        0.0
    } else {
        (1.0 - s).sqrt()
    };
    // Rows as the NIfTI-1 standard writes R; glam takes columns.
    DMat3::from_cols(
        DVec3::new(
            a * a + b * b - c * c - d * d,
            2.0 * (b * c + a * d),
            2.0 * (b * d - a * c),
        ),
        DVec3::new(
            2.0 * (b * c - a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d + a * b),
        ),
        DVec3::new(
            2.0 * (b * d + a * c),
            2.0 * (c * d - a * b),
            a * a + d * d - c * c - b * b,
        ),
    )
}

/// Where the voxels are, past the header.
struct Layout {
    data: VoxelData,
    /// Bytes of the first frame, and of all frames.
    frame_bytes: u64,
    data_bytes: u64,
    /// Bytes of the header proper (348 or 540); extensions lie between it and `data.start`.
    header_size: u64,
    /// Offset of `dim[1]`, where errors about the dimensions point.
    dims_at: usize,
}

/// Reads and checks the header, and checks the declared data against what the stream can
/// hold; reads nothing past the header.
fn read_header(stream: &mut VolumeStream<'_>) -> Result<(NiftiInfo, Layout), DecodeError> {
    let gzip = stream.gzip();
    let mut buf = [0u8; 540];
    let got = stream.fill(&mut buf[..4])?;
    if got == 0 {
        return Err(Failure::new(Location::Byte(0), Problem::EmptyFile).into());
    }
    if got < 4 {
        return Err(header_error(0, "file too short for a NIfTI header".into()));
    }
    let le = i32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]]);
    let be = i32::from_be_bytes([buf[0], buf[1], buf[2], buf[3]]);
    let (big, version, size) = match (le, be) {
        (348, _) => (false, 1u8, 348usize),
        (540, _) => (false, 2, 540),
        (_, 348) => (true, 1, 348),
        (_, 540) => (true, 2, 540),
        _ => {
            return Err(header_error(
                0,
                format!(
                    "sizeof_hdr is {le} (little-endian) / {be} (big-endian), not 348 (NIfTI-1) or 540 (NIfTI-2)"
                ),
            ));
        }
    };
    let got = stream.fill(&mut buf[4..size])?;
    if got < size - 4 {
        return Err(header_error(
            4 + got,
            format!("file ends inside the {size}-byte NIfTI-{version} header"),
        ));
    }
    let h = parse_header(&buf[..size], big, version)?;

    let (code, code_at) = h.datatype;
    let datatype = SampleType::from_nifti_code(code).ok_or_else(|| {
        header_error(
            code_at,
            format!(
                "datatype {code} is not supported (uint8, int8, int16, uint16, int32, uint32, float32, float64)"
            ),
        )
    })?;

    let (ndim, ndim_at) = h.dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(header_error(
            ndim_at,
            format!("dim[0] = {ndim} is not a dimension count in 1..=7"),
        ));
    }
    let mut extent = [1u64; 7];
    for axis in 1..=ndim as usize {
        let (n, at) = h.dim[axis];
        if n < 1 {
            return Err(header_error(
                at,
                format!("dim[{axis}] = {n} is not a positive size"),
            ));
        }
        extent[axis - 1] = n as u64;
    }
    let absurd = |what: String| header_error(h.dim[1].1, what);
    let voxels = extent[..3]
        .iter()
        .try_fold(1u64, |acc, &n| acc.checked_mul(n))
        .ok_or_else(|| absurd(format!("dims {:?} overflow", &extent[..3])))?;
    let frames = extent[3..]
        .iter()
        .try_fold(1u64, |acc, &n| acc.checked_mul(n))
        .ok_or_else(|| absurd(format!("dims {extent:?} overflow")))?;
    let frame_bytes = voxels
        .checked_mul(datatype.size() as u64)
        .ok_or_else(|| absurd(format!("dims {:?} overflow", &extent[..3])))?;
    let data_bytes = frame_bytes
        .checked_mul(frames)
        .ok_or_else(|| absurd(format!("dims {extent:?} overflow")))?;

    let (vox_offset_f, vox_at) = h.vox_offset;
    if !(vox_offset_f.is_finite()
        && vox_offset_f >= h.size as f64
        && vox_offset_f.fract() == 0.0
        && vox_offset_f < 2f64.powi(53))
    {
        return Err(header_error(
            vox_at,
            format!(
                "vox_offset = {vox_offset_f} is not a whole byte offset at or after the {}-byte header",
                h.size
            ),
        ));
    }
    let vox_offset = vox_offset_f as u64;
    let declared_end = vox_offset
        .checked_add(data_bytes)
        .ok_or_else(|| absurd(format!("dims {extent:?} overflow")))?;
    let scaling = (h.scl_slope.is_finite() && h.scl_slope != 0.0 && h.scl_inter.is_finite())
        .then_some((h.scl_slope, h.scl_inter))
        .filter(|&s| s != (1.0, 0.0));
    // NIfTI-1 slopes are f32, so a scaled value rounded to f32 loses nothing the file held;
    // NIfTI-2 slopes are f64.
    let decoder = SampleDecoder::new(datatype, big, scaling, version == 1);
    let data = VoxelData {
        dims: [extent[0], extent[1], extent[2]],
        frames,
        decoder,
        start: vox_offset,
    };
    let file_size = stream.file_size();
    if declared_end > stream.capacity() {
        if !gzip {
            return Err(data.truncated(file_size));
        }
        return Err(absurd(format!(
            "the header declares {} × {} × {} voxels × {frames} frame{} of {} from byte {vox_offset} ({declared_end} bytes), more than a {file_size}-byte gzip file can hold",
            extent[0],
            extent[1],
            extent[2],
            if frames == 1 { "" } else { "s" },
            datatype.name()
        )));
    }
    let dims = [extent[0], extent[1], extent[2]].map(usize::try_from);
    let [Ok(nx), Ok(ny), Ok(nz)] = dims else {
        return Err(absurd(format!(
            "dims {:?}: too large for this machine",
            &extent[..3]
        )));
    };

    let (affine, affine_source) = affine_of(&h)?;
    let m = affine.matrix3;
    let info = NiftiInfo {
        version,
        big_endian: big,
        gzip,
        datatype,
        dims: [nx, ny, nz],
        frames,
        voxel_size: DVec3::new(m.x_axis.length(), m.y_axis.length(), m.z_axis.length()),
        affine,
        affine_source,
        scaling,
        vox_offset,
        description: h.description,
        non_finite_voxels: 0,
    };
    let layout = Layout {
        data,
        frame_bytes,
        data_bytes,
        header_size: h.size as u64,
        dims_at: h.dim[1].1,
    };
    Ok((info, layout))
}

fn decode(
    stream: &mut VolumeStream<'_>,
    options: &ReadOptions,
) -> Result<(Volume, NiftiInfo), DecodeError> {
    let (info, layout) = read_header(stream)?;
    let data = &layout.data;
    data.check_memory(options.max_bytes)?;

    // Extensions between the header and the data are skipped.
    let gap = data.start - layout.header_size;
    if stream.skip(gap)? < gap {
        return Err(data.truncated(stream.offset()));
    }
    let mut values = data.read_values(stream)?;
    // The other frames are inflated (gzip) to check that they are all there, never kept.
    let rest = layout.data_bytes - layout.frame_bytes;
    if stream.skip(rest)? < rest {
        return Err(data.truncated(stream.offset()));
    }
    stream.expect_end()?;
    let mut info = info;
    info.non_finite_voxels = data.apply_non_finite(&mut values, options.non_finite)?;

    let volume = Volume::new(info.dims, values, info.affine)
        .map_err(|e| header_error(layout.dims_at, format!("invalid volume: {e}")))?;
    Ok((volume, info))
}
