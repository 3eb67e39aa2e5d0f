//! Parallel insertion of a large BRIO round, region by region.
//!
//! The round's points are split into regions by axis-aligned median planes (a small k-d
//! tree over a sample of them), and each region inserts its points on a thread of its own
//! with the same insertion as the one-by-one construction (`insert`), through a
//! [`RegionStore`]: it may change only the cells whose finite vertices all lie in its region.
//! A point whose walk or conflict zone would reach another cell (one across a region border)
//! is deferred. The deferred points lie along the borders; a second and a third pass split
//! them by new planes, across those borders, and the few left are inserted one after another.
//!
//! Why the regions never touch each other's memory:
//! * two cells of different regions are never adjacent: their shared face would have its
//!   three vertices in both regions (a face has at least two finite vertices);
//! * an insertion replaces a zone of its own cells by cells built from the inserted point
//!   and faces of the zone, all of its region, whose neighbours were neighbours of the zone;
//! * so each region writes its own cells, their marks, the vertices of its region and fresh
//!   slots of its own chunks ([`CHUNK`]), and reads its own cells and the cells across its
//!   border, which no region changes during the pass. The one write a border cell needs (its
//!   neighbour handle towards a new cell) is logged and done after the pass; until then it
//!   is stale, so the border cells' neighbour handles are never read.
//!
//! Determinism: a region's insertions depend only on its own cells and the border cells, so
//! each region does the same work in the same order whatever thread runs it and whatever the
//! others do meanwhile; the number of regions depends on the pass's size only, and the
//! merge runs in region order. The output is the same for every thread count. The regular
//! triangulation itself is unique, so it is also the one-by-one construction's, with cells
//! in other slots.

use rayon::prelude::*;

use super::cells::{CellRead, CellStore};
use super::insert::{GaveUp, insert_point};
use super::{
    Cell, DEAD, INFINITE_VERTEX, Marks, NO_TET, RegularTriangulation, Scratch, TriangulationParams,
    UNTESTED, WeightedPoint,
};
use crate::predicates::Point;

/// The fewest points a pass by regions takes: an eighth of a region's (two regions of a
/// sixteenth each; below that, deferrals and the pass's set-up outweigh the second thread).
pub(super) fn min_round(params: &TriangulationParams) -> usize {
    (params.region_points / 8).max(1)
}

/// Most regions in one round.
const MAX_REGIONS: usize = 64;

/// The number of regions of a round of `n` points, `n / region_points` rounded down to a
/// power of two in `2..=MAX_REGIONS`: a function of the round and the parameters alone, so
/// the output does not depend on the thread count.
fn region_count(n: usize, region_points: usize) -> usize {
    let r = (n / region_points.max(1)).clamp(2, MAX_REGIONS);
    1 << r.ilog2()
}

/// Median planes splitting space into `2^depth` boxes, in heap order: node `k` splits into
/// `2k` (below the plane) and `2k + 1` (on or above it); box `b` is leaf `2^depth + b`.
struct RegionSplit {
    depth: u32,
    /// `(axis, value)` of node `k` at index `k` (index 0 unused).
    planes: Vec<(usize, f64)>,
}

impl RegionSplit {
    /// Splits the points `ids` of `pw` (a sample of a pass's points) into `regions` (a power
    /// of two) boxes of nearly equal counts, each along its longest side. Reorders `ids`
    /// box by box and returns where each box's part starts (and the end).
    fn new(pw: &[WeightedPoint], ids: &mut [u32], regions: usize) -> (Self, Vec<usize>) {
        let depth = regions.ilog2();
        let mut planes = vec![(0usize, 0.0f64); regions];
        let mut spans = vec![(0usize, ids.len())];
        for node in 1..regions {
            let (lo, hi) = spans[node - 1];
            let part = &mut ids[lo..hi];
            let axis = longest_axis(pw, part);
            let mid = part.len() / 2;
            if !part.is_empty() {
                part.select_nth_unstable_by(mid, |&a, &b| {
                    pw[a as usize].p[axis]
                        .total_cmp(&pw[b as usize].p[axis])
                        .then(a.cmp(&b))
                });
                planes[node] = (axis, pw[part[mid] as usize].p[axis]);
            }
            spans.push((lo, lo + mid));
            spans.push((lo + mid, hi));
        }
        // The leaves are the last `regions` spans, in box order.
        let mut starts: Vec<usize> = spans[regions - 1..].iter().map(|s| s.0).collect();
        starts.push(ids.len());
        (RegionSplit { depth, planes }, starts)
    }

