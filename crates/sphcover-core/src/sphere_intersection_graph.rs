//! The sphere intersection graph (SIG) of a cover (thesis Appendix B, §5.2.3).
//!
//! The method is described on [`SphereIntersectionGraph`].

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;
use thiserror::Error;

use crate::ball_index::{BallIndex, BallIndexError};
use crate::concat::concat_in_parallel;

/// Rows computed by one parallel task. Fixed, so the work split never depends on the pool.
const ROWS_PER_CHUNK: usize = 512;

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
/// the exact test, then sorted. Rows are computed in parallel in fixed chunks and concatenated
/// in order, so the graph is identical for any thread count. Symmetry does not rely on luck:
/// both directions evaluate the test through the same expression on the same operands (the
/// lower index first), so `i ~ j` and `j ~ i` get the same floating-point answer.
///
/// Cost: one ball-index query per support, `O(n log n + E log d)` overall for `E` directed
/// entries and maximum degree `d`; memory `O(n + E)` (`4·E` bytes for the neighbour array plus
/// the same again transiently while the chunks are joined).
#[derive(Clone, Debug, PartialEq)]
pub struct SphereIntersectionGraph {
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    shrink: f64,
}

/// The adjacency test `‖c_i − c_j‖ < s·(r_i + r_j)`, evaluated squared and always with the
/// lower index first, so that it gives the same answer in both directions.
#[inline]
fn adjacent(i: u32, ci: DVec3, ri: f64, j: u32, cj: DVec3, rj: f64, shrink: f64) -> bool {
    let (ca, ra, cb, rb) = if i < j {
        (ci, ri, cj, rj)
    } else {
        (cj, rj, ci, ri)
    };
    let reach = shrink * (ra + rb);
    (ca - cb).length_squared() < reach * reach
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

        // Running count of directed entries over all chunks, so that a graph too large for u32
        // offsets stops early instead of exhausting memory first.
        let entries = AtomicU64::new(0);
        let overflow = AtomicBool::new(false);
        let chunks: Vec<(Vec<u32>, Vec<u32>)> = (0..n.div_ceil(ROWS_PER_CHUNK))
            .into_par_iter()
            .map_init(Vec::new, |scratch: &mut Vec<u32>, chunk| {
                let rows = chunk * ROWS_PER_CHUNK..((chunk + 1) * ROWS_PER_CHUNK).min(n);
                let mut degrees = Vec::with_capacity(rows.len());
                let mut len = 0usize;
                for i in rows {
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
                        // Write every candidate and keep it on a hit: the test passes for
                        // about a third of the candidates, a branch no predictor can guess.
                        let out = &mut scratch[len..len + balls.len()];
                        let mut hits = 0;
                        for ball in balls {
                            let j = ball.id;
                            out[hits] = j;
                            hits += usize::from(
                                j != i && adjacent(i, ci, ri, j, ball.centre, ball.radius, shrink),
                            );
                        }
                        len += hits;
                    });
                    scratch[start..len].sort_unstable();
                    let degree = len - start;
                    degrees.push(degree as u32);
                    let so_far =
                        entries.fetch_add(degree as u64, Ordering::Relaxed) + degree as u64;
                    if so_far > max_entries {
                        overflow.store(true, Ordering::Relaxed);
                    }
                }
                (degrees, scratch[..len].to_vec())
            })
            .collect();
        // The flag is raised only once the running total has passed the limit, and the total
        // only grows, so the outcome does not depend on scheduling.
        if overflow.load(Ordering::Relaxed) {
            return Err(SigError::TooManyEdges);
        }

        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let mut running = 0u32;
        for (degrees, _) in &chunks {
            for d in degrees {
                running += d;
                offsets.push(running);
            }
        }
        let rows: Vec<&[u32]> = chunks.iter().map(|(_, rows)| &rows[..]).collect();
        let neighbours = concat_in_parallel(&rows);

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
