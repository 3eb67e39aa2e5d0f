//! Incremental construction: the first tetrahedron and its infinite neighbours, then for
//! every point the remembering stochastic walk, the depth-first search of its conflict zone
//! and the cone stitched over the zone's boundary (Bowyer–Watson).
//!
//! It is the heart of the construction and the only part that changes the cells, through a
//! store (`cells`): the whole triangulation, or one region of a parallel round, which
//! may change only its own cells (the insertion then gives up rather than change another).
//! Every geometric question it has goes through `conflict`.

use super::cells::{CellRead, CellStore, WholeStore};
use super::conflict::conflict;
use super::{
    BoundaryFace, Cell, DEAD, EdgeSlot, Geometry, IN_CONFLICT, INFINITE_VERTEX, Marks, NO_TET,
    OUTSIDE, RegularTriangulation, Scratch, UNTESTED, face_key,
};
use crate::predicates::{collinear, orient3d};

impl RegularTriangulation {
    /// Builds the first tetrahedron and its four infinite neighbours from the first four
    /// affinely independent points of `order`; returns them, or the dimension reached.
    pub(super) fn initial_simplex(&mut self, count: usize) -> Result<[u32; 4], u8> {
        let order: Vec<u32> = (0..count as u32).collect();
        let order = &order[..];
        let p = |v: u32| self.geometry.point(v);
        let Some(&a) = order.first() else {
            return Err(0);
        };
        let Some(&b) = order.get(1) else {
            return Err(0);
        };
        // b differs from a (centres are distinct).
        let collinear = |c: u32| collinear(p(a), p(b), p(c));
        let Some(&c) = order[2..].iter().find(|&&c| !collinear(c)) else {
            return Err(1);
        };
        let Some(&d) = order[2..]
            .iter()
            .find(|&&d| d != c && orient3d(p(a), p(b), p(c), p(d)) != 0)
        else {
            return Err(2);
        };
        let (a, b) = if orient3d(p(a), p(b), p(c), p(d)) > 0 {
            (a, b)
        } else {
            (b, a)
        };
        let finite = [a, b, c, d];
        let mut cells = vec![finite];
        for i in 0..4 {
            // Face i of the finite cell with the infinite vertex in place of vertex i, made
            // positive by swapping two finite vertices.
            let mut t = finite;
            t[i] = INFINITE_VERTEX;
            let (j, k) = match i {
                0 => (1, 2),
                _ => (0, if i == 1 { 2 } else { 1 }),
            };
            t.swap(j, k);
            cells.push(t);
        }
        for cell in &cells {
            self.alloc(*cell);
        }
        // Link the five cells by matching faces.
        for t in 0..5u32 {
            for i in 0..4 {
                let face = face_key(&self.cells[t as usize].v, i);
                for u in 0..5u32 {
                    if u == t {
                        continue;
                    }
                    for j in 0..4 {
                        if face_key(&self.cells[u as usize].v, j) == face {
                            self.cells[t as usize].n[i] = u;
                        }
                    }
                }
            }
        }
        Ok(finite)
    }

    #[inline]
    fn alloc(&mut self, cell: [u32; 4]) -> u32 {
        if let Some(t) = self.free.pop() {
            self.cells[t as usize].v = cell;
            self.cells[t as usize].n = [NO_TET; 4];
            t
        } else {
            self.cells.push(Cell {
                v: cell,
                n: [NO_TET; 4],
            });
            (self.cells.len() - 1) as u32
        }
    }

    /// Inserts point `v`, walking from `hint`; returns a live tetrahedron near `v`.
    pub(super) fn insert(&mut self, v: u32, hint: u32, marks: &mut Marks, s: &mut Scratch) -> u32 {
        let mut hint = hint;
        if self.cells[hint as usize].v[0] == DEAD {
            hint = (0..self.cells.len() as u32)
                .find(|&x| self.cells[x as usize].v[0] != DEAD)
                .unwrap_or(0);
        }
        if marks.mark.len() < self.cells.len() {
            marks.mark.resize(self.cells.len(), UNTESTED);
        }
        let mut store = WholeStore {
            cells: &mut self.cells,
            free: &mut self.free,
            marks,
        };
        match insert_point(&mut store, &self.geometry, v, hint, s) {
            Ok(t) => t,
            Err(GaveUp) => unreachable!("the whole store owns every cell"),
        }
    }

