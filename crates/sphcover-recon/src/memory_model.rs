//! Peak memory of a reconstruction, predicted from the number of points and the
//! polygonisation depth, so that a caller with a memory budget can choose a coarser grid or
//! refuse before the work starts instead of being killed part-way.
//!
//! The method is described on [`ReconMemoryModel`].

/// The fitted model: bytes at the peak of a reconstruction.
///
/// The model is `peak = base + per_point · n + per_grid_cell · 4^depth`: the points and
/// everything held per point (positions and normals, neighbour structures, confidences,
/// labels) grow with `n`; the surface-net cells visited near the zero set, their function
/// values and the mesh grow with the area of the surface in grid steps, `∝ 4^depth`; the
/// cover and its operators depend on ε and the shape, not on `n` (the bunny's cover at the
/// default ε has about 66,000 supports from 100K to 3M points), and sit in `base`.
///
/// The coefficients are fitted to the peak resident set size of `sphcover recon` with
/// default parameters (integrated method, normals given) on synthetic scans of the bunny,
/// measured with `/usr/bin/time -v` (the table in `docs/benchmarks.md`, section *Memory*).
/// The grid term scales with the surface's area relative to its bounding box: a shape
/// with much more area than the bunny (a crumpled sheet, many thin parts) visits more cells
/// at the same depth, one with less (a flat plate) fewer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReconMemoryModel {
    /// Bytes whatever the input: the program, thread stacks, the cover and its operators.
    pub base_bytes: f64,
    /// Bytes per input point.
    pub bytes_per_point: f64,
    /// Bytes per unit of `4^depth` (surface-net cells, function values, the mesh).
    pub bytes_per_grid_cell: f64,
}

/// The model fitted to the measurements in `docs/benchmarks.md` (section *Memory*).
/// Fitted by least squares on relative errors to nine runs (100K to 10M points, depths 7 to
/// 10); every run is within 11% of it (10M: 10% above the prediction, 3M: 9% below). The
/// same fit without the 10M run predicted it 17% low: the cost per point grows somewhat
/// from 3M points on, so keep a margin above a few million points.
pub const RECON_MEMORY_MODEL: ReconMemoryModel = ReconMemoryModel {
    base_bytes: 119.5e6,
    bytes_per_point: 274.5,
    bytes_per_grid_cell: 929.2,
};

/// The coarsest grid a memory budget may choose (a step of 1/32 of the longest edge).
pub const COARSEST_BUDGET_DEPTH: u32 = 5;

impl ReconMemoryModel {
    /// The predicted peak, in bytes, of reconstructing `points` points at `depth`.
    pub fn peak_bytes(&self, points: usize, depth: u32) -> u64 {
        let grid = 4f64.powi(depth.min(30) as i32);
        let bytes = self.base_bytes
            + self.bytes_per_point * points as f64
            + self.bytes_per_grid_cell * grid;
        // Saturates for absurd inputs rather than wrapping.
        bytes.max(0.0).min(u64::MAX as f64) as u64
    }

    /// The finest depth from `finest` down to [`COARSEST_BUDGET_DEPTH`] whose predicted
    /// peak for `points` points is at most `budget_bytes`; `None` when even the coarsest
    /// does not fit (the points alone exceed the budget).
    pub fn finest_depth_within(
        &self,
        points: usize,
        finest: u32,
        budget_bytes: u64,
    ) -> Option<u32> {
        (COARSEST_BUDGET_DEPTH.min(finest)..=finest)
            .rev()
            .find(|&depth| self.peak_bytes(points, depth) <= budget_bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The runs the model was fitted to (`docs/benchmarks.md`, *Memory*): points, depth,
    /// peak resident set size in KiB.
    const MEASURED: [(usize, u32, u64); 9] = [
        (100_000, 7, 164_120),
        (100_000, 8, 201_000),
        (100_000, 9, 385_144),
        (100_000, 10, 1_112_868),
        (362_000, 8, 264_856),
        (1_000_000, 8, 435_560),
        (1_000_000, 9, 625_712),
        (3_000_000, 9, 1_064_612),
        (10_000_000, 9, 3_388_304),
    ];

    #[test]
    fn the_model_reproduces_the_measured_runs_within_12_percent() {
        for (points, depth, kib) in MEASURED {
            let predicted = RECON_MEMORY_MODEL.peak_bytes(points, depth) as f64;
            let measured = (kib * 1024) as f64;
            let error = predicted / measured - 1.0;
            assert!(
                error.abs() < 0.12,
                "{points} points, depth {depth}: {error:+.3}"
            );
        }
    }

    proptest! {
        #[test]
        fn the_peak_grows_with_points_and_depth(n in 0usize..1_000_000_000, d in 1u32..14) {
            let m = RECON_MEMORY_MODEL;
            prop_assert!(m.peak_bytes(n, d) < m.peak_bytes(n, d + 1));
            prop_assert!(m.peak_bytes(n, d) <= m.peak_bytes(n + 1000, d));
        }

        #[test]
        fn the_chosen_depth_is_the_finest_that_fits(
            n in 0usize..100_000_000,
            finest in 1u32..14,
            budget in 0u64..(64u64 << 30),
        ) {
            let m = RECON_MEMORY_MODEL;
            match m.finest_depth_within(n, finest, budget) {
                Some(d) => {
                    prop_assert!(d <= finest);
                    prop_assert!(m.peak_bytes(n, d) <= budget);
                    prop_assert!(d == finest || m.peak_bytes(n, d + 1) > budget);
                }
                None => prop_assert!(
                    m.peak_bytes(n, COARSEST_BUDGET_DEPTH.min(finest)) > budget
                ),
            }
        }
    }
}
