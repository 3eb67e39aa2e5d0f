//! The sphere intersection graph (SIG) of a cover (thesis Appendix B, §5.2.3).
//!
//! The method is described on [`SphereIntersectionGraph`].

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;
use thiserror::Error;

use crate::ball_index::{BallIndex, BallIndexError};

/// Rows computed by one parallel task. Fixed, so the work split never depends on the pool.
/// A power of two, so that target blocks (see [`target_block_shift`]) hold whole chunks.
const ROWS_PER_CHUNK: usize = 512;
const _: () = assert!(ROWS_PER_CHUNK.is_power_of_two());

/// Most target blocks the upper halves are transposed in. A chunk keeps one group of pairs
/// per block it reaches, so the cap bounds that bookkeeping at this many groups per chunk
/// however the supports are ordered, and still leaves plenty of blocks to share among threads.
const MAX_TARGET_BLOCKS: usize = 256;

/// Why a [`SphereIntersectionGraph`] could not be built.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum SigError {
    /// `centres` and `radii` have different lengths.
    #[error("{centres} centres but {radii} radii")]
    LengthMismatch {
        /// Number of centres given.
        centres: usize,
        /// Number of radii given.
        radii: usize,
    },
    /// The shrink factor is not a finite positive number.
    #[error("shrink factor {shrink} is not finite and positive")]
    InvalidShrink {
        /// The shrink factor given.
        shrink: f64,
    },
    /// A centre has a non-finite coordinate.
    #[error("centre {index} is not finite: {centre}")]
    InvalidCentre {
        /// Index of the support.
        index: usize,
        /// The centre given.
        centre: DVec3,
    },
    /// A radius is negative or not finite.
    #[error("radius {index} is not finite and non-negative: {radius}")]
    InvalidRadius {
        /// Index of the support.
        index: usize,
        /// The radius given.
        radius: f64,
    },
    /// Node indices are `u32`; this many supports cannot be indexed.
    #[error("{len} supports exceed the u32 index range")]
    TooManySupports {
        /// Number of supports given.
        len: usize,
    },
    /// The graph has more directed entries than `u32` offsets can address.
    #[error(
        "more than {} directed edges: the u32 offsets cannot index them",
        u32::MAX
    )]
    TooManyEdges,
}

/// The sphere intersection graph of a cover, in compressed sparse rows.
///
/// Supports `i ≠ j` are adjacent when their balls, shrunk by a factor `s`, overlap:
///
/// ```text
/// i ~ j  ⇔  ‖c_i − c_j‖ < s·(r_i + r_j)
/// ```
///
/// The shrink factor only thins the graph (the thesis uses `s = 0.7`, which takes the mean
/// degree from about 100 to about 40 with no visible change in results); `s = 1` gives the true
/// intersection graph. Every other computation uses the true radii.
///
/// The graph is stored as compressed sparse rows with `u32` indices: row `i` is
/// `neighbours[offsets[i]..offsets[i + 1]]`, sorted ascending, without `i` itself, and the
/// relation is symmetric. Pairs where one ball contains the other (see [`balls_nested`]) stay in
/// the graph; they have no intersection circle and carry zero operator weight (thesis §4), which
/// is for the operators to decide.
///
/// # Building
///
/// Each row is one query of the [`BallIndex`] at `c_i` with reach `s·r_j + s·r_i`, filtered by
/// the exact test, but only for the candidates `j > i`: each pair is tested once, by its lower
/// index, and row `i` first holds only its upper half `{j > i}`, sorted. The lower halves are
/// the transpose of the upper ones, and row `i` is its lower half followed by its upper half:
/// every id in the first is below `i` and every id in the second above, so the row is sorted.
/// Symmetry does not rely on luck: one floating-point answer serves both directions.
///
/// The upper halves are computed in parallel in fixed chunks of rows, and the transpose in
/// parallel over blocks of target rows; a row's contents are determined by the adjacency
/// alone, so the graph is identical for any thread count.
///
/// Cost: one ball-index query per support, `O(n log n + E log d)` overall for `E` directed
/// entries and maximum degree `d`; memory `O(n + E)` (`4·E` bytes for the neighbour array plus
/// the same again transiently for the upper halves, as `(i, j)` pairs).
#[derive(Clone, Debug, PartialEq)]
pub struct SphereIntersectionGraph {
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    shrink: f64,
}