    /// The box of point `p`.
    #[inline]
    fn region_of(&self, p: &Point) -> u8 {
        let mut node = 1;
        for _ in 0..self.depth {
            let (axis, value) = self.planes[node];
            node = 2 * node + usize::from(p[axis] >= value);
        }
        (node - (1 << self.depth)) as u8
    }
}

/// The axis along which `ids` spread most.
fn longest_axis(pw: &[WeightedPoint], ids: &[u32]) -> usize {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &i in ids {
        let p = &pw[i as usize].p;
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])).then(b.cmp(&a)))
        .unwrap_or(0)
}

/// Fresh slots are handed to the regions in chunks of this many, interleaved: chunk `k` of
/// region `r` of `R` is the `(k·R + r)`-th after the slots in use. After a pass, the chunks
/// and chunk tails no region took up to the last one taken become free slots: at most two
/// chunks per region, whatever the regions' sizes.
const CHUNK: u32 = 1024;

/// Raw views of the arrays the regions share (see the module docs for why their writes are
/// disjoint).
#[derive(Clone, Copy)]
struct Shared {
    /// The cells' buffer: `slots` long, initialised up to where the pass began and, beyond,
    /// wherever a region wrote a new cell.
    cells: *mut Cell,
    slots: u32,
    /// Marks of every slot of `cells`.
    mark: *mut u8,
    vmark: *mut u32,
    hidden: *mut bool,
    vertices: usize,
}

// SAFETY: the pointers stay valid for the whole pass (the vectors are neither resized nor
// dropped while the regions run), and the regions access disjoint entries (module docs).
#[allow(unsafe_code)]
unsafe impl Send for Shared {}
#[allow(unsafe_code)]
unsafe impl Sync for Shared {}

/// Where the fresh slots of one region's chunks are.
#[derive(Clone, Copy, Debug)]
struct Chunks {
    /// The first slot after the cells in use when the pass began.
    base: u32,
    region: u32,
    regions: u32,
    /// Chunks taken so far.
    taken: u32,
    /// The next fresh slot of the current chunk and the chunk's end.
    next: u32,
    end: u32,
}

impl Chunks {
    /// The first slot of chunk `k`.
    fn start(&self, k: u32) -> u64 {
        u64::from(self.base)
            + (u64::from(k) * u64::from(self.regions) + u64::from(self.region)) * u64::from(CHUNK)
    }

    /// Fresh slots this region can still take below `slots`.
    fn available(&self, slots: u32) -> u64 {
        let in_chunk = u64::from(self.end - self.next);
        let next_chunk = self.start(self.taken);
        let (chunk, stride) = (u64::from(CHUNK), u64::from(self.regions) * u64::from(CHUNK));
        if next_chunk + chunk > u64::from(slots) {
            return in_chunk;
        }
        in_chunk + ((u64::from(slots) - next_chunk - chunk) / stride + 1) * chunk
    }
}

/// The store of one region during a pass.
struct RegionStore<'a> {
    shared: Shared,
    /// Region of each vertex inserted so far.
    region_of: &'a [u8],
    region: u8,
    /// Slots this region freed, reused last freed first.
    free: Vec<u32>,
    chunks: Chunks,
    /// Neighbour handles of border cells to set after the pass: `(cell, face, new)`.
    log: Vec<(u32, u8, u32)>,
}
impl RegionStore<'_> {
    #[inline]
    fn owns_vertices(&self, v: &[u32; 4]) -> bool {
        v.iter()
            .all(|&x| x == INFINITE_VERTEX || self.region_of[x as usize] == self.region)
    }
}

