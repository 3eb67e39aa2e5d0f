//! Maximum flow / minimum cut by the Boykov–Kolmogorov algorithm.
//!
//! Written from the paper (Y. Boykov, V. Kolmogorov, "An Experimental Comparison of
//! Min-Cut/Max-Flow Algorithms for Energy Minimization in Vision", IEEE TPAMI 26(9), 2004),
//! not from any existing implementation. Two search trees grow from the terminals: `S` from the
//! source and `T` from the sink, over arcs with residual capacity. When they touch, the path
//! through the touching arc is augmented by its bottleneck; the arcs it saturates cut subtrees
//! loose ("orphans"), which look for a new parent in their own tree (adoption, preferring the
//! shortest distance to the terminal, kept valid by time stamps as in §3.2.3 of the paper) or
//! are freed. Searching never restarts from scratch, which is why the method is fast on the
//! sparse, short-path graphs of geometry (meshes, sphere intersection graphs).
//!
//! Usage follows the faer pattern: build a [`FlowGraph`] once from terminal capacities and an
//! edge list, [`FlowGraph::solve`] it, then query which nodes are on the source side of the
//! minimum cut. Nodes reachable from the source in the final residual graph are on the source
//! side; every other node (including nodes reachable from neither terminal) is on the sink
//! side.
//!
//! Terminal capacities follow the paper's reduction: a node with capacity `a` from the source
//! and `b` to the sink carries `min(a, b)` of flow straight through, and only the difference
//! stays as a residual terminal capacity.
//!
//! Determinism: the algorithm is sequential; the result (flow value bit for bit, and the cut)
//! depends only on the input, in its order.