/// The adjacency test `‖c_i − c_j‖ < s·(r_i + r_j)`, evaluated squared. Each pair is tested
/// once, with the lower index as `(c_i, r_i)`.
#[inline]
fn adjacent(ci: DVec3, ri: f64, cj: DVec3, rj: f64, shrink: f64) -> bool {
    let reach = shrink * (ri + rj);
    (ci - cj).length_squared() < reach * reach
}

/// Rows per target block, as a shift: a power of two (a shift finds an id's block), at least
/// a chunk, and at most [`MAX_TARGET_BLOCKS`] blocks.
fn target_block_shift(n: usize) -> u32 {
    n.div_ceil(MAX_TARGET_BLOCKS)
        .max(ROWS_PER_CHUNK)
        .next_power_of_two()
        .trailing_zeros()
}

/// The upper halves `{j ~ i : j > i}` of the rows of one chunk, as pairs `(i, j)` grouped by
/// the target block of `j` (rows `b << block_shift..(b + 1) << block_shift` form block `b`).
struct UpperHalves {
    /// Size of the upper half of each row of the chunk.
    degrees: Vec<u32>,
    /// `(block, end)` per target block reached, ascending: the group of `block` is
    /// `pairs[previous end..end]`.
    groups: Vec<(u32, u32)>,
    /// The pairs, by group, and within a group ascending in `(i, j)`.
    pairs: Vec<(u32, u32)>,
}

impl UpperHalves {
    /// Groups the upper halves of the rows from `first_row`: row by row, each sorted, in
    /// `rows`, `degrees` long each. `counts` has a slot per target block and is zero on entry
    /// and on return.
    fn group(
        first_row: usize,
        degrees: Vec<u32>,
        rows: &[u32],
        block_shift: u32,
        counts: &mut [u32],
    ) -> UpperHalves {
        let mut blocks = Vec::new();
        for &j in rows {
            let count = &mut counts[(j >> block_shift) as usize];
            if *count == 0 {
                blocks.push(j >> block_shift);
            }
            *count += 1;
        }
        blocks.sort_unstable();
        let mut groups = Vec::with_capacity(blocks.len());
        let mut end = 0;
        for &block in &blocks {
            // From here on the count is the group's cursor.
            let start = end;
            end += counts[block as usize];
            counts[block as usize] = start;
            groups.push((block, end));
        }
        // Rows in ascending order, each ascending: every group comes out ascending in (i, j).
        let mut pairs = vec![(0, 0); rows.len()];
        let mut rest = rows;
        for (i, &degree) in (first_row as u32..).zip(&degrees) {
            let (row, tail) = rest.split_at(degree as usize);
            for &j in row {
                let cursor = &mut counts[(j >> block_shift) as usize];
                pairs[*cursor as usize] = (i, j);
                *cursor += 1;
            }
            rest = tail;
        }
        for &block in &blocks {
            counts[block as usize] = 0;
        }
        UpperHalves {
            degrees,
            groups,
            pairs,
        }
    }

    /// The groups, as `(block, pairs)`.
    fn groups(&self) -> impl Iterator<Item = (usize, &[(u32, u32)])> {
        let starts = std::iter::once(0).chain(self.groups.iter().map(|&(_, end)| end));
        self.groups
            .iter()
            .zip(starts)
            .map(|(&(block, end), start)| {
                (block as usize, &self.pairs[start as usize..end as usize])
            })
    }
}

