//! Building a [`FlowGraph`]: from an edge list, or by borrowing a symmetric adjacency in
//! compressed sparse rows, with every input checked.
//!
//! Construction runs once per graph and is all validation and layout (the arcs in rows,
//! their sister arcs, the paper's reduction of terminal capacities); the search in `solve`
//! then trusts the arrays it is given.

use sphcover_core::LengthMismatch;
use std::borrow::Cow;

use super::{FREE, FlowEdge, FlowGraph, MAX_ARCS, MaxFlowError, NO_PARENT};

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
                return Err(MaxFlowError::LengthMismatch(LengthMismatch {
                    array,
                    expected: num_nodes,
                    found: len,
                }));
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
    /// `neighbours[offsets[v]..offsets[v + 1]]`, strictly ascending, without `v`, and `j` is
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
        neighbours: &'a [u32],
        capacities: Vec<f64>,
    ) -> Result<FlowGraph<'a>, MaxFlowError> {
        let n = offsets.len().saturating_sub(1);
        let mut graph = FlowGraph::new(n, source_capacities, sink_capacities, &[])?;
        if offsets.is_empty() {
            return if neighbours.is_empty() {
                Ok(graph)
            } else {
                Err(MaxFlowError::MalformedCsr("no offsets"))
            };
        }
        if capacities.len() != neighbours.len() {
            return Err(MaxFlowError::LengthMismatch(LengthMismatch {
                array: "capacities",
                expected: neighbours.len(),
                found: capacities.len(),
            }));
        }
        if neighbours.len() > MAX_ARCS {
            return Err(MaxFlowError::TooLarge {
                nodes: n,
                arcs: neighbours.len(),
            });
        }
        if offsets[0] != 0
            || offsets[n] as usize != neighbours.len()
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
        let row = |v: usize| &neighbours[offsets[v] as usize..offsets[v + 1] as usize];
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
        // per entry would cost more: its branches are unpredictable.)
        let mut sister = vec![u32::MAX; neighbours.len()];
        let mut cursor: Vec<u32> = offsets[..n].to_vec();
        for v in 0..n {
            let upper = row(v).partition_point(|&j| (j as usize) < v);
            for k in offsets[v] as usize + upper..offsets[v + 1] as usize {
                let j = neighbours[k] as usize;
                let lower = cursor[j] as usize;
                if lower >= offsets[j + 1] as usize || neighbours[lower] as usize != v {
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
        graph.head = Cow::Borrowed(neighbours);
        graph.residual = capacities;
        Ok(graph)
    }
}

/// True when an edge can carry flow across some cut.
fn kept(e: &FlowEdge) -> bool {
    e.from != e.to && (e.capacity > 0.0 || e.reverse_capacity > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
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
                let mut neighbours = Vec::new();
                for row in rows {
                    neighbours.extend(row.iter().copied());
                    offsets.push(neighbours.len() as u32);
                }
                (offsets, neighbours)
            };
            let z = vec![0.0; n];
            let (offsets, neighbours) = csr(&rows);
            let g = FlowGraph::from_symmetric_csr(&z, &z, &offsets, &neighbours, vec![1.0; neighbours.len()]).unwrap();
            for v in 0..n {
                for k in offsets[v] as usize..offsets[v + 1] as usize {
                    let s = g.sister[k] as usize;
                    prop_assert_eq!(g.sister[s] as usize, k);
                    prop_assert_eq!(neighbours[s] as usize, v);
                    let j = neighbours[k] as usize;
                    prop_assert!((offsets[j] as usize..offsets[j + 1] as usize).contains(&s));
                }
            }
            if !neighbours.is_empty() {
                let mut one_sided = rows.clone();
                let k = drop.index(neighbours.len());
                let v = offsets.partition_point(|&o| o as usize <= k) - 1;
                one_sided[v].remove(&neighbours[k]);
                let (offsets, neighbours) = csr(&one_sided);
                prop_assert!(matches!(
                    FlowGraph::from_symmetric_csr(&z, &z, &offsets, &neighbours, vec![1.0; neighbours.len()]),
                    Err(MaxFlowError::MalformedCsr(_))
                ));
            }
        }
    }

    #[test]
    fn malformed_csr_is_refused() {
        let z = [0.0; 3];
        // The graph borrows the adjacency: only whether it was built matters here.
        let csr = |offsets: &[u32], neighbours: &[u32]| {
            FlowGraph::from_symmetric_csr(&z, &z, offsets, neighbours, vec![1.0; neighbours.len()])
                .map(|_| ())
        };
        assert!(csr(&[0, 1, 2, 2], &[1, 0]).is_ok());
        for (offsets, neighbours) in [
            (&[0u32, 1, 1, 1][..], &[1u32][..]),
            (&[0, 1, 2, 2], &[0, 0]),
            (&[0, 1, 2, 2], &[1, 5]),
            (&[0, 2, 3, 4], &[2, 1, 0, 0]),
            (&[0, 1, 2, 3], &[1, 0]),
            (&[1, 1, 2, 2], &[1, 0]),
        ] {
            assert!(
                matches!(csr(offsets, neighbours), Err(MaxFlowError::MalformedCsr(_))),
                "{offsets:?} {neighbours:?}"
            );
        }
        assert!(matches!(
            FlowGraph::from_symmetric_csr(&z, &z, &[0, 1, 2, 2], &[1, 0], vec![1.0]),
            Err(MaxFlowError::LengthMismatch(_))
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
            Err(MaxFlowError::LengthMismatch(_))
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
}
