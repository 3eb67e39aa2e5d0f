//! Volume files of any supported format: NIfTI (`.nii`, `.nii.gz`) and INRIMAGE-4 (`.inr`,
//! `.inr.gz`), with a description of the header that does not depend on the format.

use std::path::Path;

use super::error::{Failure, IoError};
use super::inrimage::{InrimageInfo, read_inrimage};
use super::nifti::{NiftiInfo, read_nifti};
use crate::volume::{Volume, VoxelValues};

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
/// otherwise (whose reader tells plain from gzip by content).
pub fn read_volume(path: &Path) -> Result<(Volume, VolumeInfo), IoError> {
    if is_inrimage_path(path) {
        read_inrimage(path).map(|(v, i)| (v, VolumeInfo::Inrimage(i)))
    } else {
        read_nifti(path).map(|(v, i)| (v, VolumeInfo::Nifti(i)))
    }
}

/// True when the name of `path` ends in `.nii`, `.nii.gz`, `.inr` or `.inr.gz`
/// (case-insensitive): the extensions a command-line tool should send to [`read_volume`].
pub fn is_volume_path(path: &Path) -> bool {
    let name = lowercase_name(path);
    name.ends_with(".nii") || name.ends_with(".nii.gz") || is_inrimage_path(path)
}

/// A failure while decoding a volume file: a problem in the content, or an operating-system
/// read error (of the file, or of the gzip stream inside it).
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

/// The type of the samples a volume file stores (NIfTI `datatype`, INRIMAGE `TYPE` and
/// `PIXSIZE`): every reader decodes through `decode_samples`.
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

/// Decodes raw samples and applies `value = slope · stored + intercept` when `scaling` is
/// given. The result is stored as `f32` when that loses nothing: the type fits `f32` and
/// either there is no scaling or `scaled_fits_f32` says the scaled values were only ever
/// `f32`-precise (NIfTI-1 stores its slope and intercept as `f32`).
pub(crate) fn decode_samples(
    data: &[u8],
    sample_type: SampleType,
    big_endian: bool,
    scaling: Option<(f64, f64)>,
    scaled_fits_f32: bool,
) -> VoxelValues {
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
    let scale = |v: f64| match scaling {
        Some((slope, inter)) => v * slope + inter,
        None => v,
    };
    let narrow = sample_type.fits_f32() && (scaling.is_none() || scaled_fits_f32);
    macro_rules! values {
        ($t:ty) => {
            if narrow {
                VoxelValues::F32(raw!($t).map(|v| scale(f64::from(v)) as f32).collect())
            } else {
                VoxelValues::F64(raw!($t).map(|v| scale(f64::from(v))).collect())
            }
        };
    }
    match sample_type {
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
