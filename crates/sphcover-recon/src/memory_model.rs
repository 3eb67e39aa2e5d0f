//! Peak memory of a reconstruction, predicted from the number of points, the
//! polygonisation depth and the size of the cover's sphere intersection graph, so that a
//! caller with a memory budget can choose a coarser grid or refuse before the work starts
//! (and stop once the graph is built, when the cover turns out far larger than usual)
//! instead of being killed part-way.
//!
//! The method is described on [`ReconMemoryModel`].

/// The fitted model: bytes at the peak of a reconstruction.
///
/// The model is `peak = base + per_point · n + per_grid_cell · 4^depth + per_entry · E`:
/// the points and everything held per point (positions and normals, neighbour structures,
/// confidences, labels) grow with `n`; the surface-net cells visited near the zero set, their
/// function values and the mesh grow with the area of the surface in grid steps, `∝ 4^depth`;
/// the cover's operators (the graph, the pair geometry, the graph cut's network, the
/// diffusion's weights) grow with the `E` directed entries of the sphere intersection graph.
///
/// `E` depends on ε and the shape, not on `n`: the bunny's cover at the default ε has
/// 66,000–68,000 supports of mean degree 50–55 from 100K to 3M points, about
/// [`TYPICAL_GRAPH_ENTRIES`]. A thin-walled part with sharp edges everywhere is refined to
/// its sampling instead: the 200K-point scan of the generated housing has 357,524 supports
/// of mean degree 96, ten times as many entries, and peaks at 1.25 GB against 0.19 GB for
/// the bunny's 100K points. Before the run `E` is unknown and taken as typical
/// ([`ReconMemoryModel::peak_bytes`]); once the graph is built the pipeline checks the budget
/// again with its true size ([`crate::ReconParams::memory_budget`]).
///
/// The coefficients are fitted to the peak resident set size of `sphcover recon` with
/// default parameters (integrated method, normals given, two threads) on synthetic scans of
/// the bunny and of the housing, measured with `/usr/bin/time` (the table in
/// `docs/benchmarks.md`, section *Memory*). The grid term scales with the surface's area
/// relative to its bounding box: a shape with much more area than the bunny (a crumpled
/// sheet, many thin parts) visits more cells at the same depth, one with less (a flat plate)
/// fewer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReconMemoryModel {
    /// Bytes whatever the input: the program and thread stacks.
    pub base_bytes: f64,
    /// Bytes per input point.
    pub bytes_per_point: f64,
    /// Bytes per unit of `4^depth` (surface-net cells, function values, the mesh).
    pub bytes_per_grid_cell: f64,
    /// Bytes per directed entry of the sphere intersection graph (the cover's operators).
    pub bytes_per_graph_entry: f64,
}

/// The model fitted to the measurements in `docs/benchmarks.md` (section *Memory*): thirteen
/// runs, bunny scans of 100K to 10M points at depths 7 to 10 and housing scans of 100K to
/// 400K points at depths 8 and 9, fitted by least squares on relative errors with the base
/// held at 5 MB (the program and its threads). Every run is within 13% of it. The cost per
/// point grows somewhat with the scan (the 10M-point run is 12% above the model, the 1M one
/// 11% below), so keep a margin above a few million points.
pub const RECON_MEMORY_MODEL: ReconMemoryModel = ReconMemoryModel {
    base_bytes: 5.0e6,
    bytes_per_point: 230.2,
    bytes_per_grid_cell: 867.8,
    bytes_per_graph_entry: 33.0,
};

/// Directed entries of the sphere intersection graph assumed before the cover is built: the
/// bunny's at the default ε (see [`ReconMemoryModel`]).
pub const TYPICAL_GRAPH_ENTRIES: u64 = 3_500_000;

/// The coarsest grid a memory budget may choose (a step of 1/32 of the longest edge).
pub const COARSEST_BUDGET_DEPTH: u32 = 5;

impl ReconMemoryModel {
    /// The predicted peak, in bytes, of reconstructing `points` points at `depth` with a
    /// cover of typical size ([`TYPICAL_GRAPH_ENTRIES`]).
    pub fn peak_bytes(&self, points: usize, depth: u32) -> u64 {
        self.peak_bytes_with_graph(points, depth, TYPICAL_GRAPH_ENTRIES)
    }

    /// The predicted peak, in bytes, of reconstructing `points` points at `depth` with a
    /// sphere intersection graph of `graph_entries` directed entries.
    pub fn peak_bytes_with_graph(&self, points: usize, depth: u32, graph_entries: u64) -> u64 {
        let grid = 4f64.powi(depth.min(30) as i32);
        let bytes = self.base_bytes
            + self.bytes_per_point * points as f64
            + self.bytes_per_grid_cell * grid
            + self.bytes_per_graph_entry * graph_entries as f64;
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
    /// directed entries of the sphere intersection graph, peak resident set size in KiB.
    const MEASURED: [(usize, u32, u64, u64); 13] = [
        (100_000, 7, 3_687_547, 175_052),
        (100_000, 8, 3_687_547, 188_144),
        (100_000, 9, 3_687_547, 378_516),
        (100_000, 10, 3_687_547, 1_142_784),
        (362_000, 8, 3_491_288, 242_048),
        (1_000_000, 9, 3_347_190, 502_860),
        (3_000_000, 9, 3_395_266, 963_300),
        (10_000_000, 9, 3_421_507, 2_946_760),
        (100_000, 8, 11_180_298, 435_012),
        (100_000, 9, 11_180_298, 605_288),
        (200_000, 8, 34_286_552, 1_277_748),
        (200_000, 9, 34_286_552, 1_285_100),
        (400_000, 8, 39_030_508, 1_490_576),
    ];

    #[test]
    fn the_model_reproduces_the_measured_runs_within_13_percent() {
        for (points, depth, entries, kib) in MEASURED {
            let predicted = RECON_MEMORY_MODEL.peak_bytes_with_graph(points, depth, entries) as f64;
            let measured = (kib * 1024) as f64;
            let error = predicted / measured - 1.0;
            assert!(
                error.abs() < 0.13,
                "{points} points, depth {depth}, {entries} entries: {error:+.3}"
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
        fn the_peak_grows_with_the_graph_and_is_typical_without_it(
            n in 0usize..100_000_000,
            d in 1u32..14,
            e in 0u64..1_000_000_000,
        ) {
            let m = RECON_MEMORY_MODEL;
            prop_assert!(m.peak_bytes_with_graph(n, d, e) < m.peak_bytes_with_graph(n, d, e + 1000));
            prop_assert_eq!(m.peak_bytes(n, d), m.peak_bytes_with_graph(n, d, TYPICAL_GRAPH_ENTRIES));
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