#[allow(unsafe_code)]
impl CellRead for RegionStore<'_> {
    #[inline]
    fn cell(&self, t: u32) -> Cell {
        debug_assert!(t < self.shared.slots);
        // SAFETY: in bounds; cell `t` is this region's or a border cell, which no region
        // writes during the round (module docs).
        unsafe { *self.shared.cells.add(t as usize) }
    }

    #[inline]
    fn owns(&self, t: u32) -> bool {
        self.owns_vertices(&self.cell(t).v)
    }
}

#[allow(unsafe_code)]
impl CellStore for RegionStore<'_> {
    #[inline]
    fn set_neighbour(&mut self, t: u32, i: usize, n: u32) {
        debug_assert!(t < self.shared.slots);
        // SAFETY: in bounds, and cell `t` is this region's.
        unsafe { (*self.shared.cells.add(t as usize)).n[i] = n }
    }

    #[inline]
    fn kill(&mut self, t: u32) {
        debug_assert!(t < self.shared.slots);
        // SAFETY: as in `set_neighbour`.
        unsafe { (*self.shared.cells.add(t as usize)).v = [DEAD; 4] }
    }

    #[inline]
    fn mark(&self, t: u32) -> u8 {
        debug_assert!(t < self.shared.slots);
        // SAFETY: in bounds (the marks cover every slot); only this region writes the marks
        // of its cells, and no region writes a border cell's.
        unsafe { *self.shared.mark.add(t as usize) }
    }

    #[inline]
    fn set_mark(&mut self, t: u32, m: u8) {
        debug_assert!(t < self.shared.slots);
        // SAFETY: in bounds, and cell `t` is this region's.
        unsafe { *self.shared.mark.add(t as usize) = m }
    }

    #[inline]
    fn vmark(&self, v: u32) -> u32 {
        debug_assert!((v as usize) < self.shared.vertices);
        // SAFETY: in bounds, and vertex `v` is of this region.
        unsafe { *self.shared.vmark.add(v as usize) }
    }

    #[inline]
    fn set_vmark(&mut self, v: u32, stamp: u32) {
        debug_assert!((v as usize) < self.shared.vertices);
        // SAFETY: as in `vmark`.
        unsafe { *self.shared.vmark.add(v as usize) = stamp }
    }

    #[inline]
    fn hide(&mut self, v: u32) {
        debug_assert!((v as usize) < self.shared.vertices);
        // SAFETY: as in `vmark`.
        unsafe { *self.shared.hidden.add(v as usize) = true }
    }

    #[inline]
    fn reserve(&mut self, count: usize) -> bool {
        self.free.len() as u64 + self.chunks.available(self.shared.slots) >= count as u64
    }

    #[inline]
    fn alloc(&mut self, cell: Cell) -> u32 {
        let t = match self.free.pop() {
            Some(t) => t,
            None => {
                let c = &mut self.chunks;
                if c.next == c.end {
                    // `reserve` made sure the next chunk fits below `slots`.
                    c.next = c.start(c.taken) as u32;
                    c.end = c.next + CHUNK;
                    c.taken += 1;
                }
                c.next += 1;
                c.next - 1
            }
        };
        debug_assert!(t < self.shared.slots);
        // SAFETY: in bounds; a slot this region freed or a fresh slot of its chunks. A
        // fresh slot may be uninitialised: it is written whole, never read first.
        unsafe { self.shared.cells.add(t as usize).write(cell) }
        t
    }

    #[inline]
    fn release(&mut self, cells: &[u32]) {
        self.free.extend_from_slice(cells);
    }

    #[inline]
    fn link_outer(&mut self, outer: u32, read_only: bool, old: u32, face: usize, new: u32) {
        let around = self.cell(outer);
        if read_only {
            // The face's vertices are `old`'s but its vertex `face`; `outer`'s slot for it
            // is the one of its vertex not on the face.
            let o = self.cell(old).v;
            let j = (0..4)
                .find(|&j| !(0..4).any(|k| k != face && o[k] == around.v[j]))
                .expect("neighbours share a face");
            self.log.push((outer, j as u8, new));
            return;
        }
        let back = around
            .n
            .iter()
            .position(|&x| x == old)
            .expect("adjacency is symmetric");
        self.set_neighbour(outer, back, new);
    }
}

