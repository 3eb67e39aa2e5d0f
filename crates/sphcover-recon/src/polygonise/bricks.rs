//! Where the values of `f` at grid vertices live, and how they get computed.
//!
//! The grid is stored sparsely by bricks of 4×4×4 vertices: the search writes to them and
//! every later phase reads them through a [`BrickReader`]. Evaluating `f` is most of the
//! search's time and has its own batching (the next run of corners is collected while the
//! previous one is evaluated in parallel), kept here apart from the choice of which cells to
//! visit.

use std::time::Instant;

use glam::DVec3;

use super::cell::corner_offset;
use super::grid::{Index3, KeyMap, pack};
use super::search::Search;

/// Side of a brick in grid vertices (and cells).
const BRICK_SHIFT: u32 = 2;
const BRICK_MASK: i64 = (1 << BRICK_SHIFT) - 1;
const BRICK_LEN: usize = 1 << (3 * BRICK_SHIFT);

/// The state of a 4×4×4 block of grid vertices, and of the cells whose lowest corner they
/// are. Storing the grid sparsely by bricks keeps one hash lookup per brick rather than per
/// vertex, and neighbouring vertices mostly share a brick.
#[derive(Clone, Debug)]
pub(super) struct Brick {
    /// `f` at each vertex (NaN where undefined), once its bit in `evaluated` is set.
    values: [f64; BRICK_LEN],
    evaluated: u64,
    /// Cells queued or examined by the search.
    pub(super) visited: u64,
    /// Slot in [`Search::cells`] of each active cell, or `u32::MAX`.
    pub(super) active: [u32; BRICK_LEN],
}

impl Brick {
    pub(super) fn set_value(&mut self, l: usize, v: f64) {
        self.values[l] = v;
    }

    const EMPTY: Brick = Brick {
        values: [f64::NAN; BRICK_LEN],
        evaluated: 0,
        visited: 0,
        active: [u32::MAX; BRICK_LEN],
    };
}

/// The brick key of a grid index and its position in the brick.
pub(super) fn brick_of(v: Index3) -> (u64, usize) {
    let key = pack(v.map(|c| c >> BRICK_SHIFT));
    let local = (v[0] & BRICK_MASK)
        | ((v[1] & BRICK_MASK) << BRICK_SHIFT)
        | ((v[2] & BRICK_MASK) << (2 * BRICK_SHIFT));
    (key, local as usize)
}

/// The parities of the brick coordinates of grid index `v`. The bricks holding one cell's
/// corners, or the cells around one of its edges, all differ in class, so a cache with one
/// entry per class holds all of them at once (one remembering only the last brick went back
/// to the hash map at every step across a brick boundary).
fn brick_class(v: Index3) -> usize {
    let bit = |a: usize| ((v[a] >> BRICK_SHIFT) & 1) as usize;
    bit(0) | bit(1) << 1 | bit(2) << 2
}

/// The last brick key met in each [`brick_class`] and what it maps to. No brick key is
/// `u64::MAX` (the keys of in-range indices use 63 bits).
pub(super) type BrickCache<T> = [(u64, T); 8];

/// Read access to bricks that remembers the last brick found in each class, since queries
/// come in neighbourhoods.
pub(super) struct BrickReader<'s> {
    index: &'s KeyMap<u32>,
    bricks: &'s [Brick],
    cache: BrickCache<Option<&'s Brick>>,
}

impl<'s> BrickReader<'s> {
    pub(super) fn get(&mut self, v: Index3) -> Option<(&'s Brick, usize)> {
        let (key, local) = brick_of(v);
        let entry = &mut self.cache[brick_class(v)];
        if entry.0 != key {
            *entry = (key, self.index.get(&key).map(|&i| &self.bricks[i as usize]));
        }
        entry.1.map(|b| (b, local))
    }

    pub(super) fn value(&mut self, v: Index3) -> Option<f64> {
        self.get(v)
            .and_then(|(b, l)| (b.evaluated >> l & 1 == 1).then_some(b.values[l]))
    }

    pub(super) fn active_slot(&mut self, c: Index3) -> Option<u32> {
        self.get(c)
            .map(|(b, l)| b.active[l])
            .filter(|&s| s != u32::MAX)
    }
}

impl<'e, 'c> Search<'e, 'c> {
    pub(super) fn reader(&self) -> BrickReader<'_> {
        BrickReader {
            index: &self.brick_index,
            bricks: &self.bricks,
            cache: [(u64::MAX, None); 8],
        }
    }

    /// The brick holding `v` (created if needed) and `v`'s position in it; `cache` holds the
    /// slots of the last brick keys met.
    pub(super) fn brick_mut(
        &mut self,
        v: Index3,
        cache: &mut BrickCache<u32>,
    ) -> (&mut Brick, usize) {
        let (key, local) = brick_of(v);
        let entry = &mut cache[brick_class(v)];
        if entry.0 != key {
            let next = self.bricks.len() as u32;
            let slot = *self.brick_index.entry(key).or_insert(next);
            if slot == next {
                self.bricks.push(Brick::EMPTY);
            }
            *entry = (key, slot);
        }
        (&mut self.bricks[entry.1 as usize], local)
    }

    /// Evaluates `f` at the corners of `cells` not evaluated before. The corners of each
    /// run of [`CORNER_RUN`] cells are collected (a sequential walk over the bricks) while
    /// those of the previous run are evaluated in parallel: otherwise the walk over a wave's
    /// corners (1.2M in the first wave of the 362K-point bunny) holds one thread alone.
    pub(super) fn evaluate_corners(&mut self, cells: &[Index3]) {
        let mut cache = [(u64::MAX, 0); 8];
        let eval = self.eval;
        let mut runs = cells.chunks(CORNER_RUN);
        let mut pending = runs.next().map(|run| self.new_corners(run, &mut cache));
        while let Some((targets, points)) = pending.take() {
            let next_run = runs.next();
            let ((values, took), next) = rayon::join(
                || {
                    let start = Instant::now();
                    (eval.values(&points), start.elapsed())
                },
                || next_run.map(|run| self.new_corners(run, &mut cache)),
            );
            self.evaluations += points.len();
            self.evaluation_time += took;
            for ((brick, l), v) in targets.into_iter().zip(values) {
                self.bricks[brick as usize].values[l] = v.unwrap_or(f64::NAN);
            }
            pending = next;
        }
    }

    /// The corners of `cells` not evaluated before, as (brick slot, position in the brick)
    /// and grid position, marked evaluated.
    fn new_corners(
        &mut self,
        cells: &[Index3],
        cache: &mut BrickCache<u32>,
    ) -> (Vec<(u32, usize)>, Vec<DVec3>) {
        // About two new corners per cell (a surface's cells share the others): room for
        // that spares the lists most of their copies as they grow.
        let mut targets = Vec::with_capacity(2 * cells.len());
        let mut points = Vec::with_capacity(2 * cells.len());
        for &c in cells {
            for k in 0..8 {
                let o = corner_offset(k);
                let v = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
                let (brick, l) = self.brick_mut(v, cache);
                if brick.evaluated >> l & 1 == 0 {
                    brick.evaluated |= 1 << l;
                    targets.push((cache[brick_class(v)].1, l));
                    points.push(self.grid.position(v));
                }
            }
        }
        (targets, points)
    }
}

/// Cells whose new corners are collected while the previous run's are evaluated (see
/// [`Search::evaluate_corners`]).
const CORNER_RUN: usize = 16_384;
