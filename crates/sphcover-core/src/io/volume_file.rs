//! Volume files of any supported format: NIfTI (`.nii`, `.nii.gz`) and INRIMAGE-4 (`.inr`,
//! `.inr.gz`), with a description of the header that does not depend on the format, and what
//! the format readers share: the byte stream (plain or gzip), the memory check and the sample
//! decoder.
//!
//! Both readers take the same steps, so that no file makes them allocate more than the
//! memory limit or than the file can hold:
//!
//! 1. The header is read from the first bytes of the stream (a gzip stream is inflated only
//!    that far).
//! 2. The declared data is checked against what the file can hold: its size when plain; what
//!    DEFLATE can expand its size to (1032:1) when gzip.
//! 3. The voxels' size in memory is checked against
//!    [`ReadOptions::max_bytes`](super::ReadOptions::max_bytes).
//! 4. The values are allocated once, at exactly the declared count, and filled as the
//!    stream is decoded in 1 MiB pieces: the raw data is never held whole.
//! 5. A gzip stream must end where the header says the data ends; one that inflates further
//!    is refused after one byte too many, not after inflating the rest.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use glam::{DAffine3, DMat3, DVec3};

use super::ReadOptions;
use super::byte_size::format_byte_size;
use super::error::{Failure, IoError, Location, MemoryBudget};
use super::inrimage::{InrimageInfo, read_inrimage, read_inrimage_info};
use super::nifti::{NiftiInfo, read_nifti, read_nifti_info};
use crate::volume::{Volume, VoxelValues};

/// DEFLATE cannot expand data by more than this ratio (a 258-byte match costs at least two
/// bits), so a gzip file declaring more is refused before decompressing.
const MAX_DEFLATE_RATIO: u64 = 1032;
/// Raw bytes decoded per piece: large enough that per-read costs vanish, small enough to
/// stay in cache; a multiple of every sample size.
const PIECE: usize = 1 << 20;

/// What the header of a volume file declares.
#[derive(Clone, Debug, PartialEq)]
pub enum VolumeInfo {
    /// A NIfTI-1 or NIfTI-2 file.
    Nifti(NiftiInfo),
    /// An INRIMAGE-4 file.
    Inrimage(InrimageInfo),
}

impl VolumeInfo {
    /// The format with its variant, e.g. `"NIfTI-1 little-endian, gzip"`,
    /// `"INRIMAGE-4 big-endian"`.
    pub fn format_description(&self) -> String {
        let (name, big, gzip) = match self {
            VolumeInfo::Nifti(i) => (format!("NIfTI-{}", i.version), i.big_endian, i.gzip),
            VolumeInfo::Inrimage(i) => ("INRIMAGE-4".to_string(), i.big_endian, i.gzip),
        };
        format!(
            "{name} {}{}",
            if big { "big-endian" } else { "little-endian" },
            if gzip { ", gzip" } else { "" }
        )
    }

    /// The stored sample type (`"uint8"`, `"int16"`, `"float32"`, …).
    pub fn datatype_name(&self) -> &'static str {
        match self {
            VolumeInfo::Nifti(i) => i.datatype.name(),
            VolumeInfo::Inrimage(i) => i.sample_type.name(),
        }
    }

    /// Number of 3D frames in the file (only the first is read); 1 for INRIMAGE.
    pub fn frames(&self) -> u64 {
        match self {
            VolumeInfo::Nifti(i) => i.frames,
            VolumeInfo::Inrimage(_) => 1,
        }
    }

    /// Which header fields the voxel→world map came from (`"Sform"`, `"Qform"`,
    /// `"Pixdim"` for NIfTI, `"VX VY VZ, TX TY TZ"` for INRIMAGE).
    pub fn axes_source(&self) -> String {
        match self {
            VolumeInfo::Nifti(i) => format!("{:?}", i.affine_source),
            VolumeInfo::Inrimage(_) => "VX VY VZ, TX TY TZ".to_string(),
        }
    }

    /// `(slope, intercept)` when the stored values were scaled.
    pub fn scaling(&self) -> Option<(f64, f64)> {
        match self {
            VolumeInfo::Nifti(i) => i.scaling,
            VolumeInfo::Inrimage(_) => None,
        }
    }

    /// Free text of the header (NIfTI `descrip`; INRIMAGE comment lines joined by `"; "`).
    pub fn description(&self) -> String {
        match self {
            VolumeInfo::Nifti(i) => i.description.clone(),
            VolumeInfo::Inrimage(i) => i.comments.join("; "),
        }
    }

    /// Voxels found holding NaN or an infinity, handled as
    /// [`ReadOptions::non_finite`](super::ReadOptions::non_finite) says (0 when only the
    /// header was read).
    pub fn non_finite_voxels(&self) -> u64 {
        match self {
            VolumeInfo::Nifti(i) => i.non_finite_voxels,
            VolumeInfo::Inrimage(i) => i.non_finite_voxels,
        }
    }

    /// Grid dimensions `[nx, ny, nz]` (of the first frame).
    pub fn dims(&self) -> [usize; 3] {
        match self {
            VolumeInfo::Nifti(i) => i.dims,
            VolumeInfo::Inrimage(i) => i.dims,
        }
    }

    /// The voxel→world map, as [`Volume::affine`] of the volume the file holds.
    pub fn affine(&self) -> DAffine3 {
        match self {
            VolumeInfo::Nifti(i) => i.affine,
            VolumeInfo::Inrimage(i) => {
                DAffine3::from_mat3_translation(DMat3::from_diagonal(i.voxel_size), i.origin)
            }
        }
    }

    /// Voxel edge lengths in world units, as [`Volume::voxel_size`].
    pub fn voxel_size(&self) -> DVec3 {
        match self {
            VolumeInfo::Nifti(i) => i.voxel_size,
            VolumeInfo::Inrimage(i) => i.voxel_size,
        }
    }
}

