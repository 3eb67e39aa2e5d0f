//! Reading a command's volume input under the command line's read options: errors for
//! people, and a warning when voxels were changed.

use std::path::Path;

use sphcover_core::Volume;
use sphcover_core::io::{self, VolumeInfo};

use crate::args::InputArgs;
use crate::memory_limit::MemoryLimit;
use crate::report::Reporter;

/// Reads the volume at `path` within `limit`; voxels that are not finite are refused, or
/// with `--drop-non-finite` set to the background with a warning.
pub fn read_volume(
    path: &Path,
    read: &InputArgs,
    limit: &MemoryLimit,
    reporter: &Reporter,
) -> anyhow::Result<(Volume, VolumeInfo)> {
    let (volume, info) =
        io::read_volume(path, &read.read_options(limit)).map_err(|e| limit.explain(e))?;
    let replaced = info.non_finite_voxels();
    if replaced > 0 {
        reporter.warn(&format!(
            "{}: {replaced} voxel{} holding NaN or an infinity set to the lowest finite value (background)",
            path.display(),
            if replaced == 1 { "" } else { "s" }
        ));
    }
    Ok((volume, info))
}
