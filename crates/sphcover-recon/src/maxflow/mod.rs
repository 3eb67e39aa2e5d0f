//! Maximum flow / minimum cut by the Boykov–Kolmogorov algorithm.
//!
//! The method is described on [`FlowGraph`].

mod build;
mod solve;

use sphcover_core::LengthMismatch;
use std::borrow::Cow;

use thiserror::Error;

/// Parent marker: the node hangs directly from its tree's terminal.
const TERMINAL: u32 = u32::MAX;
/// Parent marker: the node lost its parent arc and awaits adoption.
const ORPHAN: u32 = u32::MAX - 1;
/// Parent marker: the node is in no tree.
const NO_PARENT: u32 = u32::MAX - 2;
/// Largest arc count: arc indices must stay below the parent markers.
const MAX_ARCS: usize = (u32::MAX - 3) as usize;

const FREE: u8 = 0;
const SOURCE_TREE: u8 = 1;
const SINK_TREE: u8 = 2;

/// Why a [`FlowGraph`] could not be built.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum MaxFlowError {
    /// The terminal capacity arrays do not have one entry per node.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
    /// An edge names a node that does not exist.
    #[error("edge {edge} joins nodes {from} and {to}, but there are {nodes} nodes")]
    NodeOutOfRange {
        /// Index of the edge in the input.
        edge: usize,
        /// Tail node.
        from: u32,
        /// Head node.
        to: u32,
        /// Number of nodes.
        nodes: usize,
    },
    /// A capacity is negative, NaN or infinite.
    #[error("{what} {index} has capacity {value}, which is not finite and non-negative")]
    InvalidCapacity {
        /// `"edge"`, `"source arc of node"` or `"sink arc of node"`.
        what: &'static str,
        /// Index of the edge or node.
        index: usize,
        /// The capacity given.
        value: f64,
    },
    /// A symmetric CSR graph is malformed: an offset is out of order or out of range, a row
    /// is not strictly ascending, an entry is out of range or a self-loop, or an entry has no
    /// reverse entry.
    #[error("the CSR graph is not a symmetric adjacency: {0}")]
    MalformedCsr(&'static str),
    /// More nodes or arcs than `u32` indices can name.
    #[error("{nodes} nodes and {arcs} arcs exceed the u32 index range")]
    TooLarge {
        /// Number of nodes.
        nodes: usize,
        /// Number of directed arcs (two per edge).
        arcs: usize,
    },
}

/// An edge between two non-terminal nodes, with a capacity in each direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlowEdge {
    /// Tail node.
    pub from: u32,
    /// Head node.
    pub to: u32,
    /// Capacity from `from` to `to`.
    pub capacity: f64,
    /// Capacity from `to` to `from`.
    pub reverse_capacity: f64,
}

impl FlowEdge {
    /// An undirected edge: the same capacity both ways.
    pub fn undirected(from: u32, to: u32, capacity: f64) -> FlowEdge {
        FlowEdge {
            from,
            to,
            capacity,
            reverse_capacity: capacity,
        }
    }
}

/// Counters of one [`FlowGraph::solve`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaxFlowInfo {
    /// The maximum flow value (= the capacity of the minimum cut).
    pub flow: f64,
    /// Paths source → v → w → sink saturated by the warm start.
    pub warm_start_pushes: u64,
    /// Augmenting paths pushed through the search trees.
    pub augmentations: u64,
    /// Orphans processed (adopted or freed).
    pub orphans: u64,
    /// Nodes on the source side of the cut.
    pub source_side_nodes: usize,
}