/// The lowercase file name of `path`.
fn lowercase_name(path: &Path) -> String {
    path.file_name()
        .and_then(|n| n.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default()
}

fn is_inrimage_path(path: &Path) -> bool {
    let name = lowercase_name(path);
    name.ends_with(".inr") || name.ends_with(".inr.gz")
}

/// Reads a volume file: INRIMAGE-4 when its name ends in `.inr` or `.inr.gz`, NIfTI
/// otherwise (whose reader tells plain from gzip by content). A volume whose values would
/// take more than `options.max_bytes` is refused from its header with
/// [`IoError::OverMemoryLimit`].
pub fn read_volume(path: &Path, options: &ReadOptions) -> Result<(Volume, VolumeInfo), IoError> {
    if is_inrimage_path(path) {
        read_inrimage(path, options).map(|(v, i)| (v, VolumeInfo::Inrimage(i)))
    } else {
        read_nifti(path, options).map(|(v, i)| (v, VolumeInfo::Nifti(i)))
    }
}

/// Reads only the header of a volume file (chosen as [`read_volume`] does), with the same
/// checks of the header and of the declared size against the file's, and allocates nothing
/// in proportion to the voxels: what a caller needs to decide whether to read the voxels.
pub fn read_volume_info(path: &Path) -> Result<VolumeInfo, IoError> {
    if is_inrimage_path(path) {
        read_inrimage_info(path).map(VolumeInfo::Inrimage)
    } else {
        read_nifti_info(path).map(VolumeInfo::Nifti)
    }
}

/// True when the name of `path` ends in `.nii`, `.nii.gz`, `.inr` or `.inr.gz`
/// (case-insensitive): the extensions a command-line tool should send to [`read_volume`].
pub fn is_volume_path(path: &Path) -> bool {
    let name = lowercase_name(path);
    name.ends_with(".nii") || name.ends_with(".nii.gz") || is_inrimage_path(path)
}

/// A failure while decoding a volume file: a problem in the content (or a size over the
/// limit), or an operating-system read error (of the file, or of the gzip stream inside it).
pub(crate) enum DecodeError {
    Content(Failure),
    Os(std::io::Error),
}

impl DecodeError {
    pub(crate) fn into_io(self, path: &Path) -> IoError {
        match self {
            DecodeError::Content(f) => f.into_io(path),
            DecodeError::Os(source) => IoError::Read {
                path: path.to_path_buf(),
                source,
            },
        }
    }
}

impl From<Failure> for DecodeError {
    fn from(f: Failure) -> DecodeError {
        DecodeError::Content(f)
    }
}

/// The decompressed bytes of a volume file, counted from its first byte.
pub(crate) struct VolumeStream<'a> {
    inner: Box<dyn Read + 'a>,
    /// Bytes delivered so far: the offset of the next byte in the (decompressed) stream.
    offset: u64,
    gzip: bool,
    /// Size of the file as stored (compressed when gzip).
    file_size: u64,
}