/// What one region did in a pass.
struct RegionOutcome {
    /// A live cell of the region near its last insertion, if it made one.
    last: Option<u32>,
    free: Vec<u32>,
    chunks: Chunks,
    log: Vec<(u32, u8, u32)>,
    deferred: Vec<u32>,
    walk_steps: u64,
    conflict_tets: u64,
}

/// The points of one pass: a round of the insertion order, less the first cell's vertices,
/// or the points an earlier pass deferred.
#[derive(Clone, Copy)]
enum PassPoints<'a> {
    Round {
        start: u32,
        end: u32,
        skip: [u32; 4],
    },
    Deferred(&'a [u32]),
}

impl PassPoints<'_> {
    fn iter(&self) -> impl Iterator<Item = u32> + '_ {
        let (round, list) = match *self {
            PassPoints::Round { start, end, skip } => {
                (Some((start..end).filter(move |v| !skip.contains(v))), None)
            }
            PassPoints::Deferred(list) => (None, Some(list.iter().copied())),
        };
        round
            .into_iter()
            .flatten()
            .chain(list.into_iter().flatten())
    }

    fn len(&self) -> usize {
        match *self {
            PassPoints::Round { start, end, skip } => {
                (end - start) as usize - skip.iter().filter(|&&v| (start..end).contains(&v)).count()
            }
            PassPoints::Deferred(list) => list.len(),
        }
    }
}

/// Most passes by regions over one round: each pass splits the points the previous one
/// deferred (they lie along its borders) by new planes, across those borders.
const MAX_PASSES: u32 = 3;

/// The largest sample of a pass's points its planes are chosen from.
const SPLIT_SAMPLE: usize = 1 << 16;

impl RegularTriangulation {
    /// Inserts the points `start..end` of the insertion order but those of `skip` (the first
    /// cell's) by regions in parallel, in up to [`MAX_PASSES`] passes, then the points still
    /// deferred one after another; returns a live cell near the last point inserted.
    pub(super) fn insert_by_regions(
        &mut self,
        (start, end): (u32, u32),
        skip: [u32; 4],
        hint: u32,
        marks: &mut Marks,
        scratch: &mut Scratch,
        params: &TriangulationParams,
    ) -> u32 {
        let round = PassPoints::Round { start, end, skip };
        let total = round.len();
        let mut pending: Option<Vec<u32>> = None;
        let mut hint = hint;
        for pass in 0..MAX_PASSES {
            let points = pending.as_deref().map_or(round, PassPoints::Deferred);
            if points.len() < min_round(params) {
                break;
            }
            // Vertex numbers are insertion ranks: every vertex so far is below `end`.
            let inserted = start as usize + total - points.len();
            let (last, deferred) = self.region_pass(
                points,
                hint,
                (inserted, end as usize),
                marks,
                scratch,
                params,
                pass,
            );
            hint = last;
            pending = Some(deferred);
        }
        let rest = pending.as_deref().map_or(round, PassPoints::Deferred);
        if pending.is_some() {
            self.stats.deferred += rest.len() as u64;
        }
        for v in rest.iter() {
            hint = self.insert(v, hint, marks, scratch);
        }
        hint
    }

