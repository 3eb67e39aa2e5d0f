//! A memory budget for a reconstruction: the peak that [`RECON_MEMORY_MODEL`] predicts,
//! checked before any heavy work, and a coarser polygonisation depth where the default one
//! does not fit. The command line's `--max-memory` and the Python keyword `max_memory` both
//! decide through [`fit_memory_budget`], so they accept and refuse the same runs; each spells
//! the options its own way in the messages.

use sphcover_core::PointCloud;
use sphcover_core::io::format_byte_size;
use thiserror::Error;

use crate::memory_model::{COARSEST_BUDGET_DEPTH, RECON_MEMORY_MODEL};
use crate::pipeline::{Method, ReconError, ReconParams, default_depth};

/// What a budget decided for a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BudgetFit {
    /// The budget, in bytes.
    pub budget: u64,
    /// The polygonisation depth the run uses.
    pub depth: u32,
    /// The predicted peak at that depth, in bytes.
    pub estimate: u64,
    /// The default depth the budget replaced and its predicted peak, when it chose a
    /// coarser one.
    pub lowered_from: Option<(u32, u64)>,
}

impl BudgetFit {
    /// What to tell the user when the budget lowered the depth; the budget's option is
    /// spelled `budget_option` (`--max-memory`, `max_memory`).
    pub fn lowering_message(&self, budget_option: &str) -> Option<String> {
        let (from, from_estimate) = self.lowered_from?;
        Some(format!(
            "{budget_option} {}: depth {from} would need about {}; using depth {} (about {}, grid step 2^{} of the longest edge)",
            format_byte_size(self.budget),
            format_byte_size(from_estimate),
            self.depth,
            format_byte_size(self.estimate),
            -i64::from(self.depth)
        ))
    }
}

/// A run the budget refuses. Its `Display` spells the options as [`crate::ReconOptions`]
/// names them; [`BudgetError::message`] spells them as a front end does.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum BudgetError {
    /// The model covers the cover-based methods only.
    #[error("{}", self.message("max_memory", "depth"))]
    GraphCutMethod,
    /// Over budget at the given depth, or at every depth.
    #[error("{}", self.message("max_memory", "depth"))]
    OverBudget {
        /// The budget, in bytes.
        budget: u64,
        /// Points of the input.
        points: usize,
        /// The depth asked for (or the default one).
        depth: u32,
        /// Its predicted peak.
        estimate: u64,
        /// Whether the depth was given (then it is never replaced).
        depth_given: bool,
        /// The finest depth within the budget and its peak, if any.
        fitting: Option<(u32, u64)>,
    },
}

impl BudgetError {
    /// The message with the budget's and the depth's options spelled `budget_option` and
    /// `depth_option`.
    pub fn message(&self, budget_option: &str, depth_option: &str) -> String {
        let size = format_byte_size;
        match *self {
            BudgetError::GraphCutMethod => format!(
                "{budget_option}: the memory model covers the cover-based methods (integrated, diffusion, pu), not the graph-cut method"
            ),
            BudgetError::OverBudget {
                budget,
                points,
                depth,
                estimate,
                depth_given,
                fitting,
            } => {
                let why = match (depth_given, fitting) {
                    (true, Some((d, peak))) => format!(
                        "{depth_option} {d} would fit (about {}); raise the budget or lower {depth_option}",
                        size(peak)
                    ),
                    (true, None) => {
                        format!("no depth fits; raise the budget or lower {depth_option}")
                    }
                    (false, _) => format!(
                        "even depth {COARSEST_BUDGET_DEPTH} needs about {}; raise the budget or thin the scan",
                        size(RECON_MEMORY_MODEL.peak_bytes(points, COARSEST_BUDGET_DEPTH))
                    ),
                };
                format!(
                    "{budget_option} {}: reconstructing {points} points at depth {depth} needs about {}; {why}",
                    size(budget),
                    size(estimate)
                )
            }
        }
    }
}

/// The message of [`ReconError::OverMemoryBudget`] (the check once the cover is built) with
/// the front end's options for the budget, the tiles and ε spelled `budget_option`,
/// `tiles_option` and `eps_option`; `None` for any other error.
pub fn cover_over_budget_message(
    error: &ReconError,
    budget_option: &str,
    tiles_option: &str,
    eps_option: &str,
) -> Option<String> {
    let ReconError::OverMemoryBudget {
        supports,
        graph_entries,
        estimate,
        budget,
    } = *error
    else {
        return None;
    };
    Some(format!(
        "{budget_option} {}: {} (thin walls and sharp edges everywhere refine a cover to its sampling, \
         far beyond the usual size); \
         build it in tiles ({tiles_option} 2 or more holds one tile's cover at a time), give a larger {eps_option}, or raise the limit",
        format_byte_size(budget),
        cover_needs(supports, graph_entries, estimate),
    ))
}

/// What a cover of `supports` supports and `graph_entries` graph entries needs: the clause
/// that [`ReconError::OverMemoryBudget`] and [`cover_over_budget_message`] share.
pub(crate) fn cover_needs(supports: usize, graph_entries: u64, estimate: u64) -> String {
    format!(
        "the cover has {supports} supports and its sphere intersection graph {graph_entries} entries, \
         so the reconstruction needs about {}",
        format_byte_size(estimate)
    )
}