impl VolumeStream<'static> {
    /// Opens a file, telling gzip from plain by its first two bytes.
    pub(crate) fn open(path: &Path) -> Result<VolumeStream<'static>, IoError> {
        let read_error = |source| IoError::Read {
            path: path.to_path_buf(),
            source,
        };
        let file = File::open(path).map_err(read_error)?;
        let file_size = file.metadata().map_err(read_error)?.len();
        let mut reader = BufReader::with_capacity(1 << 16, file);
        let gzip = std::io::BufRead::fill_buf(&mut reader)
            .map_err(read_error)?
            .starts_with(&[0x1f, 0x8b]);
        let inner: Box<dyn Read> = if gzip {
            Box::new(flate2::read::MultiGzDecoder::new(reader))
        } else {
            Box::new(reader)
        };
        Ok(VolumeStream {
            inner,
            offset: 0,
            gzip,
            file_size,
        })
    }
}

impl<'a> VolumeStream<'a> {
    /// The stream of a file held in memory.
    pub(crate) fn from_bytes(bytes: &'a [u8]) -> VolumeStream<'a> {
        let gzip = bytes.starts_with(&[0x1f, 0x8b]);
        let inner: Box<dyn Read + 'a> = if gzip {
            Box::new(flate2::read::MultiGzDecoder::new(bytes))
        } else {
            Box::new(bytes)
        };
        VolumeStream {
            inner,
            offset: 0,
            gzip,
            file_size: bytes.len() as u64,
        }
    }

    pub(crate) fn gzip(&self) -> bool {
        self.gzip
    }

    pub(crate) fn file_size(&self) -> u64 {
        self.file_size
    }

    /// Offset of the next byte in the decompressed stream.
    pub(crate) fn offset(&self) -> u64 {
        self.offset
    }

    /// The most bytes the stream can deliver: the file size when plain, what DEFLATE can
    /// expand it to when gzip (plus room for the gzip header's optional fields).
    pub(crate) fn capacity(&self) -> u64 {
        if self.gzip {
            self.file_size
                .saturating_mul(MAX_DEFLATE_RATIO)
                .saturating_add(1024)
        } else {
            self.file_size
        }
    }

    /// Reads up to `buf.len()` bytes, stopping early only at the end of the stream; returns
    /// how many were read.
    pub(crate) fn fill(&mut self, buf: &mut [u8]) -> Result<usize, DecodeError> {
        let mut done = 0;
        while done < buf.len() {
            match self.inner.read(&mut buf[done..]) {
                Ok(0) => break,
                Ok(n) => {
                    done += n;
                    self.offset += n as u64;
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(self.stream_error(e)),
            }
        }
        Ok(done)
    }

    /// Skips up to `n` bytes; returns how many were skipped.
    pub(crate) fn skip(&mut self, n: u64) -> Result<u64, DecodeError> {
        let mut scratch = [0u8; 1 << 14];
        let mut left = n;
        while left > 0 {
            let chunk = left.min(scratch.len() as u64) as usize;
            let got = self.fill(&mut scratch[..chunk])?;
            if got == 0 {
                break;
            }
            left -= got as u64;
        }
        Ok(n - left)
    }

    /// After the declared data: a gzip stream must end here. One more byte is inflated to
    /// tell, never the rest, so a stream that goes on for gigabytes costs no more than one
    /// that ends. (Bytes after the data of a plain file are not read: they cost nothing.)
    pub(crate) fn expect_end(&mut self) -> Result<(), DecodeError> {
        if !self.gzip {
            return Ok(());
        }
        let end = self.offset;
        let mut probe = [0u8; 1];
        if self.fill(&mut probe)? > 0 {
            return Err(Failure::syntax(
                Location::Byte(end),
                format!(
                    "the gzip stream goes on after the {end} bytes of header and data the header declares"
                ),
            )
            .into());
        }
        Ok(())
    }

    /// A corrupt gzip stream is a content problem; a failing disk is not.
    fn stream_error(&self, e: std::io::Error) -> DecodeError {
        let corrupt = self.gzip
            && matches!(
                e.kind(),
                std::io::ErrorKind::InvalidData
                    | std::io::ErrorKind::InvalidInput
                    | std::io::ErrorKind::UnexpectedEof
            );
        if corrupt {
            DecodeError::Content(Failure::syntax(
                Location::Byte(self.offset),
                format!("corrupt gzip stream: {e}"),
            ))
        } else {
            DecodeError::Os(e)
        }
    }
}

/// The voxel data a header declares, as far as reading it is concerned.
pub(crate) struct VoxelData {
    /// Voxels of the first frame, `dims[0] · dims[1] · dims[2]`.
    pub dims: [u64; 3],
    /// Frames in the file (only the first is read).
    pub frames: u64,
    /// How the samples are decoded.
    pub decoder: SampleDecoder,
    /// Stream offset of the first sample.
    pub start: u64,
}

impl VoxelData {
    fn voxels(&self) -> u64 {
        self.dims.iter().product()
    }

