//! The breadth-first search over active cells, from the seeds ("Continuation from seeds" in
//! the notes of the `polygonise` module), and the Newton steps that pull seeds lying off
//! the surface onto it.
//!
//! The search alone decides which cells get meshed, so the cost follows the area of the
//! surface and a sheet far from every seed is never visited; the later phases only read
//! what it found.

use std::time::Duration;

use glam::DVec3;
use rayon::prelude::*;

use super::bricks::{Brick, BrickCache, BrickReader};
use super::cell::{ActiveCell, NO_SHEET, cell_sheets, cells_around_edge, corner_offset, inside};
use super::grid::{Grid, Index3, KeyMap, pack};
use super::{PiecewiseFunction, PolygoniseError};

/// Newton steps that pull a seed onto `f = 0`.
const SEED_NEWTON_STEPS: usize = 2;

/// Pulls each seed onto `f = 0` with Newton steps; `(projected point, |f| / ‖∇f‖ there)`, or
/// `None` where `f` is undefined or flat.
pub(super) fn project_seeds(
    eval: &PiecewiseFunction<'_>,
    seeds: &[DVec3],
) -> Vec<Option<(DVec3, f64)>> {
    let mut points: Vec<Option<(DVec3, f64)>> =
        seeds.iter().map(|&p| Some((p, f64::INFINITY))).collect();
    // The last round only measures the distance at the final point.
    for round in 0..=SEED_NEWTON_STEPS {
        let live: Vec<DVec3> = points.iter().flatten().map(|&(p, _)| p).collect();
        let mut results = eval.values_gradients(&live).into_iter();
        for slot in points.iter_mut().filter(|s| s.is_some()) {
            let Some((x, _)) = *slot else { continue };
            *slot = results.next().flatten().and_then(|vg| {
                let g2 = vg.gradient.length_squared();
                if !(g2 > 0.0 && g2.is_finite()) {
                    return None;
                }
                let distance = vg.value.abs() / g2.sqrt();
                let next = if round < SEED_NEWTON_STEPS {
                    x - vg.gradient * (vg.value / g2)
                } else {
                    x
                };
                next.is_finite().then_some((next, distance))
            });
        }
    }
    points
}

/// The breadth-first search over active cells.
pub(super) struct Search<'e, 'c> {
    pub(super) eval: &'e PiecewiseFunction<'c>,
    pub(super) grid: &'e Grid,
    max_cells: usize,
    /// Slot in `bricks` of each brick key.
    pub(super) brick_index: KeyMap<u32>,
    pub(super) bricks: Vec<Brick>,
    /// Active cells with their keys, in the order found.
    pub(super) cells: Vec<(u64, ActiveCell)>,
    pub(super) visited_cells: usize,
    pub(super) evaluations: usize,
    pub(super) evaluation_time: Duration,
}

impl<'e, 'c> Search<'e, 'c> {
    pub(super) fn new(eval: &'e PiecewiseFunction<'c>, grid: &'e Grid, max_cells: usize) -> Self {
        Search {
            eval,
            grid,
            max_cells,
            brick_index: KeyMap::default(),
            bricks: Vec::new(),
            cells: Vec::new(),
            visited_cells: 0,
            evaluations: 0,
            evaluation_time: Duration::ZERO,
        }
    }

    /// Marks cell `c` visited; true when it was not before.
    fn visit(&mut self, c: Index3, cache: &mut BrickCache<u32>) -> bool {
        let (brick, l) = self.brick_mut(c, cache);
        let fresh = brick.visited >> l & 1 == 0;
        brick.visited |= 1 << l;
        self.visited_cells += usize::from(fresh);
        fresh
    }

    /// Whether the search has queued or examined cell `c`.
    pub(super) fn visited(&self, c: Index3) -> bool {
        self.grid.in_range(c)
            && self
                .reader()
                .get(c)
                .is_some_and(|(b, l)| b.visited >> l & 1 == 1)
    }

    /// Whether the cell or one of its 26 neighbours is active.
    pub(super) fn near_active(&self, reader: &mut BrickReader<'_>, c: Index3) -> bool {
        let mut active = |n: Index3| self.grid.in_range(n) && reader.active_slot(n).is_some();
        // A seed's own cell is nearly always active: ask it first.
        active(c) || self.grid.block_around(c).any(active)
    }

    /// A cell needs its far corner in range too.
    fn cell_in_range(&self, c: Index3) -> bool {
        self.grid.in_range(c) && self.grid.in_range(c.map(|x| x + 1))
    }