use std::borrow::Cow;
use std::collections::VecDeque;

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
    #[error("{array} has {found} entries for {expected} nodes")]
    LengthMismatch {
        /// `source_capacities` or `sink_capacities`.
        array: &'static str,
        /// Number of nodes.
        expected: usize,
        /// Length of the array.
        found: usize,
    },
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
/// Boykov–Kolmogorov algorithm (see the module documentation).
///
/// ```
/// use sphcover_recon::maxflow::{FlowEdge, FlowGraph};
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
/// # Ok::<(), sphcover_recon::maxflow::MaxFlowError>(())
/// ```
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
    /// Builds the network on `num_nodes` nodes. Node `v` has capacity `source_capacities[v]`
    /// from the source and `sink_capacities[v]` to the sink. Self-loops and edges with zero
    /// capacity both ways are dropped (they cross no cut). Every capacity must be finite and
    /// non-negative.
    pub fn new(
        num_nodes: usize,
        source_capacities: &[f64],
        sink_capacities: &[f64],
        edges: &[FlowEdge],
    ) -> Result<FlowGraph<'a>, MaxFlowError> {
        for (array, len) in [
            ("source_capacities", source_capacities.len()),
            ("sink_capacities", sink_capacities.len()),
        ] {
            if len != num_nodes {
                return Err(MaxFlowError::LengthMismatch {
                    array,
                    expected: num_nodes,
                    found: len,
                });
            }
        }
        let valid = |c: f64| c.is_finite() && c >= 0.0;
        for (what, caps) in [
            ("source arc of node", source_capacities),
            ("sink arc of node", sink_capacities),
        ] {
            if let Some(index) = caps.iter().position(|&c| !valid(c)) {
                return Err(MaxFlowError::InvalidCapacity {
                    what,
                    index,
                    value: caps[index],
                });
            }
        }
        let arcs = edges.len().saturating_mul(2);
        if num_nodes >= NO_PARENT as usize || arcs > MAX_ARCS {
            return Err(MaxFlowError::TooLarge {
                nodes: num_nodes,
                arcs,
            });
        }
        let mut degree = vec![0u32; num_nodes + 1];
        for (index, e) in edges.iter().enumerate() {
            if e.from as usize >= num_nodes || e.to as usize >= num_nodes {
                return Err(MaxFlowError::NodeOutOfRange {
                    edge: index,
                    from: e.from,
                    to: e.to,
                    nodes: num_nodes,
                });
            }
            for value in [e.capacity, e.reverse_capacity] {
                if !valid(value) {
                    return Err(MaxFlowError::InvalidCapacity {
                        what: "edge",
                        index,
                        value,
                    });
                }
            }
            if kept(e) {
                degree[e.from as usize] += 1;
                degree[e.to as usize] += 1;
            }
        }
        let mut first = vec![0u32; num_nodes + 1];
        for v in 0..num_nodes {
            first[v + 1] = first[v] + degree[v];
        }
        let num_arcs = first[num_nodes] as usize;
        let mut fill: Vec<u32> = first[..num_nodes].to_vec();
        let mut head = vec![0u32; num_arcs];
        let mut sister = vec![0u32; num_arcs];
        let mut residual = vec![0.0f64; num_arcs];
        for e in edges.iter().filter(|e| kept(e)) {
            let a = fill[e.from as usize];
            fill[e.from as usize] += 1;
            let b = fill[e.to as usize];
            fill[e.to as usize] += 1;
            head[a as usize] = e.to;
            head[b as usize] = e.from;
            sister[a as usize] = b;
            sister[b as usize] = a;
            residual[a as usize] = e.capacity;
            residual[b as usize] = e.reverse_capacity;
        }
        let mut flow = 0.0;
        let terminal = source_capacities
            .iter()
            .zip(sink_capacities)
            .map(|(&s, &t)| {
                flow += s.min(t);
                s - t
            })
            .collect();
        Ok(FlowGraph {
            first: Cow::Owned(first),
            head: Cow::Owned(head),
            sister,
            residual,
            terminal,
            tree: vec![FREE; num_nodes],
            parent: vec![NO_PARENT; num_nodes],
            stamp: vec![0; num_nodes],
            dist: vec![0; num_nodes],
            flow,
        })
    }

    /// Builds the network from a symmetric adjacency in compressed sparse rows: row `v` is
    /// `neighbors[offsets[v]..offsets[v + 1]]`, strictly ascending, without `v`, and `j` is
    /// in row `i` exactly when `i` is in row `j` (e.g. a
    /// [`sphcover_core::SphereIntersectionGraph`]). `capacities[a]` is the capacity of the
    /// arc of entry `a` (from the row's node to the entry's node); the vector becomes the
    /// residual capacities, so it is taken rather than copied. The arcs are the entries
    /// themselves, so no edge list is materialised and the adjacency is borrowed: about half
    /// the memory and time of [`FlowGraph::new`] on large graphs.
    pub fn from_symmetric_csr(
        source_capacities: &[f64],
        sink_capacities: &[f64],
        offsets: &'a [u32],
        neighbors: &'a [u32],
        capacities: Vec<f64>,
    ) -> Result<FlowGraph<'a>, MaxFlowError> {
        let n = offsets.len().saturating_sub(1);
        let mut graph = FlowGraph::new(n, source_capacities, sink_capacities, &[])?;
        if offsets.is_empty() {
            return if neighbors.is_empty() {
                Ok(graph)
            } else {
                Err(MaxFlowError::MalformedCsr("no offsets"))
            };
        }
        if capacities.len() != neighbors.len() {
            return Err(MaxFlowError::LengthMismatch {
                array: "capacities",
                expected: neighbors.len(),
                found: capacities.len(),
            });
        }
        if neighbors.len() > MAX_ARCS {
            return Err(MaxFlowError::TooLarge {
                nodes: n,
                arcs: neighbors.len(),
            });
        }
        if offsets[0] != 0
            || offsets[n] as usize != neighbors.len()
            || offsets.windows(2).any(|w| w[0] > w[1])
        {
            return Err(MaxFlowError::MalformedCsr("offsets"));
        }
        if let Some(index) = capacities
            .iter()
            .position(|&c| !(c.is_finite() && c >= 0.0))
        {
            return Err(MaxFlowError::InvalidCapacity {
                what: "edge",
                index,
                value: capacities[index],
            });
        }
        use rayon::prelude::*;
        let row = |v: usize| &neighbors[offsets[v] as usize..offsets[v + 1] as usize];
        let malformed = (0..n)
            .into_par_iter()
            .with_min_len(1024)
            .find_map_first(|v| {
                let r = row(v);
                if r.iter().any(|&j| j as usize >= n) {
                    Some("entry out of range")
                } else if r.contains(&(v as u32)) {
                    Some("self-loop")
                } else if r.windows(2).any(|w| w[0] >= w[1]) {
                    Some("row not strictly ascending")
                } else {
                    None
                }
            });
        if let Some(what) = malformed {
            return Err(MaxFlowError::MalformedCsr(what));
        }
        // The sister of each entry, in one walk without searches: the rows ascend, so
        // walking the rows in order and each row's entries above the diagonal (`v → j`,
        // `j > v`) in order meets the entries below the diagonal of every row `j` in their
        // own order. A cursor per row hands them out; an entry the cursor does not name
        // `v` has no reverse, and one never handed out keeps `u32::MAX`. (A binary search
        // per entry cost 40–50 ms at two threads on the 3.5 million entries of a 362K-point
        // scan's sphere intersection graph, its branches unpredictable.)
        let mut sister = vec![u32::MAX; neighbors.len()];
        let mut cursor: Vec<u32> = offsets[..n].to_vec();
        for v in 0..n {
            let upper = row(v).partition_point(|&j| (j as usize) < v);
            for k in offsets[v] as usize + upper..offsets[v + 1] as usize {
                let j = neighbors[k] as usize;
                let lower = cursor[j] as usize;
                if lower >= offsets[j + 1] as usize || neighbors[lower] as usize != v {
                    return Err(MaxFlowError::MalformedCsr("entry without a reverse entry"));
                }
                sister[k] = lower as u32;
                sister[lower] = k as u32;
                cursor[j] += 1;
            }
        }
        if sister.par_iter().any(|&s| s == u32::MAX) {
            return Err(MaxFlowError::MalformedCsr("entry without a reverse entry"));
        }
        graph.sister = sister;
        graph.first = Cow::Borrowed(offsets);
        graph.head = Cow::Borrowed(neighbors);
        graph.residual = capacities;
        Ok(graph)
    }

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

    #[inline]
    fn arcs(&self, v: u32) -> std::ops::Range<usize> {
        self.first[v as usize] as usize..self.first[v as usize + 1] as usize
    }

    /// Computes the maximum flow and the minimum cut. Calling it again pushes no more flow.
    pub fn solve(&mut self) -> MaxFlowInfo {
        let n = self.num_nodes();
        let mut active: VecDeque<u32> = VecDeque::new();
        let mut is_active = vec![false; n];
        let mut orphans: VecDeque<u32> = VecDeque::new();
        let mut info = MaxFlowInfo::default();
        let mut time: u32 = 0;
        self.push_two_arc_paths(&mut info);
        for v in 0..n {
            let t = self.terminal[v];
            if t != 0.0 {
                self.tree[v] = if t > 0.0 { SOURCE_TREE } else { SINK_TREE };
                self.parent[v] = TERMINAL;
                self.stamp[v] = time;
                self.dist[v] = 1;
                active.push_back(v as u32);
                is_active[v] = true;
            } else {
                self.tree[v] = FREE;
                self.parent[v] = NO_PARENT;
            }
        }
        // The node being grown and the arc to resume from: it stays current after an
        // augmentation through it, since its later arcs may still reach the other tree. Arcs
        // before the bridge need no second look: a neighbour there that is freed later
        // re-activates this node (adoption activates every tree neighbour with capacity).
        let mut current: Option<(u32, usize)> = None;
        loop {
            let (p, from) = match current
                .take()
                .filter(|&(p, _)| self.tree[p as usize] != FREE)
            {
                Some(c) => c,
                None => {
                    let mut next = None;
                    while let Some(v) = active.pop_front() {
                        is_active[v as usize] = false;
                        if self.tree[v as usize] != FREE {
                            next = Some(v);
                            break;
                        }
                    }
                    match next {
                        Some(v) => (v, self.first[v as usize] as usize),
                        None => break,
                    }
                }
            };
            let Some((bridge, at)) = self.grow(p, from, &mut active, &mut is_active) else {
                continue;
            };
            current = Some((p, at));
            time = time.wrapping_add(1);
            if time == 0 {
                // After 2³² augmentations the stamps would alias: invalidate them all.
                self.stamp.fill(0);
                time = 1;
            }
            self.augment(bridge, &mut orphans);
            info.augmentations += 1;
            while let Some(o) = orphans.pop_front() {
                info.orphans += 1;
                self.adopt(o, time, &mut active, &mut is_active, &mut orphans);
            }
        }
        info.flow = self.flow;
        info.source_side_nodes = self.tree.iter().filter(|&&t| t == SOURCE_TREE).count();
        info
    }

    /// Warm start: saturates every path source → v → w → sink over a single arc, in node
    /// order. On graph cuts of geometry most terminal capacity drains through such paths, and
    /// one sequential sweep over the arcs is far cheaper than as many tree augmentations and
    /// adoptions (measured: 1.3M augmentations → 14K on a sphere intersection graph of mean
    /// degree 244). Any valid flow is a valid start for the tree search.
    fn push_two_arc_paths(&mut self, info: &mut MaxFlowInfo) {
        for v in 0..self.num_nodes() {
            if self.terminal[v] <= 0.0 {
                continue;
            }
            for a in self.arcs(v as u32) {
                let w = self.head[a] as usize;
                if self.terminal[w] >= 0.0 || self.residual[a] <= 0.0 {
                    continue;
                }
                let b = self.terminal[v]
                    .min(self.residual[a])
                    .min(-self.terminal[w]);
                self.terminal[v] -= b;
                self.residual[a] -= b;
                self.residual[self.sister[a] as usize] += b;
                self.terminal[w] += b;
                if self.terminal[w] > 0.0 {
                    self.terminal[w] = 0.0;
                }
                self.flow += b;
                info.warm_start_pushes += 1;
                if self.terminal[v] <= 0.0 {
                    self.terminal[v] = 0.0;
                    break;
                }
            }
        }
    }

    /// Grows the tree of `p` over its arcs from arc `from` on; when the trees touch, returns
    /// the arc from the source tree to the sink tree with residual capacity, and the position
    /// of `p`'s arc where the scan stopped.
    fn grow(
        &mut self,
        p: u32,
        from: usize,
        active: &mut VecDeque<u32>,
        is_active: &mut [bool],
    ) -> Option<(u32, usize)> {
        let tp = self.tree[p as usize];
        let (sp, dp) = (self.stamp[p as usize], self.dist[p as usize]);
        for a in from..self.first[p as usize + 1] as usize {
            // Arc usable in the tree's direction: p → q in S, q → p in T.
            let cap = if tp == SOURCE_TREE {
                self.residual[a]
            } else {
                self.residual[self.sister[a] as usize]
            };
            if cap <= 0.0 {
                continue;
            }
            let q = self.head[a] as usize;
            let tq = self.tree[q];
            if tq == FREE {
                self.tree[q] = tp;
                self.parent[q] = self.sister[a];
                self.stamp[q] = sp;
                self.dist[q] = dp + 1;
                if !is_active[q] {
                    is_active[q] = true;
                    active.push_back(q as u32);
                }
            } else if tq != tp {
                let bridge = if tp == SOURCE_TREE {
                    a as u32
                } else {
                    self.sister[a]
                };
                return Some((bridge, a));
            } else if self.stamp[q] <= sp && self.dist[q] > dp {
                // Shorter route to the terminal through p (the paper's distance heuristic).
                self.parent[q] = self.sister[a];
                self.stamp[q] = sp;
                self.dist[q] = dp + 1;
            }
        }
        None
    }

    /// Pushes the bottleneck flow along source → … → tail(a) → head(a) → … → sink.
    fn augment(&mut self, a: u32, orphans: &mut VecDeque<u32>) {
        let a = a as usize;
        let tail = self.head[self.sister[a] as usize];
        let mut b = self.residual[a];
        let mut x = tail as usize;
        loop {
            let pa = self.parent[x];
            if pa == TERMINAL {
                b = b.min(self.terminal[x]);
                break;
            }
            b = b.min(self.residual[self.sister[pa as usize] as usize]);
            x = self.head[pa as usize] as usize;
        }
        x = self.head[a] as usize;
        loop {
            let pa = self.parent[x];
            if pa == TERMINAL {
                b = b.min(-self.terminal[x]);
                break;
            }
            b = b.min(self.residual[pa as usize]);
            x = self.head[pa as usize] as usize;
        }

        self.residual[a] -= b;
        self.residual[self.sister[a] as usize] += b;
        x = tail as usize;
        loop {
            let pa = self.parent[x];
            if pa == TERMINAL {
                self.terminal[x] -= b;
                if self.terminal[x] <= 0.0 {
                    self.terminal[x] = 0.0;
                    self.parent[x] = ORPHAN;
                    orphans.push_back(x as u32);
                }
                break;
            }
            let forward = self.sister[pa as usize] as usize;
            self.residual[forward] -= b;
            self.residual[pa as usize] += b;
            let next = self.head[pa as usize] as usize;
            if self.residual[forward] <= 0.0 {
                self.residual[forward] = 0.0;
                self.parent[x] = ORPHAN;
                orphans.push_back(x as u32);
            }
            x = next;
        }
        x = self.head[a] as usize;
        loop {
            let pa = self.parent[x];
            if pa == TERMINAL {
                self.terminal[x] += b;
                if self.terminal[x] >= 0.0 {
                    self.terminal[x] = 0.0;
                    self.parent[x] = ORPHAN;
                    orphans.push_back(x as u32);
                }
                break;
            }
            let forward = pa as usize;
            self.residual[forward] -= b;
            self.residual[self.sister[forward] as usize] += b;
            let next = self.head[forward] as usize;
            if self.residual[forward] <= 0.0 {
                self.residual[forward] = 0.0;
                self.parent[x] = ORPHAN;
                orphans.push_back(x as u32);
            }
            x = next;
        }
        self.flow += b;
    }

    /// Finds a new parent for orphan `p` in its own tree, or frees it (making its children
    /// orphans and its usable neighbours active).
    fn adopt(
        &mut self,
        p: u32,
        time: u32,
        active: &mut VecDeque<u32>,
        is_active: &mut [bool],
        orphans: &mut VecDeque<u32>,
    ) {
        let tp = self.tree[p as usize];
        let mut best_arc = NO_PARENT;
        let mut best_dist = u32::MAX;
        for a in self.arcs(p) {
            // A parent q must be able to send to p (S) or receive from p (T).
            let cap = if tp == SOURCE_TREE {
                self.residual[self.sister[a] as usize]
            } else {
                self.residual[a]
            };
            if cap <= 0.0 {
                continue;
            }
            let q = self.head[a];
            if self.tree[q as usize] != tp {
                continue;
            }
            // Walk to the root to see whether q still hangs from the terminal.
            let mut d: u32 = 0;
            let mut j = q as usize;
            loop {
                if self.stamp[j] == time {
                    d = d.saturating_add(self.dist[j]);
                    break;
                }
                let pj = self.parent[j];
                d = d.saturating_add(1);
                if pj == TERMINAL {
                    self.stamp[j] = time;
                    self.dist[j] = 1;
                    break;
                }
                if pj == ORPHAN || pj == NO_PARENT {
                    d = u32::MAX;
                    break;
                }
                j = self.head[pj as usize] as usize;
            }
            if d == u32::MAX {
                continue;
            }
            if d < best_dist {
                best_arc = a as u32;
                best_dist = d;
            }
            // Remember the distances along the path for the rest of this adoption round.
            let mut j = q as usize;
            let mut dd = d;
            while self.stamp[j] != time {
                self.stamp[j] = time;
                self.dist[j] = dd;
                dd = dd.saturating_sub(1);
                j = self.head[self.parent[j] as usize] as usize;
            }
        }
        if best_arc != NO_PARENT {
            self.parent[p as usize] = best_arc;
            self.stamp[p as usize] = time;
            self.dist[p as usize] = best_dist.saturating_add(1);
            return;
        }
        for a in self.arcs(p) {
            let q = self.head[a] as usize;
            if self.tree[q] != tp {
                continue;
            }
            let cap = if tp == SOURCE_TREE {
                self.residual[self.sister[a] as usize]
            } else {
                self.residual[a]
            };
            if cap > 0.0 && !is_active[q] {
                is_active[q] = true;
                active.push_back(q as u32);
            }
            let pq = self.parent[q];
            if pq != TERMINAL && pq != ORPHAN && pq != NO_PARENT && self.head[pq as usize] == p {
                self.parent[q] = ORPHAN;
                orphans.push_back(q as u32);
            }
        }
        self.tree[p as usize] = FREE;
        self.parent[p as usize] = NO_PARENT;
    }
}