    /// Bytes of the values in memory, for the memory check.
    pub(crate) fn memory_bytes(&self) -> u64 {
        self.voxels()
            .saturating_mul(self.decoder.value_size() as u64)
    }

    /// Refuses data whose values would take more than `limit` bytes.
    pub(crate) fn check_memory(&self, limit: Option<u64>) -> Result<(), Failure> {
        MemoryBudget::new(limit).reserve(self.memory_bytes(), || {
            let [nx, ny, nz] = self.dims;
            let sample = self.decoder.sample_type;
            let frames = if self.frames > 1 {
                format!("the first of {} frames; ", self.frames)
            } else {
                String::new()
            };
            format!(
                "{nx} x {ny} x {nz} voxels of {} ({frames}{} decoded, held as {})",
                sample.name(),
                format_byte_size(self.voxels().saturating_mul(sample.size() as u64)),
                self.decoder.value_type_name()
            )
        })
    }

    /// Applies the non-finite `policy` to the first frame's `values` (see
    /// [`NonFinitePolicy`](super::NonFinitePolicy)); returns how many voxels were not finite.
    pub(crate) fn apply_non_finite(
        &self,
        values: &mut VoxelValues,
        policy: super::NonFinitePolicy,
    ) -> Result<u64, Failure> {
        super::non_finite::apply_to_voxels(values, policy)
            .map(|found| found.count)
            .map_err(|found| {
                let first = found.first.unwrap_or(0) as u64;
                let [nx, ny, _] = self.dims;
                Failure::NonFiniteVoxels {
                    voxel: [first % nx, first / nx % ny, first / (nx * ny)].map(|c| c as usize),
                    count: found.count,
                    all: found.count == self.voxels(),
                }
            })
    }

    /// The error for data ending at stream offset `end` before the declared voxels.
    pub(crate) fn truncated(&self, end: u64) -> DecodeError {
        let sample = self.decoder.sample_type;
        DecodeError::Content(Failure::new(
            Location::Byte(end),
            super::error::Problem::Truncated {
                element: format!("{} voxel", sample.name()),
                index: end.saturating_sub(self.start) / sample.size() as u64,
                declared: self.voxels().saturating_mul(self.frames),
            },
        ))
    }

    /// Reads the first frame's values from `stream`, which stands at `start`: one
    /// allocation of exactly the declared count, filled piece by piece. The caller has
    /// checked the size against the file and the memory limit.
    pub(crate) fn read_values(
        &self,
        stream: &mut VolumeStream<'_>,
    ) -> Result<VoxelValues, DecodeError> {
        let out_of_memory = || Failure::OutOfMemory {
            what: format!("{} voxel values", self.voxels()),
            bytes: self.memory_bytes(),
        };
        let sample_size = self.decoder.sample_type.size();
        // Both fit in `usize` on 64-bit targets once the size was checked against the file.
        let voxels = usize::try_from(self.voxels()).map_err(|_| out_of_memory())?;
        let total = voxels.checked_mul(sample_size).ok_or_else(out_of_memory)?;
        let mut values = self.decoder.allocate(voxels).map_err(|_| out_of_memory())?;
        let mut piece = vec![0u8; total.min(PIECE)];
        let mut done = 0;
        while done < total {
            let want = (total - done).min(PIECE);
            let got = stream.fill(&mut piece[..want])?;
            if got < want {
                return Err(self.truncated(stream.offset()));
            }
            self.decoder.extend(&piece[..want], &mut values);
            done += want;
        }
        Ok(values)
    }
}

/// The type of the samples a volume file stores (NIfTI `datatype`, INRIMAGE `TYPE` and
/// `PIXSIZE`): every reader decodes through `SampleDecoder`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SampleType {
    /// Unsigned 8-bit integer.
    U8,
    /// Signed 8-bit integer.
    I8,
    /// Unsigned 16-bit integer.
    U16,
    /// Signed 16-bit integer.
    I16,
    /// Unsigned 32-bit integer.
    U32,
    /// Signed 32-bit integer.
    I32,
    /// 32-bit float.
    F32,
    /// 64-bit float.
    F64,
}

