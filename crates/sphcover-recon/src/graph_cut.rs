//! Inside/outside labelling of support centres by a minimum cut (thesis §5.2.2, Appendix A).
//!
//! The method is described on [`graph_cut()`].

use sphcover_core::{
    Cover, CoverError, DVec3, LengthMismatch, PuEvaluator, SphereIntersectionGraph, SupportLists,
};
use std::time::{Duration, Instant};

use rayon::prelude::*;
use thiserror::Error;

use crate::maxflow::{FlowEdge, FlowGraph, MaxFlowError};

/// Length below which an edge counts as zero, relative to the mean edge length.
const ZERO_LENGTH: f64 = 1e-9;

/// Why a graph cut could not be computed.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum GraphCutError {
    /// The ratio `k` is not finite and positive.
    #[error("terminal-to-edge cost ratio k = {0} is not finite and positive")]
    InvalidK(f64),
    /// The reference degree is not finite and positive.
    #[error("reference degree {0} is not finite and positive")]
    InvalidReferenceDegree(f64),
    /// A per-node array does not have one entry per node.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
    /// A node position or value is NaN or infinite.
    #[error("node {index} has a non-finite position or value")]
    NonFinite {
        /// Index of the node.
        index: usize,
    },
    /// An edge names a node that does not exist.
    #[error("edge {edge} names a node beyond the {nodes} nodes")]
    NodeOutOfRange {
        /// Index of the edge.
        edge: usize,
        /// Number of nodes.
        nodes: usize,
    },
    /// The partition-of-unity evaluator could not be built.
    #[error("cover: {0}")]
    Cover(#[from] CoverError),
    /// The flow network could not be built.
    #[error("max-flow: {0}")]
    MaxFlow(#[from] MaxFlowError),
}

/// Parameters of a graph cut.
#[derive(Clone, Debug, PartialEq)]
pub struct GraphCutParams {
    /// Ratio `k` of terminal to edge cost (thesis eq. 5.1).
    pub k: f64,
    /// Degree `d₀` at which `k` was calibrated: terminal weights are scaled by `d_v / d₀`
    /// (see [`graph_cut`]). `None` is the thesis's eq. 5.1 as written.
    pub reference_degree: Option<f64>,
}

impl GraphCutParams {
    /// The thesis value for the sphere intersection graph (§5.2.4: 27–30).
    pub const SIG_K: f64 = 28.0;
    /// The thesis value for the tetrahedral mesh (§5.2.2: 5–15).
    pub const TET_K: f64 = 10.0;

    /// The mean degree of the thesis's sphere intersection graphs (shrink 0.7, thesis Appendix B).
    pub const SIG_REFERENCE_DEGREE: f64 = 40.0;

    /// Parameters for the sphere intersection graph: `k` = [`GraphCutParams::SIG_K`],
    /// normalised to degree [`GraphCutParams::SIG_REFERENCE_DEGREE`].
    pub fn sig() -> GraphCutParams {
        GraphCutParams {
            k: Self::SIG_K,
            reference_degree: Some(Self::SIG_REFERENCE_DEGREE),
        }
    }

    /// Parameters for the tetrahedral mesh (`k` = [`GraphCutParams::TET_K`], eq. 5.1 as
    /// written: the dual complex's degree is close to the thesis's).
    pub fn tet() -> GraphCutParams {
        GraphCutParams {
            k: Self::TET_K,
            reference_degree: None,
        }
    }

    /// Eq. 5.1 as written with ratio `k`, no degree normalisation.
    pub fn with_k(k: f64) -> GraphCutParams {
        GraphCutParams {
            k,
            reference_degree: None,
        }
    }
}

impl Default for GraphCutParams {
    /// The sphere-intersection-graph setting of the default (integrated) pipeline.
    fn default() -> GraphCutParams {
        GraphCutParams::sig()
    }
}

/// Counters of a graph cut.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GraphCutStats {
    /// Nodes.
    pub nodes: usize,
    /// Undirected edges given.
    pub edges: usize,
    /// Nodes labelled inside.
    pub inside: usize,
    /// Nodes whose label disagrees with the sign of `f`.
    pub inconsistent: usize,
    /// Nodes where `f` was undefined (treated as 0: no terminal arc).
    pub undefined_values: usize,
    /// Augmenting paths of the max-flow (warm-start pushes included).
    pub augmentations: u64,
    /// Time to build the network.
    pub build_time: Duration,
    /// Time to solve it.
    pub solve_time: Duration,
}