/// The full rows, as `(offsets, neighbours)`, of the `n` nodes whose upper halves are
/// `uppers` (grouped with `block_shift`): row `i` is its lower half, the transpose of the
/// upper ones, then its upper half. The total number of entries must fit in `u32`.
///
/// Each target block fills its own span of the neighbour array, in parallel: a row's contents
/// do not depend on how the work is split.
fn transpose(uppers: &[UpperHalves], n: usize, block_shift: u32) -> (Vec<u32>, Vec<u32>) {
    let block_rows = 1usize << block_shift;
    let block_count = n.div_ceil(block_rows);
    // The groups pointing into each target block, by ascending chunk, so that a block meets
    // its pairs in ascending order of `i`.
    let mut incoming: Vec<Vec<&[(u32, u32)]>> = vec![Vec::new(); block_count];
    for upper in uppers {
        for (block, pairs) in upper.groups() {
            incoming[block].push(pairs);
        }
    }

    let mut lower_degrees = vec![0u32; n];
    lower_degrees
        .par_chunks_mut(block_rows)
        .zip(&incoming)
        .enumerate()
        .for_each(|(block, (degrees, groups))| {
            let first = block << block_shift;
            for group in groups {
                for &(_, j) in *group {
                    degrees[j as usize - first] += 1;
                }
            }
        });
    let mut offsets = Vec::with_capacity(n + 1);
    offsets.push(0u32);
    let mut running = 0u32;
    let upper_degrees = uppers.iter().flat_map(|upper| &upper.degrees);
    for (lower, upper) in lower_degrees.iter().zip(upper_degrees) {
        running += lower + upper;
        offsets.push(running);
    }

    let mut neighbours = vec![0u32; running as usize];
    let mut spans = Vec::with_capacity(block_count);
    let mut rest = &mut neighbours[..];
    for block in 0..block_count {
        let rows = block << block_shift..((block + 1) << block_shift).min(n);
        let (span, tail) = rest.split_at_mut((offsets[rows.end] - offsets[rows.start]) as usize);
        spans.push((rows, span));
        rest = tail;
    }
    spans
        .into_par_iter()
        .zip(&incoming)
        .for_each(|((rows, span), groups)| {
            let base = offsets[rows.start];
            let mut next: Vec<u32> = offsets[rows.clone()].iter().map(|&o| o - base).collect();
            // The lower halves: pairs by ascending i, so each half comes out sorted.
            for group in groups {
                for &(i, j) in *group {
                    let cursor = &mut next[j as usize - rows.start];
                    span[*cursor as usize] = i;
                    *cursor += 1;
                }
            }
            // The upper halves, from the block's own chunks: by group (ascending blocks of j),
            // then ascending j within a row, so each half comes out sorted.
            let chunks = rows.start / ROWS_PER_CHUNK..rows.end.div_ceil(ROWS_PER_CHUNK);
            for upper in &uppers[chunks] {
                for &(i, j) in &upper.pairs {
                    let cursor = &mut next[i as usize - rows.start];
                    span[*cursor as usize] = j;
                    *cursor += 1;
                }
            }
        });
    (offsets, neighbours)
}

/// True when one of the balls `(c_i, r_i)`, `(c_j, r_j)` contains the other (closed balls):
/// `‖c_i − c_j‖ ≤ |r_i − r_j|`. Such pairs have no intersection circle, so the discrete
/// operators of thesis §4 give them zero weight. Symmetric in its two balls.
#[inline]
pub fn balls_nested(c_i: DVec3, r_i: f64, c_j: DVec3, r_j: f64) -> bool {
    c_i.distance(c_j) <= (r_i - r_j).abs()
}