/// True when an edge can carry flow across some cut.
fn kept(e: &FlowEdge) -> bool {
    e.from != e.to && (e.capacity > 0.0 || e.reverse_capacity > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use petgraph::algo::dinics;
    use petgraph::graph::{DiGraph, NodeIndex};
    use proptest::prelude::*;

    /// Capacity of the cut `(S, V∖S)` computed from the input, independently of the solver.
    fn cut_capacity(source: &[f64], sink: &[f64], edges: &[FlowEdge], side: &[bool]) -> f64 {
        let mut c = 0.0;
        for v in 0..side.len() {
            c += if side[v] { sink[v] } else { source[v] };
        }
        for e in edges {
            let (f, t) = (side[e.from as usize], side[e.to as usize]);
            if f && !t {
                c += e.capacity;
            } else if t && !f {
                c += e.reverse_capacity;
            }
        }
        c
    }

    fn oracle(source: &[f64], sink: &[f64], edges: &[FlowEdge]) -> f64 {
        let n = source.len();
        let mut g: DiGraph<(), f64> = DiGraph::new();
        let nodes: Vec<NodeIndex> = (0..n + 2).map(|_| g.add_node(())).collect();
        let (s, t) = (nodes[n], nodes[n + 1]);
        for v in 0..n {
            g.add_edge(s, nodes[v], source[v]);
            g.add_edge(nodes[v], t, sink[v]);
        }
        for e in edges {
            g.add_edge(nodes[e.from as usize], nodes[e.to as usize], e.capacity);
            g.add_edge(
                nodes[e.to as usize],
                nodes[e.from as usize],
                e.reverse_capacity,
            );
        }
        dinics(&g, s, t).0
    }

    fn random_network() -> impl Strategy<Value = (Vec<f64>, Vec<f64>, Vec<FlowEdge>)> {
        (1usize..14).prop_flat_map(|n| {
            let caps = proptest::collection::vec(0u32..6, n);
            let edges = proptest::collection::vec(
                (0..n as u32, 0..n as u32, 0u32..9, 0u32..9).prop_map(|(f, t, c, r)| FlowEdge {
                    from: f,
                    to: t,
                    capacity: c as f64,
                    reverse_capacity: r as f64,
                }),
                0..3 * n,
            );
            (caps.clone(), caps, edges).prop_map(|(s, t, e)| {
                (
                    s.into_iter().map(f64::from).collect(),
                    t.into_iter().map(f64::from).collect(),
                    e,
                )
            })
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// Integer capacities make every flow exact: the value must equal the oracle's, and
        /// the reported side must be a cut of exactly that capacity (hence a minimum cut).
        #[test]
        fn matches_petgraph_and_cut_is_minimum((source, sink, edges) in random_network()) {
            let mut g = FlowGraph::new(source.len(), &source, &sink, &edges).unwrap();
            let info = g.solve();
            let expected = oracle(&source, &sink, &edges);
            prop_assert_eq!(info.flow, expected);
            let side = g.source_side();
            prop_assert_eq!(cut_capacity(&source, &sink, &edges, &side), expected);
            prop_assert_eq!(info.source_side_nodes, side.iter().filter(|&&s| s).count());
            // Solving again finds no more flow.
            prop_assert_eq!(g.solve().flow, expected);
            // The same network as a symmetric CSR: merge parallel edges, drop self-loops.
            let n = source.len();
            let mut caps = std::collections::BTreeMap::new();
            for e in &edges {
                if e.from != e.to {
                    *caps.entry((e.from, e.to)).or_insert(0.0) += e.capacity;
                    *caps.entry((e.to, e.from)).or_insert(0.0) += e.reverse_capacity;
                }
            }
            let mut offsets = vec![0u32; n + 1];
            let (mut neighbors, mut capacities) = (Vec::new(), Vec::new());
            for (&(a, b), &c) in &caps {
                offsets[a as usize + 1] += 1;
                neighbors.push(b);
                capacities.push(c);
            }
            for v in 0..n {
                offsets[v + 1] += offsets[v];
            }
            let mut g = FlowGraph::from_symmetric_csr(&source, &sink, &offsets, &neighbors, capacities).unwrap();
            prop_assert_eq!(g.solve().flow, expected);
            prop_assert_eq!(cut_capacity(&source, &sink, &edges, &g.source_side()), expected);
        }

        /// Every entry of a symmetric CSR gets its reverse entry as sister; an adjacency with
        /// one entry dropped (an edge in one direction only) is refused.
        #[test]
        fn sisters_are_the_reverse_entries(
            n in 1usize..40,
            pairs in prop::collection::btree_set((0u32..40, 0u32..40), 0..200),
            drop in any::<prop::sample::Index>(),
        ) {
            let rows: Vec<std::collections::BTreeSet<u32>> = (0..n as u32)
                .map(|v| {
                    pairs
                        .iter()
                        .filter(|&&(a, b)| a != b && (a as usize) < n && (b as usize) < n)
                        .filter_map(|&(a, b)| if a == v { Some(b) } else if b == v { Some(a) } else { None })
                        .collect()
                })
                .collect();
            let csr = |rows: &[std::collections::BTreeSet<u32>]| {
                let mut offsets = vec![0u32];
                let mut neighbors = Vec::new();
                for row in rows {
                    neighbors.extend(row.iter().copied());
                    offsets.push(neighbors.len() as u32);
                }
                (offsets, neighbors)
            };
            let z = vec![0.0; n];
            let (offsets, neighbors) = csr(&rows);
            let g = FlowGraph::from_symmetric_csr(&z, &z, &offsets, &neighbors, vec![1.0; neighbors.len()]).unwrap();
            for v in 0..n {
                for k in offsets[v] as usize..offsets[v + 1] as usize {
                    let s = g.sister[k] as usize;
                    prop_assert_eq!(g.sister[s] as usize, k);
                    prop_assert_eq!(neighbors[s] as usize, v);
                    let j = neighbors[k] as usize;
                    prop_assert!((offsets[j] as usize..offsets[j + 1] as usize).contains(&s));
                }
            }
            if !neighbors.is_empty() {
                let mut one_sided = rows.clone();
                let k = drop.index(neighbors.len());
                let v = offsets.partition_point(|&o| o as usize <= k) - 1;
                one_sided[v].remove(&neighbors[k]);
                let (offsets, neighbors) = csr(&one_sided);
                prop_assert!(matches!(
                    FlowGraph::from_symmetric_csr(&z, &z, &offsets, &neighbors, vec![1.0; neighbors.len()]),
                    Err(MaxFlowError::MalformedCsr(_))
                ));
            }
        }

        /// Real-valued capacities: flow and cut agree to rounding.
        #[test]
        fn real_capacities_give_consistent_cut(
            (source, sink, edges) in random_network(),
            scale in 0.001f64..1000.0,
        ) {
            let f = |c: f64| c * scale * 1.0137;
            let source: Vec<f64> = source.into_iter().map(f).collect();
            let sink: Vec<f64> = sink.into_iter().map(f).collect();
            let edges: Vec<FlowEdge> = edges
                .into_iter()
                .map(|e| FlowEdge { capacity: f(e.capacity), reverse_capacity: f(e.reverse_capacity), ..e })
                .collect();
            let mut g = FlowGraph::new(source.len(), &source, &sink, &edges).unwrap();
            let flow = g.solve().flow;
            let cut = cut_capacity(&source, &sink, &edges, &g.source_side());
            let expected = oracle(&source, &sink, &edges);
            let tol = 1e-9 * (1.0 + expected.abs());
            prop_assert!((flow - cut).abs() <= tol, "flow {} cut {}", flow, cut);
            prop_assert!((flow - expected).abs() <= tol, "flow {} oracle {}", flow, expected);
        }
    }

    #[test]
    fn grid_with_a_thin_wall() {
        // A 30 × 30 grid: left column tied to the source, right column to the sink, strong
        // edges except a weak vertical wall at x = 17: the cut is the wall.
        let n = 30;
        let id = |x: usize, y: usize| (y * n + x) as u32;
        let mut source = vec![0.0; n * n];
        let mut sink = vec![0.0; n * n];
        let mut edges = Vec::new();
        for y in 0..n {
            source[id(0, y) as usize] = 100.0;
            sink[id(n - 1, y) as usize] = 100.0;
            for x in 0..n {
                if x + 1 < n {
                    let c = if x == 17 { 1.0 } else { 10.0 };
                    edges.push(FlowEdge::undirected(id(x, y), id(x + 1, y), c));
                }
                if y + 1 < n {
                    edges.push(FlowEdge::undirected(id(x, y), id(x, y + 1), 10.0));
                }
            }
        }
        let mut g = FlowGraph::new(n * n, &source, &sink, &edges).unwrap();
        let info = g.solve();
        assert_eq!(info.flow, n as f64);
        for y in 0..n {
            for x in 0..n {
                assert_eq!(g.is_source_side(id(x, y) as usize), x <= 17);
            }
        }
    }

    #[test]
    fn empty_and_isolated_nodes() {
        let mut g = FlowGraph::new(0, &[], &[], &[]).unwrap();
        assert_eq!(g.solve().flow, 0.0);
        // One node tied to both terminals: flow straight through, the rest decides the side.
        let mut g = FlowGraph::new(2, &[2.0, 0.0], &[5.0, 0.0], &[]).unwrap();
        let info = g.solve();
        assert_eq!(info.flow, 2.0);
        assert!(!g.is_source_side(0) && !g.is_source_side(1) && !g.is_source_side(9));
    }

    #[test]
    fn malformed_csr_is_refused() {
        let z = [0.0; 3];
        // The graph borrows the adjacency: only whether it was built matters here.
        let csr = |offsets: &[u32], neighbors: &[u32]| {
            FlowGraph::from_symmetric_csr(&z, &z, offsets, neighbors, vec![1.0; neighbors.len()])
                .map(|_| ())
        };
        assert!(csr(&[0, 1, 2, 2], &[1, 0]).is_ok());
        for (offsets, neighbors) in [
            (&[0u32, 1, 1, 1][..], &[1u32][..]),
            (&[0, 1, 2, 2], &[0, 0]),
            (&[0, 1, 2, 2], &[1, 5]),
            (&[0, 2, 3, 4], &[2, 1, 0, 0]),
            (&[0, 1, 2, 3], &[1, 0]),
            (&[1, 1, 2, 2], &[1, 0]),
        ] {
            assert!(
                matches!(csr(offsets, neighbors), Err(MaxFlowError::MalformedCsr(_))),
                "{offsets:?} {neighbors:?}"
            );
        }
        assert!(matches!(
            FlowGraph::from_symmetric_csr(&z, &z, &[0, 1, 2, 2], &[1, 0], vec![1.0]),
            Err(MaxFlowError::LengthMismatch { .. })
        ));
        assert!(matches!(
            FlowGraph::from_symmetric_csr(&z, &z, &[0, 1, 2, 2], &[1, 0], vec![1.0, -1.0]),
            Err(MaxFlowError::InvalidCapacity { index: 1, .. })
        ));
    }

    #[test]
    fn bad_input_is_refused() {
        let e = |f, t, c| [FlowEdge::undirected(f, t, c)];
        assert!(matches!(
            FlowGraph::new(2, &[0.0], &[0.0, 0.0], &[]),
            Err(MaxFlowError::LengthMismatch { .. })
        ));
        assert!(matches!(
            FlowGraph::new(2, &[0.0; 2], &[0.0; 2], &e(0, 2, 1.0)),
            Err(MaxFlowError::NodeOutOfRange { edge: 0, .. })
        ));
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                FlowGraph::new(2, &[0.0; 2], &[0.0; 2], &e(0, 1, bad)),
                Err(MaxFlowError::InvalidCapacity { what: "edge", .. })
            ));
            assert!(matches!(
                FlowGraph::new(2, &[0.0, bad], &[0.0; 2], &[]),
                Err(MaxFlowError::InvalidCapacity { index: 1, .. })
            ));
        }
    }

    /// Speed on a 3D grid graph of about 1M nodes and 3M edges (6M arcs) plus a random
    /// long-range layer, with noisy terminal capacities, like a graph-cut of a scan.
    /// Run with `cargo test --release -p sphcover-recon maxflow_speed -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn maxflow_speed() {
        use rand::{Rng, SeedableRng};
        let side = 100usize;
        let n = side * side * side;
        let id = |x: usize, y: usize, z: usize| ((z * side + y) * side + x) as u32;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut source = vec![0.0; n];
        let mut sink = vec![0.0; n];
        let mut edges = Vec::new();
        let c = DVecLike(side as f64 / 2.0);
        for z in 0..side {
            for y in 0..side {
                for x in 0..side {
                    let d = c.dist(x, y, z) - side as f64 / 3.0;
                    let noise: f64 = rng.random_range(-8.0..8.0);
                    let f = -d + noise;
                    if f > 0.0 {
                        source[id(x, y, z) as usize] = 27.0 * f.min(10.0);
                    } else {
                        sink[id(x, y, z) as usize] = 27.0 * (-f).min(10.0);
                    }
                    for (dx, dy, dz) in [(1, 0, 0), (0, 1, 0), (0, 0, 1)] {
                        let (a, b, cc) = (x + dx, y + dy, z + dz);
                        if a < side && b < side && cc < side {
                            let w = rng.random_range(1.0..20.0);
                            edges.push(FlowEdge::undirected(id(x, y, z), id(a, b, cc), w));
                        }
                    }
                }
            }
        }
        // Extra edges to reach the degree of a sphere intersection graph (≈ 40).
        for v in 0..n as u32 {
            for _ in 0..17 {
                let (x, y, z) = (
                    v as usize % side,
                    (v as usize / side) % side,
                    v as usize / (side * side),
                );
                let mut j = |a: usize| {
                    (a as i64 + rng.random_range(-2i64..=2)).clamp(0, side as i64 - 1) as usize
                };
                let (a, b, cc) = (j(x), j(y), j(z));
                let w = rng.random_range(1.0..20.0);
                edges.push(FlowEdge::undirected(v, id(a, b, cc), w));
            }
        }
        let t0 = std::time::Instant::now();
        let mut g = FlowGraph::new(n, &source, &sink, &edges).unwrap();
        let t1 = std::time::Instant::now();
        let info = g.solve();
        let t2 = std::time::Instant::now();
        println!(
            "maxflow_speed: {} nodes, {} arcs: build {:.2} s, solve {:.2} s, {:?}",
            n,
            g.num_arcs(),
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            info
        );
    }

    struct DVecLike(f64);
    impl DVecLike {
        fn dist(&self, x: usize, y: usize, z: usize) -> f64 {
            let d = |a: usize| a as f64 - self.0;
            (d(x) * d(x) + d(y) * d(y) + d(z) * d(z)).sqrt()
        }
    }
}