    /// Visits the cells `starts` not yet visited and everything reachable from them.
    pub(super) fn run(&mut self, starts: Vec<Index3>) -> Result<(), PolygoniseError> {
        let mut cache = [(u64::MAX, 0); 8];
        let mut frontier: Vec<Index3> = Vec::new();
        for c in starts {
            if self.cell_in_range(c) && self.visit(c, &mut cache) {
                frontier.push(c);
            }
        }
        while !frontier.is_empty() {
            if self.visited_cells > self.max_cells {
                return Err(PolygoniseError::TooManyCells {
                    max_cells: self.max_cells,
                    step: self.grid.step,
                });
            }
            self.evaluate_corners(&frontier);
            // Classified in parallel, each run with the neighbours its active cells reach
            // that were not visited before this wave: the sequential pass below would
            // reject the others, so it only walks these, in the same order.
            let classified: Vec<(Vec<Option<ActiveCell>>, Vec<Index3>)> = frontier
                .par_chunks(256)
                .map(|chunk| {
                    let mut reader = self.reader();
                    let cells: Vec<Option<ActiveCell>> =
                        chunk.iter().map(|&c| classify(&mut reader, c)).collect();
                    let mut reached = Vec::new();
                    for (&c, cell) in chunk.iter().zip(&cells) {
                        let Some(cell) = cell else { continue };
                        for e in (0..12).filter(|&e| cell.sheet[e] != NO_SHEET) {
                            reached.extend(cells_around_edge(c, e).into_iter().filter(|&n| {
                                n != c
                                    && self.cell_in_range(n)
                                    && reader.get(n).is_none_or(|(b, l)| b.visited >> l & 1 == 0)
                            }));
                        }
                    }
                    (cells, reached)
                })
                .collect();
            let mut next = Vec::new();
            for (chunk, (cells, reached)) in frontier.chunks(256).zip(classified) {
                for n in reached {
                    if self.visit(n, &mut cache) {
                        next.push(n);
                    }
                }
                for (&c, cell) in chunk.iter().zip(cells) {
                    let Some(cell) = cell else { continue };
                    let slot = self.cells.len() as u32;
                    let (brick, l) = self.brick_mut(c, &mut cache);
                    brick.active[l] = slot;
                    self.cells.push((pack(c), cell));
                }
            }
            frontier = next;
        }
        Ok(())
    }
}

/// The active-cell data of cell `c`, or `None` when it is not active or `f` is undefined at
/// a corner.
pub(super) fn classify(reader: &mut BrickReader<'_>, c: Index3) -> Option<ActiveCell> {
    let mut values = [0.0; 8];
    let mut inside_count = 0;
    for (k, value) in values.iter_mut().enumerate() {
        let o = corner_offset(k);
        let v = reader.value([c[0] + o[0], c[1] + o[1], c[2] + o[2]])?;
        if v.is_nan() {
            return None;
        }
        inside_count += usize::from(inside(v));
        *value = v;
    }
    if inside_count == 0 || inside_count == 8 {
        return None;
    }
    let (sheet, sheets) = cell_sheets(&values);
    Some(ActiveCell {
        inside: (0..8).fold(0, |m, k| m | (u8::from(inside(values[k])) << k)),
        sheet,
        sheets,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::polygonise::tests::cover_of;
    use sphcover_core::PuEvaluator;
    use sphcover_evaluation::{sphere, torus};

    /// The search from seeds on every component finds exactly the active cells (with the
    /// same sheets) that classifying every cell of the grid finds.
    #[test]
    fn search_finds_what_a_scan_of_the_whole_grid_finds() {
        let mut cloud = sphere(DVec3::new(-0.2, 0.0, 0.0), 0.15, 1200);
        let other = torus(0.15, 0.06, 2000);
        let shifted: Vec<DVec3> = other
            .positions
            .iter()
            .map(|&p| p + DVec3::X * 0.2)
            .collect();
        cloud.positions.extend(&shifted);
        if let (Some(a), Some(b)) = (cloud.normals.as_mut(), other.normals.as_ref()) {
            a.extend(b);
        }
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let field = PiecewiseFunction::single(super::super::FieldPiece {
            eval: &eval,
            blend: None,
        })
        .unwrap();
        let grid = Grid::around(&field, 0.025).unwrap();
        let mut search = Search::new(&field, &grid, usize::MAX);
        // One seed per component is enough.
        let seeds = [cloud.positions[0], shifted[0]];
        search
            .run(
                seeds
                    .iter()
                    .flat_map(|&p| grid.block_around(grid.cell_of(p)))
                    .collect(),
            )
            .unwrap();
        let mut found: Vec<(u64, [u8; 12])> =
            search.cells.iter().map(|(k, c)| (*k, c.sheet)).collect();
        found.sort_unstable();

        let [nx, ny, nz] = grid.dims;
        let index = |v: Index3| ((v[2] * ny + v[1]) * nx + v[0]) as usize;
        let vertices: Vec<DVec3> = (0..nx * ny * nz)
            .map(|i| grid.position([i % nx, (i / nx) % ny, i / (nx * ny)]))
            .collect();
        let values = eval.values(&vertices);
        let mut scanned = Vec::new();
        for i in 0..(nx - 1) * (ny - 1) * (nz - 1) {
            let c = [
                i % (nx - 1),
                (i / (nx - 1)) % (ny - 1),
                i / ((nx - 1) * (ny - 1)),
            ];
            let corners: Option<Vec<f64>> = (0..8)
                .map(|k| {
                    let o = corner_offset(k);
                    values[index([c[0] + o[0], c[1] + o[1], c[2] + o[2]])]
                })
                .collect();
            let Some(corners) = corners else { continue };
            let f: [f64; 8] = std::array::from_fn(|k| corners[k]);
            let inside_count = f.iter().filter(|&&v| inside(v)).count();
            if inside_count != 0 && inside_count != 8 {
                scanned.push((pack(c), cell_sheets(&f).0));
            }
        }
        scanned.sort_unstable();
        assert!(found.len() > 1000);
        assert_eq!(found, scanned);
    }
}
