//! Why a skeletal sheet could not be extracted.

use sphcover_core::ParameterError;
use sphcover_core::{CoverError, Stopped, VolumeCoverError, VolumeError};
use sphcover_tetra::TetraError;

/// Why [`crate::extract_skeleton`] or [`crate::nms_skeleton`] failed. Every variant is a
/// property of the input or the parameters, except the wrapped lower-layer failures.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SkeletonError {
    /// No voxel value is finite.
    #[error("no voxel value is finite")]
    NoFiniteValue,
    /// Every finite voxel has the same value: there is no object to find.
    #[error("the volume is constant (every voxel is {value})")]
    ConstantVolume {
        /// The value.
        value: f64,
    },
    /// The threshold leaves no voxel above it.
    #[error("threshold {threshold} selects no voxel (values range over [{min}, {max}]): lower it")]
    ThresholdSelectsNothing {
        /// The threshold in the volume's units.
        threshold: f64,
        /// Smallest finite value.
        min: f64,
        /// Largest finite value.
        max: f64,
    },
    /// The threshold leaves no background voxel: a sheet is the middle of a thin object
    /// surrounded by background.
    #[error(
        "threshold {threshold} selects every voxel (values range over [{min}, {max}]): raise it"
    )]
    ThresholdSelectsEverything {
        /// The threshold in the volume's units.
        threshold: f64,
        /// Smallest finite value.
        min: f64,
        /// Largest finite value.
        max: f64,
    },
    /// A material was asked for, but the volume does not look like a CT in Hounsfield units.
    #[error(
        "--material {material} needs a CT in Hounsfield units (a histogram with air near -1000 and soft tissue near 0); give the threshold instead"
    )]
    NotHounsfield {
        /// The material asked for.
        material: &'static str,
    },
    /// A parameter is out of its domain.
    #[error(transparent)]
    InvalidParameter(#[from] ParameterError),
    /// A stage found nothing, so there is no sheet to output.
    #[error("empty result: {stage} found nothing ({hint})")]
    EmptyResult {
        /// The stage that came up empty.
        stage: &'static str,
        /// What usually causes it.
        hint: &'static str,
    },
    /// The volume could not be resampled to near-cubic voxels (its refined grid would have
    /// more voxels than memory can index).
    #[error("resampling to near-cubic voxels: {0}")]
    Resampling(#[from] VolumeError),
    /// The volume cover could not be built.
    #[error("volume cover: {0}")]
    Cover(#[from] VolumeCoverError),
    /// The evaluator of the cover could not be built.
    #[error("evaluator: {0}")]
    Evaluator(#[from] CoverError),
    /// The tetrahedral mesh could not be built.
    #[error("tetrahedral mesh: {0}")]
    Tetra(#[from] TetraError),
    /// Smoothing the derivatives over the supports failed (graph or solver).
    #[error("derivative smoothing: {0}")]
    Smoothing(String),
    /// The caller asked the pipeline to stop ([`crate::extract_skeleton_until`]).
    #[error(transparent)]
    Stopped(#[from] Stopped),
}