    /// The walk of [`Self::insert`] from the live cell `hint`, changing nothing.
    pub(super) fn locate_read_only(&self, v: u32, hint: u32, s: &mut Scratch) -> u32 {
        match locate(&self.cells[..], &self.geometry, v, hint, s) {
            Ok(t) => t,
            Err(GaveUp) => unreachable!("every cell is readable"),
        }
    }
}

/// An insertion that would have changed a cell its store does not own; nothing was changed.
#[derive(Clone, Copy, Debug)]
pub(super) struct GaveUp;

/// Inserts point `v` into `store`, walking from the live cell `hint`; returns a live
/// tetrahedron near `v`, or gives up, changing nothing, when the walk or the conflict zone
/// reaches a cell the store does not own or the store has no room.
pub(super) fn insert_point<S: CellStore>(
    store: &mut S,
    geometry: &Geometry,
    v: u32,
    hint: u32,
    s: &mut Scratch,
) -> Result<u32, GaveUp> {
    let start = locate(store, geometry, v, hint, s)?;
    // `locate` ends in a cell the store owns, so the test has an answer.
    if conflict(store, geometry, start, v) != Some(true) {
        store.hide(v);
        return Ok(start);
    }
    s.stamp += 1;
    let (conflict_mark, outside) = (IN_CONFLICT, OUTSIDE);
    // The search's vectors as locals (their lengths can then live in registers across the
    // out-of-line predicate calls); put back below.
    let mut stack = std::mem::take(&mut s.stack);
    let mut cavity = std::mem::take(&mut s.cavity);
    let mut boundary = std::mem::take(&mut s.boundary);
    stack.clear();
    cavity.clear();
    boundary.clear();
    stack.push(start);
    store.set_mark(start, conflict_mark);
    let mut gave_up = false;
    'search: while let Some(t) = stack.pop() {
        cavity.push(t);
        let neighbours = store.cell(t).n;
        for (i, n) in (0..4u8).zip(neighbours) {
            let m = store.mark(n);
            if m == conflict_mark {
                continue;
            }
            if m != outside {
                if !store.owns(n) {
                    // Read only: on the boundary of the zone, or the insertion gives up.
                    if conflict(store, geometry, n, v) != Some(false) {
                        gave_up = true;
                        break 'search;
                    }
                    boundary.push(BoundaryFace {
                        old: t,
                        face: i,
                        read_only: true,
                        new: NO_TET,
                    });
                    continue;
                }
                if conflict(store, geometry, n, v) == Some(true) {
                    store.set_mark(n, conflict_mark);
                    stack.push(n);
                    continue;
                }
            }
            store.set_mark(n, outside);
            boundary.push(BoundaryFace {
                old: t,
                face: i,
                read_only: false,
                new: NO_TET,
            });
        }
    }
    if gave_up || !store.reserve(boundary.len()) {
        // Clear this search's marks; nothing else was changed.
        for &t in stack.iter().chain(&cavity) {
            store.set_mark(t, UNTESTED);
        }
        for f in boundary.iter().filter(|f| !f.read_only) {
            let outer = store.cell(f.old).n[f.face as usize];
            store.set_mark(outer, UNTESTED);
        }
        s.stack = stack;
        s.cavity = cavity;
        s.boundary = boundary;
        return Err(GaveUp);
    }
    s.stack = stack;
    s.cavity = cavity;
    s.boundary = boundary;
    s.conflict_tets += s.cavity.len() as u64;
    // Cone from v over the zone's boundary. The old cell keeps, in the slot of the
    // boundary face, the handle of the new cell built on that face: the second pass
    // finds the new cells' mutual neighbours through it.
    // New cells take the free slots last freed first, then fresh ones; a reused slot's mark
    // was cleared when it was freed and a fresh one is clear, so every new cell is UNTESTED.
    let stamp = s.stamp;
    for f in s.boundary.iter_mut() {
        let (t, i) = (f.old, f.face as usize);
        let old = store.cell(t);
        let mut fresh = Cell {
            v: old.v,
            n: [NO_TET; 4],
        };
        fresh.v[i] = v;
        let outer = old.n[i];
        fresh.n[i] = outer;
        let nt = store.alloc(fresh);
        if !f.read_only {
            // The search is over: clear the tested-outside mark for the next insertion.
            store.set_mark(outer, UNTESTED);
        }
        store.link_outer(outer, f.read_only, t, i, nt);
        store.set_neighbour(t, i, nt);
        // The boundary facet's vertices stay; `v` is new.
        for (k, &u) in old.v.iter().enumerate() {
            if k != i && u != INFINITE_VERTEX {
                store.set_vmark(u, stamp);
            }
        }
        f.new = nt;
    }
    // Each face of a new cell through v contains an edge ab of the zone's boundary (a
    // closed surface: every edge is on exactly two boundary faces), and the neighbour
    // across it is the new cell on the other face through ab. They are paired by a
    // small open-addressing table keyed by the edge, stamped per insertion (no clearing).
    let edges = 3 * s.boundary.len() / 2;
    if s.edge_table.len() < 4 * edges {
        let size = (4 * edges).next_power_of_two();
        s.edge_table.clear();
        s.edge_table.resize(size, EdgeSlot::default());
    }
    let mask = s.edge_table.len() - 1;
    let shift = 64 - s.edge_table.len().trailing_zeros();
    for f in &s.boundary {
        let (i, nt) = (f.face as usize, f.new);
        let cell = store.cell(nt).v;
        for k in 0..4usize {
            if k == i {
                continue;
            }
            let (x, y) = other_two(i, k);
            let (a, b) = (cell[x], cell[y]);
            let key = if a < b {
                ((a as u64) << 32) | b as u64
            } else {
                ((b as u64) << 32) | a as u64
            };
            let mut h = (key.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> shift) as usize;
            loop {
                let slot = &mut s.edge_table[h];
                if slot.stamp != stamp {
                    *slot = EdgeSlot {
                        key,
                        cell: nt,
                        face: k as u32,
                        stamp,
                    };
                    break;
                }
                if slot.key == key {
                    store.set_neighbour(nt, k, slot.cell);
                    store.set_neighbour(slot.cell, slot.face as usize, nt);
                    break;
                }
                h = (h + 1) & mask;
            }
        }
    }
    // A vertex of the zone on no boundary facet has been swallowed.
    for &t in &s.cavity {
        for u in store.cell(t).v {
            if u != INFINITE_VERTEX && store.vmark(u) != stamp {
                store.hide(u);
            }
        }
        store.kill(t);
        store.set_mark(t, UNTESTED);
    }
    store.release(&s.cavity);
    Ok(s.boundary[0].new)
}