/// The labelling found by a graph cut.
#[derive(Clone, Debug, PartialEq)]
pub struct GraphCut {
    /// Per node: `true` inside (source side), `false` outside.
    pub labels: Vec<bool>,
    /// Nodes whose label disagrees with the sign of `f` (ascending). `f = 0` is never
    /// inconsistent.
    pub inconsistent: Vec<u32>,
    /// The minimum cut's cost (= the maximum flow).
    pub flow: f64,
    /// Counters.
    pub stats: GraphCutStats,
}

/// Labels the nodes at `positions` with values `values` (the partition-of-unity `f`,
/// positive inside) over the undirected `edges`, by the minimum cut of thesis eq. 5.1–5.2.
///
/// Nodes are support centres `v` with partition-of-unity values `f(v)` (positive inside);
/// the source is *inside* and the sink *outside*. With `l_v` the mean length of the edges at
/// `v` and `l_ij` the length of edge `ij` (thesis eq. 5.1, 5.2):
///
/// ```text
/// f(v) > 0:  w(v, source) = k |f(v)| / l_v          f(v) < 0:  w(v, sink) = k |f(v)| / l_v
/// edge ij:   w(v_i, v_j)  = |f(v_i) + f(v_j)| / l_ij
/// ```
///
/// Both costs are dimensionless; `k` is the ratio of terminal to edge cost.
///
/// **Degree normalisation** (beyond the thesis). A node's terminal arc competes with the sum
/// of its edges, so the balance set by `k` depends on the mean degree of the graph: the
/// thesis's `k` ≈ 28 was tuned on sphere intersection graphs of mean degree about 40 (shrink
/// 0.7), and its `k` ≈ 5–15 on tetrahedral meshes of mean degree about 15 — in both cases the
/// terminal arc is about a third of the edge sum. Covers with more overlap (measured: mean
/// degree 244 on a noisy sphere's cover) make the thesis weights label almost every node
/// outside. With [`GraphCutParams::reference_degree`] `= Some(d₀)`, the terminal weight of a
/// node of degree `d_v` is multiplied by `d_v / d₀`, which keeps the thesis's balance at any
/// degree and reduces to eq. 5.1 at `d_v = d₀`. An edge whose
/// ends have opposite signs of `f` near the true surface is cheap to cut (`f_i + f_j ≈ 0`),
/// while an isolated blob of wrong sign (an outlier cluster, a flipped normal) is expensive to
/// keep apart from its neighbours, so the cut relabels it. A node whose label disagrees with
/// the sign of `f` is *inconsistent*.
///
/// The graph is either the sphere intersection graph (the integrated pipeline, thesis §5.2.4,
/// `k` ≈ 27–30: every support gets a label) or the edges of the tetrahedral mesh of the cover
/// (the graph-cut-only path, `k` ≈ 5–15), see [`reconstruct_graphcut`](crate::reconstruct_graphcut).
///
/// Degenerate input: a node with no edge of positive length uses the mean edge length of the
/// whole graph as `l_v` (1 when there is none); an edge of zero length (coincident centres)
/// uses a length of `1e-9` times the mean edge length, which ties its ends together.
pub fn graph_cut(
    positions: &[DVec3],
    values: &[f64],
    edges: &[[u32; 2]],
    params: &GraphCutParams,
) -> Result<GraphCut, GraphCutError> {
    check_nodes(positions, values, params)?;
    let n = positions.len();
    if let Some(edge) = edges
        .iter()
        .position(|e| e[0] as usize >= n || e[1] as usize >= n)
    {
        return Err(GraphCutError::NodeOutOfRange { edge, nodes: n });
    }
    let start = Instant::now();

    let lengths: Vec<f64> = edges
        .par_iter()
        .with_min_len(4096)
        .map(|e| positions[e[0] as usize].distance(positions[e[1] as usize]))
        .collect();
    // Sequential sums in edge order: the same bits whatever the thread count.
    let mut length_sum = vec![0.0f64; n];
    let mut length_count = vec![0u32; n];
    let mut total = 0.0;
    let mut counted = 0usize;
    for (e, &l) in edges.iter().zip(&lengths) {
        if l > 0.0 && e[0] != e[1] {
            for v in *e {
                length_sum[v as usize] += l;
                length_count[v as usize] += 1;
            }
            total += l;
            counted += 1;
        }
    }
    let mean_length = if counted > 0 {
        total / counted as f64
    } else {
        1.0
    };
    let floor = ZERO_LENGTH * mean_length;

    let (source, sink) =
        terminal_capacities(values, &length_sum, &length_count, mean_length, params);
    let flow_edges: Vec<FlowEdge> = edges
        .par_iter()
        .zip(&lengths)
        .with_min_len(4096)
        .map(|(e, &l)| {
            let w = finite_capacity(
                (values[e[0] as usize] + values[e[1] as usize]).abs() / l.max(floor),
            );
            FlowEdge::undirected(e[0], e[1], w)
        })
        .collect();
    let graph = FlowGraph::new(n, &source, &sink, &flow_edges)?;
    drop(flow_edges);
    Ok(solve(|| Ok(graph), values, edges.len(), start, || ())?.0)
}

