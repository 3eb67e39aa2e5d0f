//! Where an insertion reads and writes cells and marks.
//!
//! One insertion algorithm (`insert`) serves two stores: [`WholeStore`], the triangulation's
//! own arrays, in which an insertion may change every cell; and the store of one region of
//! a parallel round (`parallel`), in which it may change only the cells of its region and
//! must leave the others as they are. The second answers `false` from
//! [`CellRead::owns`] for a cell outside its region, and the insertion then gives up (the
//! point is inserted later, alone) rather than change it.

use super::{Cell, DEAD, Marks};

/// Read access to cells.
pub(super) trait CellRead {
    /// A copy of slot `t`.
    fn cell(&self, t: u32) -> Cell;
    /// Whether the current insertion may change cell `t`. A cell it may not change is
    /// only read, and only its vertices: its neighbour handles can be stale.
    fn owns(&self, t: u32) -> bool;
}

/// Everything an insertion changes.
pub(super) trait CellStore: CellRead {
    fn set_neighbour(&mut self, t: u32, i: usize, n: u32);
    /// Marks slot `t` free (its vertices become [`DEAD`]).
    fn kill(&mut self, t: u32);
    fn mark(&self, t: u32) -> u8;
    fn set_mark(&mut self, t: u32, m: u8);
    fn vmark(&self, v: u32) -> u32;
    fn set_vmark(&mut self, v: u32, stamp: u32);
    fn hide(&mut self, v: u32);
    /// Room for `count` new cells and their marks; `false` when the store has none (the
    /// insertion then gives up before changing anything).
    fn reserve(&mut self, count: usize) -> bool;
    /// A slot for a new cell: the last freed one, else a fresh one.
    fn alloc(&mut self, cell: Cell) -> u32;
    /// Gives back the slots of `cells`, already killed.
    fn release(&mut self, cells: &[u32]);
    /// Points the face that `outer` shares with the replaced cell `old` (the face of `old`
    /// opposite its vertex `face`) at the new cell `new`. `read_only`: `outer` is a cell
    /// the store does not own.
    fn link_outer(&mut self, outer: u32, read_only: bool, old: u32, face: usize, new: u32);
}

impl CellRead for [Cell] {
    #[inline]
    fn cell(&self, t: u32) -> Cell {
        self[t as usize]
    }

    #[inline]
    fn owns(&self, _t: u32) -> bool {
        true
    }
}

/// The triangulation's own cells, free list and marks: an insertion may change any cell.
pub(super) struct WholeStore<'a> {
    pub cells: &'a mut Vec<Cell>,
    pub free: &'a mut Vec<u32>,
    pub marks: &'a mut Marks,
}

impl CellRead for WholeStore<'_> {
    #[inline]
    fn cell(&self, t: u32) -> Cell {
        self.cells[t as usize]
    }

    #[inline]
    fn owns(&self, _t: u32) -> bool {
        true
    }
}

impl CellStore for WholeStore<'_> {
    #[inline]
    fn set_neighbour(&mut self, t: u32, i: usize, n: u32) {
        self.cells[t as usize].n[i] = n;
    }

    #[inline]
    fn kill(&mut self, t: u32) {
        self.cells[t as usize].v = [DEAD; 4];
    }

    #[inline]
    fn mark(&self, t: u32) -> u8 {
        self.marks.mark[t as usize]
    }

    #[inline]
    fn set_mark(&mut self, t: u32, m: u8) {
        self.marks.mark[t as usize] = m;
    }

    #[inline]
    fn vmark(&self, v: u32) -> u32 {
        self.marks.vmark[v as usize]
    }

    #[inline]
    fn set_vmark(&mut self, v: u32, stamp: u32) {
        self.marks.vmark[v as usize] = stamp;
    }

    #[inline]
    fn hide(&mut self, v: u32) {
        self.marks.hidden[v as usize] = true;
    }

    #[inline]
    fn reserve(&mut self, count: usize) -> bool {
        // Every new cell's slot, reused or appended, gets a mark entry.
        let needed = self.cells.len() + count;
        if self.marks.mark.len() < needed {
            self.marks.mark.resize(needed, 0);
        }
        true
    }

    #[inline]
    fn alloc(&mut self, cell: Cell) -> u32 {
        if let Some(t) = self.free.pop() {
            self.cells[t as usize] = cell;
            t
        } else {
            self.cells.push(cell);
            (self.cells.len() - 1) as u32
        }
    }

    #[inline]
    fn release(&mut self, cells: &[u32]) {
        self.free.extend_from_slice(cells);
    }

    #[inline]
    fn link_outer(&mut self, outer: u32, _read_only: bool, old: u32, _face: usize, new: u32) {
        let back = self.cells[outer as usize]
            .n
            .iter()
            .position(|&x| x == old)
            .expect("adjacency is symmetric");
        self.cells[outer as usize].n[back] = new;
    }
}
