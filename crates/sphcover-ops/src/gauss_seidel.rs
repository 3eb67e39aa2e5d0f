//! Symmetric Gauss–Seidel preconditioning on a fixed multicolour ordering.
//!
//! `M = (D + L) D⁻¹ (D + Lᵀ)` with `L` the strictly lower part of `A` in an ordering where the
//! supports are grouped by colour (no two neighbours share one). The colouring is greedy in
//! index order, so it depends on the matrix alone; within a colour the rows are independent,
//! so each colour is updated in parallel over fixed blocks and the result is bit-identical for
//! any thread count. `M` is symmetric positive definite when `A` is (diagonal positive), as
//! conjugate gradients need.

use rayon::prelude::*;

/// A symmetric matrix in compressed rows, its diagonal apart (the form the Gauss–Seidel
/// preconditioner needs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SparseRows {
    /// Row offsets into `columns` / `values` (length `n + 1`).
    pub offsets: Vec<u32>,
    /// Column of every off-diagonal entry.
    pub columns: Vec<u32>,
    /// Value of every off-diagonal entry.
    pub values: Vec<f64>,
    /// The diagonal (length `n`).
    pub diagonal: Vec<f64>,
}

/// Rows per parallel block inside one colour.
const BLOCK: usize = 2048;

/// The symmetric Gauss–Seidel preconditioner of a [`SparseRows`] matrix.
#[derive(Clone, Debug)]
pub struct SymmetricGaussSeidel {
    /// `order[p]` = original row at colour-sorted position `p`.
    order: Vec<u32>,
    /// Start of each colour in the sorted order (length colours + 1).
    colour_start: Vec<usize>,
    /// The matrix with rows and columns in the sorted order.
    offsets: Vec<u32>,
    columns: Vec<u32>,
    values: Vec<f64>,
    inv_diagonal: Vec<f64>,
}

impl SymmetricGaussSeidel {
    /// Colours the matrix graph greedily in index order and reorders it. Rows with a
    /// non-positive or non-finite diagonal are treated as identity rows.
    pub fn new(matrix: &SparseRows) -> SymmetricGaussSeidel {
        let n = matrix.diagonal.len();
        let row = |i: usize| matrix.offsets[i] as usize..matrix.offsets[i + 1] as usize;
        let mut colour = vec![u32::MAX; n];
        let mut used: Vec<bool> = Vec::new();
        for i in 0..n {
            used.iter_mut().for_each(|u| *u = false);
            for k in row(i) {
                let c = colour[matrix.columns[k] as usize];
                if c != u32::MAX && matrix.values[k] != 0.0 {
                    if used.len() <= c as usize {
                        used.resize(c as usize + 1, false);
                    }
                    used[c as usize] = true;
                }
            }
            let free = used.iter().position(|u| !u).unwrap_or(used.len());
            colour[i] = free as u32;
        }
        let colours = colour.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut colour_start = vec![0usize; colours + 1];
        for &c in &colour {
            colour_start[c as usize + 1] += 1;
        }
        for c in 0..colours {
            colour_start[c + 1] += colour_start[c];
        }
        let mut next = colour_start.clone();
        let mut order = vec![0u32; n];
        let mut position = vec![0u32; n];
        for i in 0..n {
            let c = colour[i] as usize;
            order[next[c]] = i as u32;
            position[i] = next[c] as u32;
            next[c] += 1;
        }
        let mut offsets = Vec::with_capacity(n + 1);
        let mut columns = Vec::with_capacity(matrix.columns.len());
        let mut values = Vec::with_capacity(matrix.values.len());
        let mut inv_diagonal = Vec::with_capacity(n);
        offsets.push(0u32);
        for &i in &order {
            let i = i as usize;
            let d = matrix.diagonal[i];
            let usable = d > 0.0 && d.is_finite();
            inv_diagonal.push(if usable { 1.0 / d } else { 1.0 });
            if usable {
                for k in row(i) {
                    let j = matrix.columns[k] as usize;
                    let dj = matrix.diagonal[j];
                    // Entries into identity rows are dropped on both sides (symmetry of M).
                    if matrix.values[k] != 0.0 && dj > 0.0 && dj.is_finite() {
                        columns.push(position[matrix.columns[k] as usize]);
                        values.push(matrix.values[k]);
                    }
                }
            }
            offsets.push(columns.len() as u32);
        }
        SymmetricGaussSeidel {
            order,
            colour_start,
            offsets,
            columns,
            values,
            inv_diagonal,
        }
    }

    /// Number of colours of the ordering.
    pub fn colours(&self) -> usize {
        self.colour_start.len() - 1
    }

    /// `Σ_k A_ik x_k` over the off-diagonal entries of sorted row `p`, reading the rows before
    /// the current colour from `before` and those after it from `after` (`after_start` is the
    /// first sorted index of `after`); entries of the current colour do not exist.
    #[inline]
    fn off_diagonal(&self, p: usize, before: &[f64], after: &[f64], after_start: usize) -> f64 {
        let mut acc = 0.0;
        for k in self.offsets[p] as usize..self.offsets[p + 1] as usize {
            let q = self.columns[k] as usize;
            let x = if q < before.len() {
                before[q]
            } else {
                after[q - after_start]
            };
            acc += self.values[k] * x;
        }
        acc
    }

    /// `z = M⁻¹ r`; `work` is resized to the dimension.
    pub fn apply(&self, r: &[f64], z: &mut [f64], work: &mut Vec<f64>) {
        let n = self.order.len();
        work.clear();
        work.resize(2 * n, 0.0);
        let (y, x) = work.split_at_mut(n);
        // Forward: (D + L) y = r in sorted order; later colours of y are still zero.
        let sorted_r: Vec<f64> = self.order.iter().map(|&i| r[i as usize]).collect();
        for c in 0..self.colours() {
            let (start, end) = (self.colour_start[c], self.colour_start[c + 1]);
            let (before, rest) = y.split_at_mut(start);
            let (mid, after) = rest.split_at_mut(end - start);
            let (before, after) = (&*before, &*after);
            mid.par_chunks_mut(BLOCK).enumerate().for_each(|(b, out)| {
                for (l, v) in out.iter_mut().enumerate() {
                    let p = start + b * BLOCK + l;
                    *v = (sorted_r[p] - self.off_diagonal(p, before, after, end))
                        * self.inv_diagonal[p];
                }
            });
        }
        // Backward: (D + Lᵀ) x = D y, colours in reverse; earlier colours of x still zero.
        for c in (0..self.colours()).rev() {
            let (start, end) = (self.colour_start[c], self.colour_start[c + 1]);
            let (before, rest) = x.split_at_mut(start);
            let (mid, after) = rest.split_at_mut(end - start);
            let (before, after) = (&*before, &*after);
            let y = &*y;
            mid.par_chunks_mut(BLOCK).enumerate().for_each(|(b, out)| {
                for (l, v) in out.iter_mut().enumerate() {
                    let p = start + b * BLOCK + l;
                    *v = y[p] - self.off_diagonal(p, before, after, end) * self.inv_diagonal[p];
                }
            });
        }
        for (p, &i) in self.order.iter().enumerate() {
            z[i as usize] = x[p];
        }
    }
}
