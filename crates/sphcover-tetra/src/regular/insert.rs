//! Incremental construction: the first tetrahedron and its infinite neighbours, then for
//! every point the remembering stochastic walk, the depth-first search of its conflict zone
//! and the cone stitched over the zone's boundary (Bowyer–Watson).
//!
//! It is the sequential heart of the construction and the only part that changes the cells;
//! every geometric question it has goes through `conflict`.

use super::{
    BoundaryFace, Cell, DEAD, EdgeSlot, IN_CONFLICT, INFINITE_VERTEX, NO_TET, OUTSIDE,
    RegularTriangulation, Scratch, UNTESTED, face_key,
};
use crate::predicates::{collinear, orient3d};

impl RegularTriangulation {
    /// Builds the first tetrahedron and its four infinite neighbours from the first four
    /// affinely independent points of `order`; returns them, or the dimension reached.
    pub(super) fn initial_simplex(&mut self, count: usize) -> Result<[u32; 4], u8> {
        let order: Vec<u32> = (0..count as u32).collect();
        let order = &order[..];
        let p = |v: u32| self.point(v);
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
    pub(super) fn insert(&mut self, v: u32, hint: u32, s: &mut Scratch) -> u32 {
        let start = self.locate(v, hint, s);
        if !self.in_conflict(start, v) {
            s.hidden[v as usize] = true;
            return start;
        }
        if s.mark.len() < self.cells.len() {
            s.mark.resize(self.cells.len(), 0);
        }
        s.stamp += 1;
        let (conflict, outside) = (IN_CONFLICT, OUTSIDE);
        // The search's vectors as locals (their lengths can then live in registers across the
        // out-of-line predicate calls); put back below.
        let mut stack = std::mem::take(&mut s.stack);
        let mut cavity = std::mem::take(&mut s.cavity);
        let mut boundary = std::mem::take(&mut s.boundary);
        let mark = &mut s.mark;
        stack.clear();
        cavity.clear();
        boundary.clear();
        stack.push(start);
        mark[start as usize] = conflict;
        while let Some(t) = stack.pop() {
            cavity.push(t);
            let neighbours = self.cells[t as usize].n;
            for (i, n) in (0..4u8).zip(neighbours) {
                let m = mark[n as usize];
                if m == conflict {
                    continue;
                }
                if m != outside && self.in_conflict(n, v) {
                    mark[n as usize] = conflict;
                    stack.push(n);
                } else {
                    mark[n as usize] = outside;
                    boundary.push(BoundaryFace {
                        old: t,
                        face: i,
                        new: NO_TET,
                    });
                }
            }
        }
        s.stack = stack;
        s.cavity = cavity;
        s.boundary = boundary;
        self.stats.conflict_tets += s.cavity.len() as u64;
        // Every new cell's slot, reused or appended, gets a mark entry.
        let needed = self.cells.len() + s.boundary.len();
        if s.mark.len() < needed {
            s.mark.resize(needed, UNTESTED);
        }
        // Cone from v over the zone's boundary. The old cell keeps, in the slot of the
        // boundary face, the handle of the new cell built on that face: the second pass
        // finds the new cells' mutual neighbours through it.
        // New cells take the free slots in the order `pop` would (last freed first), then
        // append; a reused slot's mark was cleared when it was freed and an appended one is
        // fresh, so every new cell is UNTESTED.
        let stamp = s.stamp;
        let (mark, vmark) = (&mut s.mark, &mut s.vmark);
        let free_len = self.free.len();
        let reused = free_len.min(s.boundary.len());
        for (j, f) in s.boundary.iter_mut().enumerate() {
            let (t, i) = (f.old, f.face as usize);
            let old = self.cells[t as usize];
            let mut fresh = Cell {
                v: old.v,
                n: [NO_TET; 4],
            };
            fresh.v[i] = v;
            let outer = old.n[i];
            fresh.n[i] = outer;
            let nt = if j < reused {
                let nt = self.free[free_len - 1 - j];
                self.cells[nt as usize] = fresh;
                nt
            } else {
                self.cells.push(fresh);
                (self.cells.len() - 1) as u32
            };
            // The search is over: clear the tested-outside mark for the next insertion.
            mark[outer as usize] = UNTESTED;
            let back = self.cells[outer as usize]
                .n
                .iter()
                .position(|&x| x == t)
                .expect("adjacency is symmetric");
            self.cells[outer as usize].n[back] = nt;
            self.cells[t as usize].n[i] = nt;
            // The boundary facet's vertices stay; `v` is new.
            for (k, &u) in old.v.iter().enumerate() {
                if k != i && u != INFINITE_VERTEX {
                    vmark[u as usize] = stamp;
                }
            }
            f.new = nt;
        }
        self.free.truncate(free_len - reused);
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
            let cell = self.cells[nt as usize].v;
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
                        self.cells[nt as usize].n[k] = slot.cell;
                        self.cells[slot.cell as usize].n[slot.face as usize] = nt;
                        break;
                    }
                    h = (h + 1) & mask;
                }
            }
        }
        // A vertex of the zone on no boundary facet has been swallowed.
        for &t in &s.cavity {
            for &u in &self.cells[t as usize].v {
                if u != INFINITE_VERTEX && s.vmark[u as usize] != s.stamp {
                    s.hidden[u as usize] = true;
                }
            }
            self.cells[t as usize].v = [DEAD; 4];
            s.mark[t as usize] = UNTESTED;
        }
        self.free.extend_from_slice(&s.cavity);

        s.boundary[0].new
    }

    /// Remembering stochastic walk to a tetrahedron containing point `v` (closed), or to an
    /// infinite tetrahedron whose hull facet `v` lies strictly beyond.
    fn locate(&mut self, v: u32, hint: u32, s: &mut Scratch) -> u32 {
        let mut t = hint;
        if self.cells[t as usize].v[0] == DEAD {
            t = (0..self.cells.len() as u32)
                .find(|&x| self.cells[x as usize].v[0] != DEAD)
                .unwrap_or(0);
        }
        if let Some(k) = self.cells[t as usize]
            .v
            .iter()
            .position(|&x| x == INFINITE_VERTEX)
        {
            t = self.cells[t as usize].n[k];
        }
        let mut previous = NO_TET;
        let mut steps = 0u64;
        'walk: loop {
            let cell = self.cells[t as usize].v;
            let first = (s.rng.next_u64() >> 62) as usize;
            for j in 0..4 {
                let i = (first + j) & 3;
                let n = self.cells[t as usize].n[i];
                if n == previous {
                    continue;
                }
                let mut ids = cell;
                ids[i] = v;
                steps += 1;
                if self.orient(ids) < 0 {
                    previous = t;
                    t = n;
                    if self.cells[t as usize].v.contains(&INFINITE_VERTEX) {
                        self.stats.walk_steps += steps;
                        return t;
                    }
                    continue 'walk;
                }
            }
            self.stats.walk_steps += steps;
            return t;
        }
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