/// Terminal capacities of eq. 5.1 (with the optional degree normalisation) from the sums and
/// counts of positive edge lengths at each node.
fn terminal_capacities(
    values: &[f64],
    length_sum: &[f64],
    length_count: &[u32],
    mean_length: f64,
    params: &GraphCutParams,
) -> (Vec<f64>, Vec<f64>) {
    (0..values.len())
        .into_par_iter()
        .with_min_len(4096)
        .map(|v| {
            let l = if length_count[v] > 0 {
                length_sum[v] / f64::from(length_count[v])
            } else {
                mean_length
            };
            let scale = match params.reference_degree {
                Some(d) => f64::from(length_count[v].max(1)) / d,
                None => 1.0,
            };
            let w = finite_capacity(params.k * scale * values[v].abs() / l);
            if values[v] > 0.0 { (w, 0.0) } else { (0.0, w) }
        })
        .unzip()
}

/// Builds the network with `build`, solves it and reads the labelling off the cut, running
/// `alongside` on the other threads meanwhile: building the network's reverse arcs and the
/// max-flow solve are sequential. An error of `build` is returned once `alongside` is done.
fn solve<'g, R: Send>(
    build: impl FnOnce() -> Result<FlowGraph<'g>, MaxFlowError> + Send,
    values: &[f64],
    edges: usize,
    start: Instant,
    alongside: impl FnOnce() -> R + Send,
) -> Result<(GraphCut, R), GraphCutError> {
    let n = values.len();
    let (solved, beside) = rayon::join(
        || {
            let mut graph = build()?;
            let build_time = start.elapsed();
            let solve_start = Instant::now();
            let info = graph.solve();
            Ok::<_, MaxFlowError>((graph, info, build_time, solve_start.elapsed()))
        },
        alongside,
    );
    let (graph, info, build_time, solve_time) = solved?;
    let labels = graph.source_side();
    let inconsistent: Vec<u32> = (0..n)
        .filter(|&v| (labels[v] && values[v] < 0.0) || (!labels[v] && values[v] > 0.0))
        .map(|v| v as u32)
        .collect();
    let stats = GraphCutStats {
        nodes: n,
        edges,
        inside: info.source_side_nodes,
        inconsistent: inconsistent.len(),
        undefined_values: 0,
        augmentations: info.augmentations + info.warm_start_pushes,
        build_time,
        solve_time,
    };
    let cut = GraphCut {
        labels,
        inconsistent,
        flow: info.flow,
        stats,
    };
    Ok((cut, beside))
}

/// Checks the common inputs of the graph cuts.
fn check_nodes(
    positions: &[DVec3],
    values: &[f64],
    params: &GraphCutParams,
) -> Result<(), GraphCutError> {
    if !(params.k.is_finite() && params.k > 0.0) {
        return Err(GraphCutError::InvalidK(params.k));
    }
    if let Some(d) = params.reference_degree
        && !(d.is_finite() && d > 0.0)
    {
        return Err(GraphCutError::InvalidReferenceDegree(d));
    }
    let n = positions.len();
    if values.len() != n {
        return Err(GraphCutError::LengthMismatch(LengthMismatch {
            array: "values",
            expected: n,
            found: values.len(),
        }));
    }
    if let Some(index) = (0..n).find(|&i| !(positions[i].is_finite() && values[i].is_finite())) {
        return Err(GraphCutError::NonFinite { index });
    }
    Ok(())
}