    /// One pass by regions over `points`; `taken`: how many points were inserted before,
    /// and a bound on the vertex numbers so far. Returns a live cell and the points deferred,
    /// in region order.
    #[allow(clippy::too_many_arguments)]
    fn region_pass(
        &mut self,
        points: PassPoints<'_>,
        hint: u32,
        (inserted, vertices): (usize, usize),
        marks: &mut Marks,
        scratch: &mut Scratch,
        params: &TriangulationParams,
        pass: u32,
    ) -> (u32, Vec<u32>) {
        let count = points.len();
        let regions = region_count(count, params.region_points);
        let pw = &self.geometry.pw;
        let mut sample: Vec<u32> = points
            .iter()
            .step_by(count.div_ceil(SPLIT_SAMPLE).max(1))
            .collect();
        let (split, leaves) = RegionSplit::new(pw, &mut sample, regions);
        let region_of: Vec<u8> = pw[..vertices]
            .par_iter()
            .with_min_len(4096)
            .map(|q| split.region_of(&q.p))
            .collect();
        let mut counts = vec![0u32; regions];
        for v in points.iter() {
            counts[region_of[v as usize] as usize] += 1;
        }

        // A start cell of each region: the cell holding a sampled point near the middle of
        // its box, if that cell is the region's.
        let mut starts = vec![None; regions];
        for (r, start) in starts.iter_mut().enumerate() {
            let part = &sample[leaves[r]..leaves[r + 1]];
            for probe in [part.len() / 2, part.len() / 4, 3 * part.len() / 4] {
                let Some(&v) = part.get(probe) else { break };
                if region_of[v as usize] != r as u8 {
                    continue;
                }
                let t = self.locate_read_only(v, hint, scratch);
                let cell = self.cells[t as usize].v;
                if cell
                    .iter()
                    .all(|&x| x == INFINITE_VERTEX || region_of[x as usize] == r as u8)
                {
                    *start = Some(t);
                    break;
                }
            }
        }
        drop(sample);

        // Fresh slots beyond the cells in use, in chunks taken as the regions need them, up
        // to a bound above the cells per point so far, within the capacity the construction
        // reserved (a region that reaches it defers its remaining points to the next pass).
        // Pages no region writes cost no memory.
        let base = self.cells.len();
        let per_point = (base - self.free.len()) as f64 / inserted.max(1) as f64;
        let room = (1.2 * per_point * count as f64) as usize + 2 * regions * CHUNK as usize;
        if self.cells.capacity() < base + room / 2 {
            self.cells.reserve(room);
        }
        let slots = (base + room)
            .min(self.cells.capacity())
            .min(u32::MAX as usize - 2);
        marks.mark.resize(slots, UNTESTED);

        let shared = Shared {
            cells: self.cells.as_mut_ptr(),
            slots: slots as u32,
            mark: marks.mark.as_mut_ptr(),
            vmark: marks.vmark.as_mut_ptr(),
            hidden: marks.hidden.as_mut_ptr(),
            vertices: marks.vmark.len(),
        };
        let geometry = &self.geometry;
        // Each region's stamps in a range of their own: at most one per point.
        let mut stamp_offsets = Vec::with_capacity(regions);
        let mut offset = scratch.stamp;
        for &m in &counts {
            stamp_offsets.push(offset);
            offset += m;
        }
        let first = points.iter().next().unwrap_or(0);
        let outcomes: Vec<RegionOutcome> = (0..regions)
            .into_par_iter()
            .with_max_len(1)
            .map(|r| {
                let mut store = RegionStore {
                    shared,
                    region_of: &region_of,
                    region: r as u8,
                    free: Vec::new(),
                    chunks: Chunks {
                        base: base as u32,
                        region: r as u32,
                        regions: regions as u32,
                        taken: 0,
                        next: 0,
                        end: 0,
                    },
                    log: Vec::new(),
                };
                let mut s = Scratch::new(
                    params.seed
                        ^ (u64::from(first) << 16)
                        ^ (u64::from(pass) << 8)
                        ^ r as u64
                        ^ 0x5ca1_ab1e_0ddb_a110,
                    stamp_offsets[r],
                );
                let mut deferred = Vec::new();
                let mut hint = starts[r];
                for v in points.iter().filter(|&v| region_of[v as usize] == r as u8) {
                    let outcome = match hint {
                        Some(h) => insert_point(&mut store, geometry, v, h, &mut s),
                        None => Err(GaveUp),
                    };
                    match outcome {
                        Ok(t) => hint = Some(t),
                        Err(GaveUp) => deferred.push(v),
                    }
                }
                RegionOutcome {
                    last: hint,
                    free: store.free,
                    chunks: store.chunks,
                    log: store.log,
                    deferred,
                    walk_steps: s.walk_steps,
                    conflict_tets: s.conflict_tets,
                }
            })
            .collect();
        scratch.stamp = offset;

        // Merge in region order: the border cells' neighbour handles, the slots, the counters.
        for o in &outcomes {
            for &(cell, face, new) in &o.log {
                self.cells[cell as usize].n[face as usize] = new;
            }
            self.free.extend_from_slice(&o.free);
            scratch.walk_steps += o.walk_steps;
            scratch.conflict_tets += o.conflict_tets;
        }
        let chunks: Vec<Chunks> = outcomes.iter().map(|o| o.chunks).collect();
        self.adopt_fresh_slots(&chunks, marks);

        // A cell of a region that inserted a point is live (no other region changes it);
        // the old hint is live when no region did.
        let hint = outcomes.iter().rev().find_map(|o| o.last).unwrap_or(hint);
        let deferred = outcomes.into_iter().flat_map(|o| o.deferred).collect();
        (hint, deferred)
    }