/// Checks the predicted peak of reconstructing `cloud` with `params` against `budget` bytes.
/// Within it, the run goes ahead as asked. Over it, a coarser depth that fits replaces the
/// default one; when `params.depth` was given, or even the coarsest depth does not fit, the
/// run is refused with the estimate.
pub fn fit_memory_budget(
    cloud: &PointCloud,
    params: &ReconParams,
    budget: u64,
) -> Result<BudgetFit, BudgetError> {
    if params.method == Method::GraphCut {
        return Err(BudgetError::GraphCutMethod);
    }
    let model = RECON_MEMORY_MODEL;
    let finite = cloud.positions.iter().filter(|p| p.is_finite()).count();
    let depth = params.depth.unwrap_or_else(|| default_depth(finite));
    let estimate = model.peak_bytes(cloud.len(), depth);
    if estimate <= budget {
        return Ok(BudgetFit {
            budget,
            depth,
            estimate,
            lowered_from: None,
        });
    }
    let fitting = model
        .finest_depth_within(cloud.len(), depth, budget)
        .map(|d| (d, model.peak_bytes(cloud.len(), d)));
    match fitting {
        Some((coarser, coarser_estimate)) if params.depth.is_none() => Ok(BudgetFit {
            budget,
            depth: coarser,
            estimate: coarser_estimate,
            lowered_from: Some((depth, estimate)),
        }),
        _ => Err(BudgetError::OverBudget {
            budget,
            points: cloud.len(),
            depth,
            estimate,
            depth_given: params.depth.is_some(),
            fitting,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::DVec3;

    fn cloud(n: usize) -> PointCloud {
        PointCloud::from_positions(vec![DVec3::ZERO; n])
    }

    #[test]
    fn the_default_depth_is_lowered_to_fit_and_a_given_depth_is_refused() {
        let points = cloud(1_000_000);
        let params = ReconParams::default();
        let default = default_depth(points.len());
        let peak = |d| RECON_MEMORY_MODEL.peak_bytes(points.len(), d);
        let roomy = fit_memory_budget(&points, &params, peak(default)).unwrap();
        assert_eq!((roomy.depth, roomy.lowered_from), (default, None));
        assert_eq!(roomy.lowering_message("--max-memory"), None);

        let tight = fit_memory_budget(&points, &params, peak(default - 1)).unwrap();
        assert_eq!(tight.depth, default - 1);
        assert_eq!(tight.estimate, peak(default - 1));
        assert_eq!(tight.lowered_from, Some((default, peak(default))));
        let warning = tight.lowering_message("max_memory").unwrap();
        assert!(warning.starts_with("max_memory "), "{warning}");

        let given = ReconParams {
            depth: Some(default),
            ..ReconParams::default()
        };
        let err = fit_memory_budget(&points, &given, peak(default - 1)).unwrap_err();
        let text = err.message("--max-memory", "--depth");
        assert!(
            text.contains(&format!("--depth {} would fit", default - 1))
                && text.ends_with("raise the budget or lower --depth"),
            "{text}"
        );
        assert!(err.to_string().contains("lower depth"), "{err}");
    }

    #[test]
    fn the_budget_is_checked_again_with_the_graphs_true_size() {
        use crate::pipeline::reconstruct;
        let n = 1500;
        let directions = sphcover_core::synthetic::fibonacci_sphere(n);
        let mut sphere = PointCloud::from_positions(directions.clone());
        sphere.normals = Some(directions);
        let free = reconstruct(&sphere, &ReconParams::default(), &|_| {}).unwrap();
        let s = &free.stats;
        let entries = (s.graph_mean_degree * s.supports as f64).round() as u64;
        let estimate = RECON_MEMORY_MODEL.peak_bytes_with_graph(n, s.depth, entries);
        assert_eq!(s.predicted_peak_bytes, Some(estimate));

        // One byte short of the estimate stops the run with what it measured.
        let short = ReconParams {
            memory_budget: Some(estimate - 1),
            ..ReconParams::default()
        };
        let err = reconstruct(&sphere, &short, &|_| {}).unwrap_err();
        let ReconError::OverMemoryBudget {
            supports,
            graph_entries,
            estimate: estimated,
            budget,
        } = err
        else {
            panic!("{err}");
        };
        assert_eq!(
            (supports, graph_entries, estimated, budget),
            (s.supports, entries, estimate, estimate - 1)
        );
        assert!(err.is_bad_input());
        let text = cover_over_budget_message(&err, "--max-memory", "--tiles", "--eps").unwrap();
        assert!(
            text.starts_with("--max-memory ")
                && text.contains("--tiles 2")
                && text.contains("--eps"),
            "{text}"
        );
        assert_eq!(
            cover_over_budget_message(&ReconError::Flat, "--max-memory", "--tiles", "--eps"),
            None
        );

        // The estimate itself fits, and the budget changes nothing in the result.
        let exact = ReconParams {
            memory_budget: Some(estimate),
            ..ReconParams::default()
        };
        let within = reconstruct(&sphere, &exact, &|_| {}).unwrap();
        assert_eq!(within.mesh, free.mesh);
    }

    #[test]
    fn nothing_fits_a_tiny_budget_and_the_graph_cut_has_no_model() {
        let points = cloud(5_000);
        let err = fit_memory_budget(&points, &ReconParams::default(), 1 << 20).unwrap_err();
        assert!(
            err.to_string().contains("even depth 5 needs about"),
            "{err}"
        );
        let graphcut = ReconParams {
            method: Method::GraphCut,
            ..ReconParams::default()
        };
        assert_eq!(
            fit_memory_budget(&points, &graphcut, u64::MAX),
            Err(BudgetError::GraphCutMethod)
        );
    }
}