/// A flow network in compressed sparse rows with terminal capacities, solved in place by the
/// Boykov–Kolmogorov algorithm (see [`FlowGraph`]).
///
/// ```
/// use sphcover_recon::{FlowEdge, FlowGraph};
///
/// // source → 0 (3), 0 → 1 (2), 1 → sink (4): the edge 0–1 is the bottleneck.
/// let mut g = FlowGraph::new(
///     2,
///     &[3.0, 0.0],
///     &[0.0, 4.0],
///     &[FlowEdge { from: 0, to: 1, capacity: 2.0, reverse_capacity: 0.0 }],
/// )?;
/// let info = g.solve();
/// assert_eq!(info.flow, 2.0);
/// assert!(g.is_source_side(0) && !g.is_source_side(1));
/// # Ok::<(), sphcover_recon::MaxFlowError>(())
/// ```
///
/// Written from the paper (Y. Boykov, V. Kolmogorov, "An Experimental Comparison of
/// Min-Cut/Max-Flow Algorithms for Energy Minimization in Vision", IEEE TPAMI 26(9), 2004),
/// not from any existing implementation. Two search trees grow from the terminals: `S` from the
/// source and `T` from the sink, over arcs with residual capacity. When they touch, the path
/// through the touching arc is augmented by its bottleneck; the arcs it saturates cut subtrees
/// loose ("orphans"), which look for a new parent in their own tree (adoption, preferring the
/// shortest distance to the terminal, kept valid by time stamps as in §3.2.3 of the paper) or
/// are freed. Searching never restarts from scratch, which is why the method is fast on the
/// sparse, short-path graphs of geometry (meshes, sphere intersection graphs).
///
/// Usage follows the faer pattern: build a [`FlowGraph`] once from terminal capacities and an
/// edge list, [`FlowGraph::solve`] it, then query which nodes are on the source side of the
/// minimum cut. Nodes reachable from the source in the final residual graph are on the source
/// side; every other node (including nodes reachable from neither terminal) is on the sink
/// side.
///
/// Terminal capacities follow the paper's reduction: a node with capacity `a` from the source
/// and `b` to the sink carries `min(a, b)` of flow straight through, and only the difference
/// stays as a residual terminal capacity.
///
/// Determinism: the algorithm is sequential; the result (flow value bit for bit, and the cut)
/// depends only on the input, in its order.
///
/// Layout: the types and the graph's queries are here; `build` lays out and checks the
/// network (from an edge list or a borrowed symmetric CSR), `solve` runs the search.
#[derive(Clone, Debug)]
pub struct FlowGraph<'a> {
    /// Arcs of node `v` are `first[v]..first[v + 1]`.
    first: Cow<'a, [u32]>,
    /// Head node of each arc: borrowed from the caller's adjacency by
    /// [`FlowGraph::from_symmetric_csr`] (4 bytes per arc that a copy would add at the
    /// reconstruction's peak of memory).
    head: Cow<'a, [u32]>,
    /// The opposite arc of each arc.
    sister: Vec<u32>,
    /// Residual capacity of each arc.
    residual: Vec<f64>,
    /// Residual terminal capacity: `> 0` from the source, `< 0` to the sink.
    terminal: Vec<f64>,
    /// Tree of each node: [`FREE`], [`SOURCE_TREE`] or [`SINK_TREE`].
    tree: Vec<u8>,
    /// Arc from each node to its parent, or one of the markers.
    parent: Vec<u32>,
    /// Time stamp of the last time the node's distance was known valid.
    stamp: Vec<u32>,
    /// Distance to the tree's terminal, valid when `stamp` is current.
    dist: Vec<u32>,
    /// Flow pushed so far (including the flow straight through terminal pairs).
    flow: f64,
}

impl<'a> FlowGraph<'a> {
    /// Number of nodes (terminals excluded).
    pub fn num_nodes(&self) -> usize {
        self.terminal.len()
    }

    /// Number of directed arcs kept (two per kept edge).
    pub fn num_arcs(&self) -> usize {
        self.head.len()
    }

    /// The flow pushed so far; after [`FlowGraph::solve`], the maximum flow.
    pub fn flow(&self) -> f64 {
        self.flow
    }

    /// True when node `v` is on the source side of the cut found by [`FlowGraph::solve`]
    /// (reachable from the source in the residual graph). False for an out-of-range `v`.
    pub fn is_source_side(&self, v: usize) -> bool {
        self.tree.get(v) == Some(&SOURCE_TREE)
    }

    /// [`FlowGraph::is_source_side`] for every node.
    pub fn source_side(&self) -> Vec<bool> {
        self.tree.iter().map(|&t| t == SOURCE_TREE).collect()
    }
}
