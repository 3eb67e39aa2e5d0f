//! `sphcover skeleton --max-memory`: the predicted peak of the ridge pipeline from the number
//! of voxels, checked from the volume's header before its voxels are read. The grid is the
//! input's, so there is no coarser parameter to fall back on: a run over budget is refused
//! with the estimate. Without `--max-memory` the budget is all the memory the process may
//! use ([`process_memory`]): a run predicted above it cannot finish, and would end in a
//! failed allocation deep in the pipeline. A grid too anisotropic to process directly is
//! resampled first, so the prediction is for the resampled grid, with the input's values
//! held beside it.

use crate::args::{SkeletonArgs, SkeletonMethod};
use crate::exit::BadInput;
use crate::report::Reporter;
use sphcover_core::io::format_byte_size;
use sphcover_core::{ProcessMemory, process_memory};
use sphcover_skeleton::Resampling;

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

/// The same for a CT in Hounsfield units, whose material is windowed: the material stage
/// holds the volume smoothed and the squared depths of two masks (f64 each) beside the
/// input, and the windowed copy stays for the stages after it. Fitted to the generated head
/// CT on 1.5, 2.9 and 4.8 mm slices (`docs/benchmarks.md`, *Memory*) for the smallest
/// largest error: every run within 11%. The 4.8 mm grid costs more per processed voxel
/// than the others (its cover and tetrahedra, not its voxels), which one rate per voxel
/// cannot follow.
pub const CT_MEMORY_MODEL: SkeletonMemoryModel = SkeletonMemoryModel {
    base_bytes: 7.53e6,
    bytes_per_voxel: 51.4,
};

/// Whether the file stores integers of 16 bits or more, as CT scanners store Hounsfield
/// units: the header's best guess that the material stage will run.
pub fn stores_ct(header: &sphcover_core::io::VolumeInfo) -> bool {
    let name = header.datatype_name();
    (name.starts_with("int") || name.starts_with("uint")) && !name.ends_with('8')
}

impl SkeletonMemoryModel {
    /// The predicted peak, in bytes, for a grid of `voxels` voxels.
    pub fn peak_bytes(&self, voxels: usize) -> u64 {
        let bytes = self.base_bytes + self.bytes_per_voxel * voxels as f64;
        bytes.max(0.0).min(u64::MAX as f64) as u64
    }
}

/// The grid the pipeline runs on: the input's, or the input's resampled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkeletonGrid {
    /// Dimensions of the input grid.
    pub input: [usize; 3],
    /// Dimensions of the grid the stages run on (the input's unless resampled).
    pub processed: [usize; 3],
    /// Predicted with [`CT_MEMORY_MODEL`]: the volume will likely be windowed to a material.
    pub ct: bool,
}

impl SkeletonGrid {
    /// The grid of an input of `dims` voxels resampled as `resampling` says, of a CT when
    /// `ct`.
    pub fn new(dims: [usize; 3], resampling: Option<&Resampling>, ct: bool) -> SkeletonGrid {
        SkeletonGrid {
            input: dims,
            processed: resampling.map_or(dims, |r| r.dims(dims)),
            ct,
        }
    }

    /// The predicted peak in bytes: the model's for the processed grid, plus the input's
    /// values (at most 8 bytes each) when the stages run on a resampled copy, and for a CT
    /// the input windowed to its material (4 bytes each), which the slice centroids read.
    pub fn peak_bytes(&self) -> u64 {
        let voxels = |[nx, ny, nz]: [usize; 3]| nx.saturating_mul(ny).saturating_mul(nz);
        let model = if self.ct {
            CT_MEMORY_MODEL
        } else {
            SKELETON_MEMORY_MODEL
        };
        let peak = model.peak_bytes(voxels(self.processed));
        if self.processed == self.input {
            return peak;
        }
        let input = voxels(self.input) as u64;
        let windowed = if self.ct { size_of::<f32>() } else { 0 };
        peak.saturating_add(input.saturating_mul((size_of::<f64>() + windowed) as u64))
    }
}

impl std::fmt::Display for SkeletonGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [nx, ny, nz] = self.processed;
        write!(f, "{nx} x {ny} x {nz} voxels")?;
        if self.processed != self.input {
            let [nx, ny, nz] = self.input;
            write!(f, " (resampled from {nx} x {ny} x {nz})")?;
        }
        Ok(())
    }
}

/// Refuses the run (bad usage, exit 2) when `--max-memory`, or without it the memory of the
/// process, is below the predicted peak for `grid`.
pub fn check_budget(
    args: &SkeletonArgs,
    grid: SkeletonGrid,
    reporter: &Reporter,
) -> anyhow::Result<()> {
    let Some(budget) = args.max_memory else {
        if args.method == SkeletonMethod::Ridge
            && let Some(memory) = process_memory()
        {
            check_memory(args, grid, &memory)?;
        }
        return Ok(());
    };
    if args.method != SkeletonMethod::Ridge {
        return Err(BadInput(
            "--max-memory: the memory model covers --method ridge only".to_owned(),
        )
        .into());
    }
    let estimate = grid.peak_bytes();
    if estimate > budget {
        return Err(BadInput(format!(
            "--max-memory {}: extracting the sheet of {grid} needs about {}; \
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
    grid: SkeletonGrid,
    memory: &ProcessMemory,
) -> anyhow::Result<()> {
    let estimate = grid.peak_bytes();
    if estimate > memory.bytes {
        return Err(BadInput(format!(
            "{}: extracting the sheet of {grid} needs about {}, more than {}; \
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

    /// The head CT's grids (input, processed) and peak RSS in MiB.
    const MEASURED_CT: [([usize; 3], [usize; 3], u64); 3] = [
        ([256, 256, 108], [256, 256, 108], 320),
        ([256, 256, 56], [256, 256, 111], 374),
        ([256, 256, 34], [256, 256, 100], 396),
    ];

    #[test]
    fn the_ct_model_reproduces_the_head_ct_within_11_percent() {
        for (input, processed, mib) in MEASURED_CT {
            let grid = SkeletonGrid {
                input,
                processed,
                ct: true,
            };
            let error = grid.peak_bytes() as f64 / (mib << 20) as f64 - 1.0;
            assert!(error.abs() < 0.11, "{input:?}: {error:+.3}");
        }
    }

    #[test]
    fn a_resampled_grid_is_predicted_with_the_input_beside_it() {
        let size = sphcover_core::DVec3::new(0.5, 0.5, 2.5);
        let resampling = Resampling::of(size).unwrap();
        let grid = SkeletonGrid::new([100, 100, 40], Some(&resampling), false);
        assert_eq!(grid.processed, [100, 100, 118]);
        let model = SKELETON_MEMORY_MODEL.peak_bytes(100 * 100 * 118);
        assert_eq!(grid.peak_bytes(), model + 8 * 100 * 100 * 40);
        assert_eq!(
            grid.to_string(),
            "100 x 100 x 118 voxels (resampled from 100 x 100 x 40)"
        );
        let direct = SkeletonGrid::new([100, 100, 40], None, false);
        assert_eq!(
            direct.peak_bytes(),
            SKELETON_MEMORY_MODEL.peak_bytes(400_000)
        );
        assert_eq!(direct.to_string(), "100 x 100 x 40 voxels");
    }
}