/// [`graph_cut`] over a symmetric adjacency in compressed sparse rows (row `v` is
/// `neighbours[offsets[v]..offsets[v + 1]]`, strictly ascending, without `v`; `j` in row `i`
/// exactly when `i` in row `j`), such as a sphere intersection graph. The flow network is
/// built on the rows directly, without an edge list.
#[cfg(test)]
fn graph_cut_csr(
    positions: &[DVec3],
    values: &[f64],
    offsets: &[u32],
    neighbours: &[u32],
    params: &GraphCutParams,
) -> Result<GraphCut, GraphCutError> {
    graph_cut_csr_alongside(positions, values, offsets, neighbours, params, || ())
        .map(|(cut, ())| cut)
}

/// [`graph_cut`] over compressed rows, running `alongside` on the other threads while the max-flow solve,
/// which is sequential, runs on one.
fn graph_cut_csr_alongside<R: Send>(
    positions: &[DVec3],
    values: &[f64],
    offsets: &[u32],
    neighbours: &[u32],
    params: &GraphCutParams,
    alongside: impl FnOnce() -> R + Send,
) -> Result<(GraphCut, R), GraphCutError> {
    check_nodes(positions, values, params)?;
    let n = positions.len();
    if offsets.len() != n + 1 {
        return Err(GraphCutError::LengthMismatch(LengthMismatch {
            array: "offsets",
            expected: n + 1,
            found: offsets.len(),
        }));
    }
    if offsets[0] != 0
        || offsets[n] as usize != neighbours.len()
        || offsets.windows(2).any(|w| w[0] > w[1])
    {
        return Err(GraphCutError::MaxFlow(MaxFlowError::MalformedCsr(
            "offsets",
        )));
    }
    if let Some(edge) = neighbours.iter().position(|&j| j as usize >= n) {
        return Err(GraphCutError::NodeOutOfRange { edge, nodes: n });
    }
    let start = Instant::now();
    // The length of an entry, evaluated with the lower index first so both directions of an
    // edge get the same bits; computed where needed rather than stored (a pass over the
    // lengths cost more than the square roots).
    let length = |v: usize, j: usize| {
        let (a, b) = if v < j { (v, j) } else { (j, v) };
        positions[a].distance(positions[b])
    };
    let (length_sum, length_count): (Vec<f64>, Vec<u32>) = (0..n)
        .into_par_iter()
        .with_min_len(1024)
        .map(|v| {
            neighbours[offsets[v] as usize..offsets[v + 1] as usize]
                .iter()
                .map(|&j| length(v, j as usize))
                .filter(|&l| l > 0.0)
                .fold((0.0, 0u32), |(s, c), l| (s + l, c + 1))
        })
        .unzip();
    // The mean over directed entries equals the mean over edges (each counted twice).
    let (mut total, mut counted) = (0.0, 0usize);
    for (s, c) in length_sum.iter().zip(&length_count) {
        total += s;
        counted += *c as usize;
    }
    let mean_length = if counted > 0 {
        total / counted as f64
    } else {
        1.0
    };
    let floor = ZERO_LENGTH * mean_length;
    let (source, sink) =
        terminal_capacities(values, &length_sum, &length_count, mean_length, params);
    let mut capacities = vec![0.0; neighbours.len()];
    crate::csr::fill_entries(offsets, &mut capacities, |v, k| {
        let j = neighbours[k] as usize;
        finite_capacity((values[v] + values[j]).abs() / length(v, j).max(floor))
    });
    let build = || FlowGraph::from_symmetric_csr(&source, &sink, offsets, neighbours, capacities);
    solve(build, values, neighbours.len() / 2, start, alongside)
}

/// Keeps a capacity finite when a tiny length meets a large value.
fn finite_capacity(c: f64) -> f64 {
    c.min(f64::MAX / 4.0)
}

/// The partition-of-unity values of `cover` at `points` (σ = 1); undefined values become 0.
/// Returns the values and how many were undefined.
pub(crate) fn values_at(
    cover: &Cover,
    points: &[DVec3],
) -> Result<(Vec<f64>, usize), GraphCutError> {
    let eval = PuEvaluator::new(cover, 1.0)?;
    Ok(undefined_as_zero(eval.values(points)))
}

