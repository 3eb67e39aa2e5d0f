//! `sphcover skeleton --max-memory`: the predicted peak of the ridge pipeline from the number
//! of voxels, checked from the volume's header before its voxels are read. The grid is the
//! input's, so there is no coarser parameter to fall back on: a run over budget is refused
//! with the estimate. Without `--max-memory` the budget is all the memory the process may
//! use ([`process_memory`]): a run predicted above it cannot finish, and would end in a
//! failed allocation deep in the pipeline.

use crate::args::{SkeletonArgs, SkeletonMethod};
use crate::exit::BadInput;
use crate::report::Reporter;
use sphcover_core::io::format_byte_size;
use sphcover_core::{ProcessMemory, process_memory};

/// Peak memory of `sphcover skeleton` (ridge method, default parameters): bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkeletonMemoryModel {
    /// Bytes whatever the input.
    pub base_bytes: f64,
    /// Bytes per voxel of the input grid (its values, the volume in f64, masks, the
    /// intensity model; the cover and tetrahedral mesh of a thin part, a few percent of the
    /// grid, scale with it in the measured phantoms).
    pub bytes_per_voxel: f64,
}

/// Fitted to the peak resident set size of four phantoms, 64³ to 256³
/// (`docs/benchmarks.md`, *Memory*); every run within 7.3% of it.
pub const SKELETON_MEMORY_MODEL: SkeletonMemoryModel = SkeletonMemoryModel {
    base_bytes: 7.53e6,
    bytes_per_voxel: 29.8,
};

impl SkeletonMemoryModel {
    /// The predicted peak, in bytes, for a grid of `voxels` voxels.
    pub fn peak_bytes(&self, voxels: usize) -> u64 {
        let bytes = self.base_bytes + self.bytes_per_voxel * voxels as f64;
        bytes.max(0.0).min(u64::MAX as f64) as u64
    }
}

/// Refuses the run (bad usage, exit 2) when `--max-memory`, or without it the memory of the
/// process, is below the predicted peak for a grid of `dims` voxels.
pub fn check_budget(
    args: &SkeletonArgs,
    dims: [usize; 3],
    reporter: &Reporter,
) -> anyhow::Result<()> {
    let Some(budget) = args.max_memory else {
        if args.method == SkeletonMethod::Ridge
            && let Some(memory) = process_memory()
        {
            check_memory(args, dims, &memory)?;
        }
        return Ok(());
    };
    if args.method != SkeletonMethod::Ridge {
        return Err(BadInput(
            "--max-memory: the memory model covers --method ridge only".to_owned(),
        )
        .into());
    }
    let [nx, ny, nz] = dims;
    let voxels = nx.saturating_mul(ny).saturating_mul(nz);
    let estimate = SKELETON_MEMORY_MODEL.peak_bytes(voxels);
    if estimate > budget {
        return Err(BadInput(format!(
            "--max-memory {}: extracting the sheet of {nx} x {ny} x {nz} voxels needs about {}; \
             raise the budget or crop the volume",
            format_byte_size(budget),
            format_byte_size(estimate)
        ))
        .into());
    }
    reporter.detail(&format!(
        "  memory: predicted peak {}, within --max-memory {}",
        format_byte_size(estimate),
        format_byte_size(budget)
    ));
    Ok(())
}

/// Refuses a run predicted above all the memory the process may use.
fn check_memory(
    args: &SkeletonArgs,
    dims: [usize; 3],
    memory: &ProcessMemory,
) -> anyhow::Result<()> {
    let [nx, ny, nz] = dims;
    let estimate = SKELETON_MEMORY_MODEL.peak_bytes(nx.saturating_mul(ny).saturating_mul(nz));
    if estimate > memory.bytes {
        return Err(BadInput(format!(
            "{}: extracting the sheet of {nx} x {ny} x {nz} voxels needs about {}, more than {}; \
             crop the volume, or pass --max-memory to try anyway",
            args.input.display(),
            format_byte_size(estimate),
            memory.describe()
        ))
        .into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Grid edge and peak RSS in KiB of the runs the model was fitted to.
    const MEASURED: [(usize, u64); 4] =
        [(64, 14_812), (128, 73_816), (192, 207_456), (256, 483_148)];

    #[test]
    fn the_model_reproduces_the_measured_runs_within_8_percent() {
        for (n, kib) in MEASURED {
            let predicted = SKELETON_MEMORY_MODEL.peak_bytes(n * n * n) as f64;
            let error = predicted / (kib * 1024) as f64 - 1.0;
            assert!(error.abs() < 0.08, "{n}³: {error:+.3}");
        }
    }
}
