//! An additive two-level preconditioner: Jacobi plus a coarse correction on aggregates.
//!
//! The method is described on [`TwoLevel`].

use std::collections::VecDeque;

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};
use rayon::prelude::*;

use crate::gauss_seidel::SparseRows;

/// At most this many aggregates (the coarse matrix is dense).
const MAX_AGGREGATES: usize = 800;

/// The two-level preconditioner of a [`SparseRows`] matrix.
///
/// `M⁻¹ = D⁻¹ + P (PᵀAP)⁻¹ Pᵀ` with `P` the piecewise-constant prolongation of aggregates of
/// about [`TwoLevel::aggregate_size`] rows, grown breadth-first over the matrix graph from
/// seeds taken in index order (so they depend on the matrix alone), and the coarse matrix
/// `PᵀAP` factored once by dense Cholesky. The coarse space carries the smooth modes that
/// Jacobi cannot reduce (the reason CG on a Poisson problem needs `O(n^{1/3})` iterations),
/// and every step is a fixed-order sum, so iterates are bit-identical for any thread count.
/// `M` is symmetric positive definite when `A` is.
#[derive(Clone, Debug)]
pub struct TwoLevel {
    aggregate: Vec<u32>,
    inv_diagonal: Vec<f64>,
    coarse: Option<Cholesky<f64, Dyn>>,
    count: usize,
    size: usize,
}

impl TwoLevel {
    /// Aggregates the matrix graph and factors the coarse matrix. When the coarse matrix is not
    /// positive definite (the fine one is not either) the preconditioner is plain Jacobi.
    pub fn new(matrix: &SparseRows) -> TwoLevel {
        let n = matrix.diagonal.len();
        let size = n.div_ceil(MAX_AGGREGATES).max(64);
        let mut aggregate = vec![u32::MAX; n];
        let mut count = 0usize;
        let mut queue = VecDeque::new();
        for seed in 0..n {
            if aggregate[seed] != u32::MAX {
                continue;
            }
            let id = count as u32;
            count += 1;
            aggregate[seed] = id;
            queue.clear();
            queue.push_back(seed);
            let mut members = 1;
            while let Some(i) = queue.pop_front() {
                for k in matrix.offsets[i] as usize..matrix.offsets[i + 1] as usize {
                    let j = matrix.columns[k] as usize;
                    if members < size && matrix.values[k] != 0.0 && aggregate[j] == u32::MAX {
                        aggregate[j] = id;
                        members += 1;
                        queue.push_back(j);
                    }
                }
                if members >= size {
                    break;
                }
            }
        }
        let inv_diagonal: Vec<f64> = matrix
            .diagonal
            .iter()
            .map(|&d| {
                if d > 0.0 && d.is_finite() {
                    1.0 / d
                } else {
                    1.0
                }
            })
            .collect();
        // Small leftovers make many tiny aggregates on fragmented graphs; beyond the cap the
        // coarse level is skipped (Jacobi only).
        let coarse = (count <= 4 * MAX_AGGREGATES).then(|| {
            let mut a = DMatrix::<f64>::zeros(count, count);
            for i in 0..n {
                let ai = aggregate[i] as usize;
                a[(ai, ai)] += matrix.diagonal[i];
                for k in matrix.offsets[i] as usize..matrix.offsets[i + 1] as usize {
                    let aj = aggregate[matrix.columns[k] as usize] as usize;
                    a[(ai, aj)] += matrix.values[k];
                }
            }
            Cholesky::new(a)
        });
        TwoLevel {
            aggregate,
            inv_diagonal,
            coarse: coarse.flatten(),
            count,
            size,
        }
    }

    /// Target rows per aggregate.
    pub fn aggregate_size(&self) -> usize {
        self.size
    }

    /// Number of aggregates (coarse unknowns).
    pub fn aggregates(&self) -> usize {
        self.count
    }

    /// Whether the coarse correction is in use.
    pub fn has_coarse_level(&self) -> bool {
        self.coarse.is_some()
    }

    /// `z = M⁻¹ r`.
    pub fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.par_iter_mut()
            .zip(r.par_iter().zip(self.inv_diagonal.par_iter()))
            .for_each(|(zi, (ri, di))| *zi = ri * di);
        let Some(coarse) = &self.coarse else {
            return;
        };
        // Pᵀ r in index order (a fixed-order sum), the coarse solve, then z += P y.
        let mut rc = DVector::<f64>::zeros(self.count);
        for (i, &a) in self.aggregate.iter().enumerate() {
            rc[a as usize] += r[i];
        }
        let y = coarse.solve(&rc);
        z.par_iter_mut()
            .zip(self.aggregate.par_iter())
            .for_each(|(zi, &a)| *zi += y[a as usize]);
    }
}
