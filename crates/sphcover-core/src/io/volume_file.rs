//! Volume files of any supported format: NIfTI (`.nii`, `.nii.gz`) and INRIMAGE-4 (`.inr`,
//! `.inr.gz`), with a description of the header that does not depend on the format.

use std::path::Path;

use super::error::{Failure, IoError};
use super::inrimage::{InrimageInfo, read_inrimage};
use super::nifti::{NiftiInfo, read_nifti};
use crate::volume::Volume;

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