impl SampleType {
    /// Bytes per sample.
    pub fn size(self) -> usize {
        match self {
            SampleType::U8 | SampleType::I8 => 1,
            SampleType::U16 | SampleType::I16 => 2,
            SampleType::U32 | SampleType::I32 | SampleType::F32 => 4,
            SampleType::F64 => 8,
        }
    }

    /// Name for messages (`"uint8"`, `"float32"`, …).
    pub fn name(self) -> &'static str {
        match self {
            SampleType::U8 => "uint8",
            SampleType::I8 => "int8",
            SampleType::U16 => "uint16",
            SampleType::I16 => "int16",
            SampleType::U32 => "uint32",
            SampleType::I32 => "int32",
            SampleType::F32 => "float32",
            SampleType::F64 => "float64",
        }
    }

    /// True when every value of the type is exactly an `f32` (up to 16-bit integers, f32).
    fn fits_f32(self) -> bool {
        matches!(
            self,
            SampleType::U8 | SampleType::I8 | SampleType::U16 | SampleType::I16 | SampleType::F32
        )
    }
}

/// Decodes raw samples and applies `value = slope · stored + intercept` when there is
/// scaling. The values are stored as `f32` when that loses nothing: the type fits `f32` and
/// either there is no scaling or the scaled values were only ever `f32`-precise (NIfTI-1
/// stores its slope and intercept as `f32`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct SampleDecoder {
    pub sample_type: SampleType,
    big_endian: bool,
    scaling: Option<(f64, f64)>,
    narrow: bool,
}

impl SampleDecoder {
    pub(crate) fn new(
        sample_type: SampleType,
        big_endian: bool,
        scaling: Option<(f64, f64)>,
        scaled_fits_f32: bool,
    ) -> SampleDecoder {
        SampleDecoder {
            sample_type,
            big_endian,
            scaling,
            narrow: sample_type.fits_f32() && (scaling.is_none() || scaled_fits_f32),
        }
    }

    /// Bytes of one value in memory.
    pub(crate) fn value_size(&self) -> usize {
        if self.narrow { 4 } else { 8 }
    }

    /// `"float32"` or `"float64"`, for messages.
    pub(crate) fn value_type_name(&self) -> &'static str {
        if self.narrow { "float32" } else { "float64" }
    }

    /// Empty values with room for exactly `count`, or the allocator's refusal.
    fn allocate(&self, count: usize) -> Result<VoxelValues, std::collections::TryReserveError> {
        Ok(if self.narrow {
            let mut v = Vec::new();
            v.try_reserve_exact(count)?;
            VoxelValues::F32(v)
        } else {
            let mut v = Vec::new();
            v.try_reserve_exact(count)?;
            VoxelValues::F64(v)
        })
    }

    /// Decodes whole samples of `data` and appends them to `out` (made by `allocate`).
    fn extend(&self, data: &[u8], out: &mut VoxelValues) {
        let big_endian = self.big_endian;
        macro_rules! raw {
            ($t:ty) => {{
                const N: usize = std::mem::size_of::<$t>();
                data.chunks_exact(N).map(move |c| {
                    let mut a = [0u8; N];
                    a.copy_from_slice(c);
                    if big_endian {
                        <$t>::from_be_bytes(a)
                    } else {
                        <$t>::from_le_bytes(a)
                    }
                })
            }};
        }
        let scaling = self.scaling;
        let scale = move |v: f64| match scaling {
            Some((slope, inter)) => v * slope + inter,
            None => v,
        };
        macro_rules! values {
            ($t:ty) => {
                match out {
                    VoxelValues::F32(v) => v.extend(raw!($t).map(|x| scale(f64::from(x)) as f32)),
                    VoxelValues::F64(v) => v.extend(raw!($t).map(|x| scale(f64::from(x)))),
                }
            };
        }
        match self.sample_type {
            SampleType::U8 => values!(u8),
            SampleType::I8 => values!(i8),
            SampleType::U16 => values!(u16),
            SampleType::I16 => values!(i16),
            SampleType::U32 => values!(u32),
            SampleType::I32 => values!(i32),
            SampleType::F32 => values!(f32),
            SampleType::F64 => values!(f64),
        }
    }
}