/// Remembering stochastic walk to a tetrahedron containing point `v` (closed), or to an
/// infinite tetrahedron whose hull facet `v` lies strictly beyond; gives up on reaching a
/// cell the store does not own.
fn locate<S: CellRead + ?Sized>(
    cells: &S,
    geometry: &Geometry,
    v: u32,
    hint: u32,
    s: &mut Scratch,
) -> Result<u32, GaveUp> {
    let mut t = hint;
    if let Some(k) = cells.cell(t).v.iter().position(|&x| x == INFINITE_VERTEX) {
        t = cells.cell(t).n[k];
        if !cells.owns(t) {
            return Err(GaveUp);
        }
    }
    let mut previous = NO_TET;
    let mut steps = 0u64;
    'walk: loop {
        let cell = cells.cell(t);
        let first = (s.rng.next_u64() >> 62) as usize;
        for j in 0..4 {
            let i = (first + j) & 3;
            let n = cell.n[i];
            if n == previous {
                continue;
            }
            let mut ids = cell.v;
            ids[i] = v;
            steps += 1;
            if geometry.orient(ids) < 0 {
                s.walk_steps += steps;
                if !cells.owns(n) {
                    return Err(GaveUp);
                }
                steps = 0;
                previous = t;
                t = n;
                if cells.cell(t).v.contains(&INFINITE_VERTEX) {
                    return Ok(t);
                }
                continue 'walk;
            }
        }
        s.walk_steps += steps;
        return Ok(t);
    }
}

/// The two positions of `0..4` other than `i` and `k` (`i ≠ k`), by table.
#[inline]
fn other_two(i: usize, k: usize) -> (usize, usize) {
    const OTHER: [[(u8, u8); 4]; 4] = [
        [(0, 0), (2, 3), (1, 3), (1, 2)],
        [(2, 3), (0, 0), (0, 3), (0, 2)],
        [(1, 3), (0, 3), (0, 0), (0, 1)],
        [(1, 2), (0, 2), (0, 1), (0, 0)],
    ];
    let (x, y) = OTHER[i & 3][k & 3];
    (x as usize, y as usize)
}