    /// Takes into the cells the fresh slots the regions wrote beyond `cells.len()`: the
    /// slots up to the end of the last chunk taken; those no region took become free.
    #[allow(unsafe_code)]
    fn adopt_fresh_slots(&mut self, chunks: &[Chunks], marks: &mut Marks) {
        let base = self.cells.len();
        let end = chunks
            .iter()
            .filter(|c| c.taken > 0)
            .map(|c| c.end as usize)
            .max()
            .unwrap_or(base);
        let dead = Cell {
            v: [DEAD; 4],
            n: [NO_TET; 4],
        };
        let regions = chunks.len();
        let ptr = self.cells.as_mut_ptr();
        for (j, start) in (base..end).step_by(CHUNK as usize).enumerate() {
            let c = &chunks[j % regions];
            let k = (j / regions) as u32;
            let untaken = if k + 1 < c.taken {
                start..start // taken and full
            } else if k + 1 == c.taken {
                c.next as usize..c.end as usize
            } else {
                start..start + CHUNK as usize
            };
            for t in untaken.rev() {
                // SAFETY: `t < end ≤ capacity` (the regions' chunks lie below the bound of
                // the pass, itself within the capacity); the slot was never written.
                unsafe { ptr.add(t).write(dead) }
                self.free.push(t as u32);
            }
        }
        // SAFETY: every slot below `end` is initialised: those below `base` were, the regions
        // wrote each slot they took whole, and the loop above wrote the others.
        unsafe { self.cells.set_len(end) }
        marks.mark.truncate(end);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn available_slots_match_counting_the_chunks(
            base in 0u32..5000,
            regions in 1u32..9,
            region in 0u32..8,
            taken in 0u32..6,
            left in 0u32..=CHUNK,
            slots in 0u32..40_000,
        ) {
            let region = region % regions;
            let mut c = Chunks { base, region, regions, taken, next: 0, end: 0 };
            if taken > 0 {
                c.end = c.start(taken - 1) as u32 + CHUNK;
                c.next = c.end - left;
            }
            let mut counted = u64::from(c.end - c.next);
            let mut k = taken;
            while c.start(k) + u64::from(CHUNK) <= u64::from(slots) {
                counted += u64::from(CHUNK);
                k += 1;
            }
            prop_assert_eq!(c.available(slots), counted);
        }
    }

    #[test]
    fn region_count_is_a_power_of_two_from_two_to_the_most() {
        assert_eq!(region_count(10, 1 << 15), 2);
        assert_eq!(region_count(3 << 15, 1 << 15), 2);
        assert_eq!(region_count(4 << 15, 1 << 15), 4);
        assert_eq!(region_count(usize::MAX, 1), MAX_REGIONS);
        assert_eq!(region_count(100, 0), MAX_REGIONS);
    }
}