/// The values with the undefined ones 0, and how many were undefined.
fn undefined_as_zero(values: Vec<Option<f64>>) -> (Vec<f64>, usize) {
    let undefined = values.iter().filter(|v| v.is_none()).count();
    (
        values.into_iter().map(|v| v.unwrap_or(0.0)).collect(),
        undefined,
    )
}

/// Graph cut on the sphere intersection graph of `cover` (thesis §5.2.4): one node per
/// support, `f` evaluated at the centres. `sig` must have been built over this cover.
pub fn graph_cut_sig(
    cover: &Cover,
    sig: &SphereIntersectionGraph,
    params: &GraphCutParams,
) -> Result<GraphCut, GraphCutError> {
    let at_centres = PuEvaluator::new(cover, 1.0)?.support_lists(cover.centres());
    graph_cut_sig_alongside(cover, sig, &at_centres, params, || ()).map(|(cut, ())| cut)
}

/// [`graph_cut_sig`], with `alongside` run on the other threads while the max-flow solve,
/// which is sequential, occupies one: work the caller needs next and that does not depend
/// on the cut. Its result comes back with the cut's; it is not run when the inputs are
/// refused, but may be when the graph proves not symmetric while the network is built. `f`
/// at the centres comes from `at_centres`, the support lists gathered at `cover`'s centres
/// (which later evaluations there can share).
pub(crate) fn graph_cut_sig_alongside<R: Send>(
    cover: &Cover,
    sig: &SphereIntersectionGraph,
    at_centres: &SupportLists,
    params: &GraphCutParams,
    alongside: impl FnOnce() -> R + Send,
) -> Result<(GraphCut, R), GraphCutError> {
    if sig.len() != cover.len() {
        return Err(GraphCutError::LengthMismatch(LengthMismatch {
            array: "sphere intersection graph",
            expected: cover.len(),
            found: sig.len(),
        }));
    }
    let (values, undefined) = undefined_as_zero(at_centres.values(cover, cover.centres())?);
    let (mut cut, beside) = graph_cut_csr_alongside(
        cover.centres(),
        &values,
        sig.offsets(),
        sig.neighbour_array(),
        params,
        alongside,
    )?;
    cut.stats.undefined_values = undefined;
    Ok((cut, beside))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The cut energy of a labelling: terminal arcs of the nodes on the wrong side plus the
    /// edges between the sides, with the weights of eq. 5.1–5.2.
    fn energy(
        positions: &[DVec3],
        values: &[f64],
        edges: &[[u32; 2]],
        k: f64,
        labels: &[bool],
    ) -> f64 {
        let n = positions.len();
        let mut sum = vec![0.0; n];
        let mut cnt = vec![0.0; n];
        for e in edges {
            let l = positions[e[0] as usize].distance(positions[e[1] as usize]);
            for v in e {
                sum[*v as usize] += l;
                cnt[*v as usize] += 1.0;
            }
        }
        let mean: f64 = if edges.is_empty() {
            1.0
        } else {
            edges
                .iter()
                .map(|e| positions[e[0] as usize].distance(positions[e[1] as usize]))
                .sum::<f64>()
                / edges.len() as f64
        };
        let mut e_total = 0.0;
        for v in 0..n {
            let l = if cnt[v] > 0.0 { sum[v] / cnt[v] } else { mean };
            let w = k * values[v].abs() / l;
            if (values[v] > 0.0 && !labels[v]) || (values[v] < 0.0 && labels[v]) {
                e_total += w;
            }
        }
        for e in edges {
            let (a, b) = (e[0] as usize, e[1] as usize);
            if labels[a] != labels[b] {
                e_total += (values[a] + values[b]).abs() / positions[a].distance(positions[b]);
            }
        }
        e_total
    }

    fn small_graph() -> impl Strategy<Value = (Vec<DVec3>, Vec<f64>, Vec<[u32; 2]>, f64)> {
        (2usize..10).prop_flat_map(|n| {
            (
                proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0), n),
                proptest::collection::vec(-1.0f64..1.0, n),
                proptest::collection::vec((0..n as u32, 0..n as u32), 0..3 * n),
                0.1f64..40.0,
            )
                .prop_map(|(p, v, e, k)| {
                    // Distinct positions: zero-length edges follow their own rule (tested below).
                    let p: Vec<DVec3> = p
                        .into_iter()
                        .enumerate()
                        .map(|(i, (x, y, z))| DVec3::new(x + 3.0 * i as f64, y, z))
                        .collect();
                    let e: Vec<[u32; 2]> = e
                        .into_iter()
                        .filter(|(a, b)| a != b)
                        .map(|(a, b)| [a, b])
                        .collect();
                    (p, v, e, k)
                })
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// Brute force over all 2ⁿ labellings: the cut's labelling has the least energy, and
        /// that energy is the flow.
        #[test]
        fn labelling_minimises_the_energy((p, v, e, k) in small_graph()) {
            let cut = graph_cut(&p, &v, &e, &GraphCutParams::with_k(k)).unwrap();
            let n = p.len();
            // The CSR form of the same graph (parallel edges merged, so compare energies).
            let mut pairs: Vec<(u32, u32)> = e.iter().flat_map(|&[a, b]| [(a, b), (b, a)]).collect();
            pairs.sort_unstable();
            pairs.dedup();
            let mut offsets = vec![0u32; n + 1];
            for &(a, _) in &pairs {
                offsets[a as usize + 1] += 1;
            }
            for i in 0..n {
                offsets[i + 1] += offsets[i];
            }
            let neighbours: Vec<u32> = pairs.iter().map(|&(_, b)| b).collect();
            let unique: Vec<[u32; 2]> = pairs.iter().filter(|(a, b)| a < b).map(|&(a, b)| [a, b]).collect();
            let csr = graph_cut_csr(&p, &v, &offsets, &neighbours, &GraphCutParams::with_k(k)).unwrap();
            let by_list = graph_cut(&p, &v, &unique, &GraphCutParams::with_k(k)).unwrap();
            let (ea, eb) = (energy(&p, &v, &unique, k, &csr.labels), energy(&p, &v, &unique, k, &by_list.labels));
            prop_assert!((ea - eb).abs() <= 1e-9 * (1.0 + ea), "csr {} list {}", ea, eb);
            prop_assert!((csr.flow - by_list.flow).abs() <= 1e-9 * (1.0 + ea));
            let mut best = f64::INFINITY;
            for mask in 0u32..(1 << n) {
                let labels: Vec<bool> = (0..n).map(|i| mask & (1 << i) != 0).collect();
                best = best.min(energy(&p, &v, &e, k, &labels));
            }
            let mine = energy(&p, &v, &e, k, &cut.labels);
            let tol = 1e-9 * (1.0 + best);
            prop_assert!((mine - best).abs() <= tol, "cut energy {} brute force {}", mine, best);
            prop_assert!((cut.flow - best).abs() <= tol, "flow {} brute force {}", cut.flow, best);
            // The inconsistent set is exactly the disagreement with sign(f).
            for i in 0..n {
                let wrong = (cut.labels[i] && v[i] < 0.0) || (!cut.labels[i] && v[i] > 0.0);
                prop_assert_eq!(wrong, cut.inconsistent.contains(&(i as u32)));
            }
        }

        /// When every terminal arc outweighs all edges at its node, the cut follows sign(f).
        #[test]
        fn dominant_terminals_follow_the_sign((p, v, e, _k) in small_graph()) {
            let v: Vec<f64> = v.into_iter().map(|x| if x.abs() < 0.05 { 0.5 } else { x }).collect();
            let cut = graph_cut(&p, &v, &e, &GraphCutParams::with_k(1e9)).unwrap();
            prop_assert!(cut.inconsistent.is_empty());
            for i in 0..p.len() {
                prop_assert_eq!(cut.labels[i], v[i] > 0.0);
            }
        }
    }

    /// A grid of nodes in a ball-shaped object with a few weak wrong-sign nodes inside and
    /// outside (the outliers of a scan): the cut relabels those, and otherwise departs from
    /// sign(f) only next to the zero set (where it trades terminal cost for a smoother cut).
    #[test]
    fn isolated_wrong_signs_are_relabelled() {
        let m = 12;
        let h = 1.0 / m as f64;
        let mut positions = Vec::new();
        for z in 0..m {
            for y in 0..m {
                for x in 0..m {
                    positions.push(DVec3::new(x as f64, y as f64, z as f64) * h);
                }
            }
        }
        let id = |x: usize, y: usize, z: usize| ((z * m + y) * m + x) as u32;
        let mut edges = Vec::new();
        for z in 0..m {
            for y in 0..m {
                for x in 0..m {
                    if x + 1 < m {
                        edges.push([id(x, y, z), id(x + 1, y, z)]);
                    }
                    if y + 1 < m {
                        edges.push([id(x, y, z), id(x, y + 1, z)]);
                    }
                    if z + 1 < m {
                        edges.push([id(x, y, z), id(x, y, z + 1)]);
                    }
                }
            }
        }
        let c = DVec3::splat(0.5 - h / 2.0);
        let mut values: Vec<f64> = positions.iter().map(|p| 0.3 - p.distance(c)).collect();
        let flipped = [id(5, 5, 5), id(6, 5, 6), id(0, 0, 0), id(11, 3, 0)];
        for &f in &flipped {
            values[f as usize] *= -0.1;
        }
        // A grid node has 6 edges, not the ≈ 40 of a sphere intersection graph: the
        // tetrahedral-mesh ratio fits.
        let cut = graph_cut(&positions, &values, &edges, &GraphCutParams::tet()).unwrap();
        for f in flipped {
            assert!(cut.inconsistent.contains(&f), "{f} kept its wrong sign");
        }
        for &v in &cut.inconsistent {
            if !flipped.contains(&v) {
                assert!(
                    values[v as usize].abs() < h,
                    "node {v} far from the surface relabelled"
                );
            }
        }
        assert_eq!(cut.stats.inconsistent, cut.inconsistent.len());
    }

    /// A cover-sized random graph gives the same labels and flow bits on one thread and two.
    #[test]
    fn thread_count_does_not_change_the_cut() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let n = 20_000;
        let positions: Vec<DVec3> = (0..n)
            .map(|_| DVec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let values: Vec<f64> = positions
            .iter()
            .map(|p| 0.3 - p.distance(DVec3::splat(0.5)) + rng.random_range(-0.05..0.05))
            .collect();
        let sig = SphereIntersectionGraph::build(&positions, &vec![0.04; n], 1.0).unwrap();
        let run = |threads| {
            sphcover_core::on_threads(threads, || {
                graph_cut_csr(
                    &positions,
                    &values,
                    sig.offsets(),
                    sig.neighbour_array(),
                    &GraphCutParams::sig(),
                )
                .unwrap()
            })
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a.labels, b.labels);
        assert_eq!(a.flow.to_bits(), b.flow.to_bits());
        assert!(a.stats.inconsistent > 0 && a.stats.inside > 0);
    }

    #[test]
    fn degenerate_inputs() {
        // Empty graph.
        let cut = graph_cut(&[], &[], &[], &GraphCutParams::default()).unwrap();
        assert!(cut.labels.is_empty() && cut.flow == 0.0);
        // One node, no edge; duplicated positions with a zero-length edge.
        let p = [DVec3::ZERO, DVec3::ZERO, DVec3::X];
        let cut = graph_cut(&p, &[0.2, -0.1, 0.0], &[[0, 1]], &GraphCutParams::tet()).unwrap();
        assert_eq!(
            cut.labels[0], cut.labels[1],
            "coincident nodes share a label"
        );
        assert!(!cut.labels[2]);
        // Errors.
        let bad_k = GraphCutParams::with_k(f64::NAN);
        let bad_degree = GraphCutParams {
            reference_degree: Some(0.0),
            ..GraphCutParams::sig()
        };
        assert!(matches!(
            graph_cut(&p, &[0.0; 3], &[], &bad_degree),
            Err(GraphCutError::InvalidReferenceDegree(_))
        ));
        assert!(matches!(
            graph_cut(&p, &[0.0; 3], &[], &bad_k),
            Err(GraphCutError::InvalidK(_))
        ));
        assert!(matches!(
            graph_cut(&p, &[0.0; 2], &[], &GraphCutParams::default()),
            Err(GraphCutError::LengthMismatch(_))
        ));
        assert!(matches!(
            graph_cut(&p, &[0.0, f64::NAN, 0.0], &[], &GraphCutParams::default()),
            Err(GraphCutError::NonFinite { index: 1 })
        ));
        assert!(matches!(
            graph_cut(&p, &[0.0; 3], &[[0, 3]], &GraphCutParams::default()),
            Err(GraphCutError::NodeOutOfRange { edge: 0, nodes: 3 })
        ));
    }
}