impl SphereIntersectionGraph {
    /// Builds the graph of the balls `(centres[i], radii[i])` with shrink factor `shrink`
    /// (thesis default 0.7; 1 gives the true intersection graph).
    ///
    /// Centres must be finite, radii finite and non-negative, `shrink` finite and positive.
    pub fn build(
        centres: &[DVec3],
        radii: &[f64],
        shrink: f64,
    ) -> Result<SphereIntersectionGraph, SigError> {
        SphereIntersectionGraph::build_with_entry_limit(centres, radii, shrink, u64::from(u32::MAX))
    }

    /// [`SphereIntersectionGraph::build`] failing with [`SigError::TooManyEdges`] beyond
    /// `max_entries` directed entries (the u32 limit, or less in tests).
    fn build_with_entry_limit(
        centres: &[DVec3],
        radii: &[f64],
        shrink: f64,
        max_entries: u64,
    ) -> Result<SphereIntersectionGraph, SigError> {
        if centres.len() != radii.len() {
            return Err(SigError::LengthMismatch {
                centres: centres.len(),
                radii: radii.len(),
            });
        }
        if !(shrink > 0.0 && shrink.is_finite()) {
            return Err(SigError::InvalidShrink { shrink });
        }
        let n = centres.len();
        if u32::try_from(n).is_err() {
            return Err(SigError::TooManySupports { len: n });
        }
        if let Some(index) = centres.iter().position(|c| !c.is_finite()) {
            return Err(SigError::InvalidCentre {
                index,
                centre: centres[index],
            });
        }
        if let Some(index) = radii.iter().position(|r| !(r.is_finite() && *r >= 0.0)) {
            return Err(SigError::InvalidRadius {
                index,
                radius: radii[index],
            });
        }

        let index = BallIndex::try_new(centres, radii).map_err(|e| match e {
            BallIndexError::LengthMismatch { centres, radii } => {
                SigError::LengthMismatch { centres, radii }
            }
            BallIndexError::TooManyBalls { len } => SigError::TooManySupports { len },
        })?;

        let block_shift = target_block_shift(n);
        let block_count = n.div_ceil(1 << block_shift);

        // Running count of directed entries over all chunks, so that a graph too large for u32
        // offsets stops early instead of exhausting memory first. Each pair found is two
        // directed entries.
        let entries = AtomicU64::new(0);
        let overflow = AtomicBool::new(false);
        let uppers: Vec<UpperHalves> = (0..n.div_ceil(ROWS_PER_CHUNK))
            .into_par_iter()
            .map_init(
                || (Vec::new(), vec![0u32; block_count]),
                |(scratch, counts): &mut (Vec<u32>, Vec<u32>), chunk| {
                    let rows = chunk * ROWS_PER_CHUNK..((chunk + 1) * ROWS_PER_CHUNK).min(n);
                    let mut degrees = Vec::with_capacity(rows.len());
                    let mut len = 0usize;
                    for i in rows.clone() {
                        if overflow.load(Ordering::Relaxed) {
                            break;
                        }
                        let (ci, ri) = (centres[i], radii[i]);
                        let i = i as u32;
                        let start = len;
                        index.for_each_candidate_run(ci, shrink, shrink * ri, |balls| {
                            if scratch.len() < len + balls.len() {
                                scratch.resize(2 * (len + balls.len()) + 1024, 0);
                            }
                            // Write every upper candidate and keep it on a hit: the test passes
                            // for about one upper candidate in seven, and on the 362K-point
                            // bunny a branch on it saved instructions but cost 7% in time. The
                            // lower candidates are skipped by a branch: that measured cheaper,
                            // in instructions and in time, than testing and masking them.
                            let out = &mut scratch[len..len + balls.len()];
                            let mut hits = 0;
                            // Copies stay in registers; read through the closure's captures,
                            // they were loaded again for every candidate.
                            let (i, ci, ri, shrink) = (i, ci, ri, shrink);
                            for ball in balls {
                                let j = ball.id;
                                if j <= i {
                                    continue;
                                }
                                out[hits] = j;
                                hits +=
                                    usize::from(adjacent(ci, ri, ball.centre, ball.radius, shrink));
                            }
                            len += hits;
                        });
                        scratch[start..len].sort_unstable();
                        let degree = (len - start) as u64;
                        degrees.push(degree as u32);
                        let so_far = entries.fetch_add(2 * degree, Ordering::Relaxed) + 2 * degree;
                        if so_far > max_entries {
                            overflow.store(true, Ordering::Relaxed);
                        }
                    }
                    UpperHalves::group(rows.start, degrees, &scratch[..len], block_shift, counts)
                },
            )
            .collect();
        // The flag is raised only once the running total has passed the limit, and the total
        // only grows, so the outcome does not depend on scheduling.
        if overflow.load(Ordering::Relaxed) {
            return Err(SigError::TooManyEdges);
        }

        let (offsets, neighbours) = transpose(&uppers, n, block_shift);
        Ok(SphereIntersectionGraph {
            offsets,
            neighbours,
            shrink,
        })
    }

    /// Number of nodes (supports).
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// True when the graph has no node.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of undirected edges.
    pub fn num_edges(&self) -> usize {
        self.neighbours.len() / 2
    }

    /// The shrink factor the graph was built with.
    pub fn shrink(&self) -> f64 {
        self.shrink
    }

    /// Neighbours of node `i`, ascending. Panics when `i ≥ len()`, like slice indexing.
    pub fn neighbours(&self, i: usize) -> &[u32] {
        &self.neighbours[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    /// Number of neighbours of node `i`. Panics when `i ≥ len()`.
    pub fn degree(&self, i: usize) -> usize {
        (self.offsets[i + 1] - self.offsets[i]) as usize
    }

    /// Mean number of neighbours per node (0 for an empty graph).
    pub fn mean_degree(&self) -> f64 {
        if self.is_empty() {
            0.0
        } else {
            self.neighbours.len() as f64 / self.len() as f64
        }
    }

    /// Row offsets: row `i` is `neighbour_array()[offsets()[i]..offsets()[i + 1]]`; length
    /// `len() + 1`, starting at 0.
    pub fn offsets(&self) -> &[u32] {
        &self.offsets
    }

    /// All rows concatenated (each directed entry once, so every edge appears twice).
    pub fn neighbour_array(&self) -> &[u32] {
        &self.neighbours
    }

    /// Every undirected edge once, as `(i, j)` with `i < j`, in ascending order of `i` then `j`.
    pub fn edges(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        (0..self.len()).flat_map(move |i| {
            let row = self.neighbours(i);
            let i = i as u32;
            let above = row.partition_point(|&j| j < i);
            row[above..].iter().map(move |&j| (i, j))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;
    use proptest::prelude::*;

    /// `(offsets, neighbours)` of sorted rows.
    fn csr(rows: &[Vec<u32>]) -> (Vec<u32>, Vec<u32>) {
        let mut offsets = vec![0u32];
        for row in rows {
            offsets.push(offsets[offsets.len() - 1] + row.len() as u32);
        }
        (offsets, rows.concat())
    }

    /// Every ordered pair through the literal test, the lower index first.
    fn brute_force(centres: &[DVec3], radii: &[f64], shrink: f64) -> (Vec<u32>, Vec<u32>) {
        let rows: Vec<Vec<u32>> = (0..centres.len())
            .map(|i| {
                (0..centres.len())
                    .filter(|&j| {
                        let (a, b) = (i.min(j), i.max(j));
                        let reach = shrink * (radii[a] + radii[b]);
                        j != i && (centres[a] - centres[b]).length_squared() < reach * reach
                    })
                    .map(|j| j as u32)
                    .collect()
            })
            .collect();
        csr(&rows)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// Supports on a coarse lattice, up to three chunks of them: coincident centres, zero
        /// radii and balls tangent exactly at the reach (`0.5·(0.5 + 0.5) = 0.5`) are common.
        #[test]
        fn degenerate_balls_equal_brute_force(
            sites in prop::collection::vec((0u8..6, 0u8..6, 0u8..6, 0u8..5), 0..1300),
            shrink in prop_oneof![Just(0.5), Just(1.0), 0.3f64..1.2],
        ) {
            let centres: Vec<DVec3> = sites
                .iter()
                .map(|&(x, y, z, _)| DVec3::new(x.into(), y.into(), z.into()) * 0.5)
                .collect();
            let radii: Vec<f64> = sites.iter().map(|&(.., r)| f64::from(r) * 0.25).collect();
            let graph = SphereIntersectionGraph::build(&centres, &radii, shrink).unwrap();
            let (offsets, neighbours) = brute_force(&centres, &radii, shrink);
            prop_assert_eq!(graph.offsets(), &offsets[..]);
            prop_assert_eq!(graph.neighbour_array(), &neighbours[..]);
        }
    }

    #[test]
    fn transpose_equals_a_plain_one_for_any_block_size() {
        // Six chunks, the last one partial; upper halves near the diagonal, far from it, and
        // empty.
        let n = 3000;
        let mut rng = SplitMix64::new(11);
        let upper: Vec<Vec<u32>> = (0..n)
            .map(|i| {
                let mut row: Vec<u32> = match i % 7 {
                    0 => Vec::new(),
                    1 => (0..6).map(|_| rng.below(n as u64) as u32).collect(),
                    _ => (0..8)
                        .map(|_| (i + 1 + rng.below(40) as usize) as u32)
                        .collect(),
                };
                row.retain(|&j| j as usize > i && (j as usize) < n);
                row.sort_unstable();
                row.dedup();
                row
            })
            .collect();
        let mut rows = vec![Vec::new(); n];
        for (i, row) in upper.iter().enumerate() {
            for &j in row {
                rows[i].push(j);
                rows[j as usize].push(i as u32);
            }
        }
        rows.iter_mut().for_each(|row| row.sort_unstable());
        let want = csr(&rows);

        for block_shift in [9, 10, 12] {
            let mut counts = vec![0; n.div_ceil(1 << block_shift)];
            let uppers: Vec<UpperHalves> = upper
                .chunks(ROWS_PER_CHUNK)
                .enumerate()
                .map(|(chunk, halves)| {
                    let degrees = halves.iter().map(|h| h.len() as u32).collect();
                    let first = chunk * ROWS_PER_CHUNK;
                    UpperHalves::group(first, degrees, &halves.concat(), block_shift, &mut counts)
                })
                .collect();
            assert!(counts.iter().all(|&c| c == 0));
            assert_eq!(
                transpose(&uppers, n, block_shift),
                want,
                "shift {block_shift}"
            );
        }
    }

    #[test]
    fn target_blocks_are_whole_chunks_and_few() {
        for n in [
            0,
            1,
            512,
            513,
            256 * 512,
            256 * 512 + 1,
            1 << 27,
            u32::MAX as usize,
        ] {
            let shift = target_block_shift(n);
            assert!(1 << shift >= ROWS_PER_CHUNK, "n = {n}");
            assert!(n.div_ceil(1 << shift) <= MAX_TARGET_BLOCKS, "n = {n}");
        }
        assert_eq!(target_block_shift(256 * 512), 9);
        assert_eq!(target_block_shift(256 * 512 + 1), 10);
    }

    #[test]
    fn too_many_edges_is_an_error_not_an_allocation() {
        // 3000 identical balls: a complete graph of 3000·2999 directed entries.
        let centres = vec![DVec3::ZERO; 3000];
        let radii = vec![1.0; 3000];
        let entries = 3000 * 2999;
        let build =
            |limit| SphereIntersectionGraph::build_with_entry_limit(&centres, &radii, 0.7, limit);
        assert_eq!(build(entries - 1), Err(SigError::TooManyEdges));
        let graph = build(entries).unwrap();
        assert_eq!(graph.neighbour_array().len() as u64, entries);
    }
}
