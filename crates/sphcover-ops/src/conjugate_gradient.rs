//! Preconditioned conjugate gradients for the symmetric systems the operators give.
//!
//! The method is described on [`conjugate_gradient()`].

use rayon::prelude::*;
use sphcover_core::ParameterError;
use thiserror::Error;

use crate::gauss_seidel::{SparseRows, SymmetricGaussSeidel};
use crate::two_level::TwoLevel;

/// Entries per partial sum of a dot product (fixed, so the reduction order never depends on
/// the thread pool).
pub const DOT_CHUNK: usize = 8192;

/// A symmetric linear operator `A` on `ℝⁿ`, applied matrix-free.
pub trait SymmetricOperator: Sync {
    /// The dimension `n`.
    fn dim(&self) -> usize;
    /// `y = A x`; `x` and `y` have length [`SymmetricOperator::dim`]. Must be deterministic.
    fn apply(&self, x: &[f64], y: &mut [f64]);
    /// Writes the diagonal of `A` (for the Jacobi preconditioner).
    fn diagonal(&self, diag: &mut [f64]);
    /// The matrix of `A` in compressed rows, for
    /// [`Preconditioner::SymmetricGaussSeidel`]; `None` (the default) when the operator is
    /// only available matrix-free.
    fn matrix(&self) -> Option<SparseRows> {
        None
    }
}

/// Preconditioner of [`conjugate_gradient`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Preconditioner {
    /// Plain conjugate gradients.
    Identity,
    /// Diagonal scaling by `1 / A_ii` (entries with `A_ii ≤ 0` are left unscaled).
    #[default]
    Jacobi,
    /// Symmetric Gauss–Seidel inside fixed blocks of rows ([`SymmetricGaussSeidel`]): fewer
    /// iterations than Jacobi, about twice the work per iteration; needs
    /// [`SymmetricOperator::matrix`] (falls back to Jacobi when the operator has none).
    SymmetricGaussSeidel,
    /// Jacobi plus a coarse correction on aggregates of the matrix graph ([`TwoLevel`]): far
    /// fewer iterations on Poisson problems; needs [`SymmetricOperator::matrix`] (falls back to
    /// Jacobi when the operator has none).
    TwoLevel,
}

/// Parameters of [`conjugate_gradient`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CgParams {
    /// Stop when `‖b − A x‖ ≤ relative_tolerance · ‖b‖`.
    pub relative_tolerance: f64,
    /// … or when `‖b − A x‖ ≤ absolute_tolerance`.
    pub absolute_tolerance: f64,
    /// Give up (with [`CgError::NotConverged`]) after this many iterations.
    pub max_iterations: usize,
    /// The preconditioner.
    pub preconditioner: Preconditioner,
}

impl Default for CgParams {
    /// Relative residual 1e-8, no absolute floor, at most 10,000 iterations, Jacobi.
    fn default() -> Self {
        CgParams {
            relative_tolerance: 1e-8,
            absolute_tolerance: 0.0,
            max_iterations: 10_000,
            preconditioner: Preconditioner::Jacobi,
        }
    }
}

/// What a successful solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CgInfo {
    /// Iterations performed (operator applications after the initial residual).
    pub iterations: usize,
    /// `‖b − A x‖ / ‖b‖` at exit, from the recurrence residual (0 when `b = 0`).
    pub relative_residual: f64,
    /// `‖b‖`.
    pub rhs_norm: f64,
}

/// Why [`conjugate_gradient`] failed.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum CgError {
    /// `b`, `x` or the operator disagree in length.
    #[error("operator of dimension {dim} but {array} has length {len}")]
    LengthMismatch {
        /// Dimension of the operator.
        dim: usize,
        /// Which vector.
        array: &'static str,
        /// Its length.
        len: usize,
    },
    /// `b` or the initial guess holds a NaN or infinity.
    #[error("{array} holds a non-finite value at {index}")]
    NonFiniteInput {
        /// Which vector.
        array: &'static str,
        /// First bad index.
        index: usize,
    },
    /// A parameter is out of range.
    #[error(transparent)]
    InvalidParameter(#[from] ParameterError),
    /// `pᵀ A p ≤ 0` for a search direction: the operator is not positive definite (or the
    /// system is singular and the right-hand side not in its range).
    #[error("operator not positive definite: pᵀAp = {curvature} at iteration {iteration}")]
    NotPositiveDefinite {
        /// Iteration at which it was found.
        iteration: usize,
        /// The offending `pᵀ A p`.
        curvature: f64,
    },
    /// A NaN or infinity appeared during the iteration.
    #[error("non-finite value at iteration {iteration}")]
    Breakdown {
        /// Iteration at which it appeared.
        iteration: usize,
    },
    /// The tolerance was not reached within `max_iterations`; `x` holds the last iterate.
    #[error(
        "no convergence after {} iterations (relative residual {})",
        info.iterations,
        info.relative_residual
    )]
    NotConverged {
        /// State at exit.
        info: CgInfo,
    },
}

/// Work vectors of [`conjugate_gradient`], reusable across solves of any size.
#[derive(Clone, Debug, Default)]
pub struct CgScratch {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
    inv_diag: Vec<f64>,
}

impl CgScratch {
    /// Empty scratch; grows on first use.
    pub fn new() -> CgScratch {
        CgScratch::default()
    }
}

/// `Σ a_k b_k` reduced over fixed chunks, then in chunk order.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let partial: Vec<f64> = a
        .par_chunks(DOT_CHUNK)
        .zip(b.par_chunks(DOT_CHUNK))
        .map(|(x, y)| {
            let mut acc = [0.0f64; 4];
            let mut cx = x.chunks_exact(4);
            let mut cy = y.chunks_exact(4);
            for (p, q) in (&mut cx).zip(&mut cy) {
                for l in 0..4 {
                    acc[l] += p[l] * q[l];
                }
            }
            for (p, q) in cx.remainder().iter().zip(cy.remainder()) {
                acc[0] += p * q;
            }
            (acc[0] + acc[1]) + (acc[2] + acc[3])
        })
        .collect();
    partial.iter().sum()
}

/// Solves `A x = b` by (preconditioned) conjugate gradients, starting from the `x` given.
///
/// On success `x` holds the solution and [`CgInfo`] the iteration count and residual; on
/// [`CgError::NotConverged`] `x` holds the last iterate. The result is bit-identical for any
/// thread count when `A`'s apply is.
///
/// `Lap = M⁻¹ L_W` with `L_W = W − diag(W·1)` symmetric negative semi-definite (thesis §4), so
/// implicit smoothing `(M − t L_W) u = M u₀` and Poisson problems `−L_W u = −M f` with fixed
/// values are symmetric positive definite: conjugate gradients apply. The solver follows the
/// faer conventions: a [`CgParams`] with `Default`, a [`CgInfo`] on success, a typed
/// [`CgError`], and caller-provided scratch ([`CgScratch`]) so that repeated solves allocate
/// nothing.
///
/// Reproducibility: every dot product is reduced over fixed chunks of 8,192 entries
/// whose partial sums are then added in order, and the operator applies are row-parallel with
/// a fixed order inside each row, so iterates are bit-identical for any thread count.
pub fn conjugate_gradient<A: SymmetricOperator + ?Sized>(
    op: &A,
    b: &[f64],
    x: &mut [f64],
    params: &CgParams,
    scratch: &mut CgScratch,
) -> Result<CgInfo, CgError> {
    let n = op.dim();
    for (array, len) in [("b", b.len()), ("x", x.len())] {
        if len != n {
            return Err(CgError::LengthMismatch { dim: n, array, len });
        }
    }
    if !(params.relative_tolerance >= 0.0 && params.relative_tolerance.is_finite()) {
        return Err(CgError::InvalidParameter(ParameterError {
            name: "relative_tolerance",
            value: params.relative_tolerance,
            expected: "finite and >= 0",
        }));
    }
    if !(params.absolute_tolerance >= 0.0 && params.absolute_tolerance.is_finite()) {
        return Err(CgError::InvalidParameter(ParameterError {
            name: "absolute_tolerance",
            value: params.absolute_tolerance,
            expected: "finite and >= 0",
        }));
    }
    for (array, v) in [("b", b), ("x", &*x)] {
        if let Some(index) = v.iter().position(|e| !e.is_finite()) {
            return Err(CgError::NonFiniteInput { array, index });
        }
    }

    let CgScratch {
        r,
        z,
        p,
        q,
        inv_diag,
    } = scratch;
    for v in [&mut *r, &mut *z, &mut *p, &mut *q, &mut *inv_diag] {
        v.clear();
        v.resize(n, 0.0);
    }
    let gauss_seidel = match params.preconditioner {
        Preconditioner::SymmetricGaussSeidel => op.matrix().map(|m| SymmetricGaussSeidel::new(&m)),
        _ => None,
    };
    let two_level = match params.preconditioner {
        Preconditioner::TwoLevel => op.matrix().map(|m| TwoLevel::new(&m)),
        _ => None,
    };
    match params.preconditioner {
        Preconditioner::Identity => inv_diag.fill(1.0),
        Preconditioner::Jacobi
        | Preconditioner::SymmetricGaussSeidel
        | Preconditioner::TwoLevel => {
            op.diagonal(inv_diag);
            inv_diag.par_iter_mut().for_each(|d| {
                *d = if *d > 0.0 && d.is_finite() {
                    1.0 / *d
                } else {
                    1.0
                }
            });
        }
    }

    let rhs_norm = dot(b, b).sqrt();
    // r = b − A x
    op.apply(x, q);
    r.par_iter_mut()
        .zip(b.par_iter().zip(q.par_iter()))
        .for_each(|(ri, (bi, qi))| *ri = bi - qi);
    let threshold = (params.relative_tolerance * rhs_norm).max(params.absolute_tolerance);
    let relative = |res: f64| if rhs_norm > 0.0 { res / rhs_norm } else { 0.0 };

    let mut res_norm = dot(r, r).sqrt();
    if res_norm <= threshold || res_norm == 0.0 {
        return Ok(CgInfo {
            iterations: 0,
            relative_residual: relative(res_norm),
            rhs_norm,
        });
    }
    precondition(gauss_seidel.as_ref(), two_level.as_ref(), inv_diag, r, z);
    p.copy_from_slice(z);
    let mut rz = dot(r, z);

    for iteration in 1..=params.max_iterations {
        op.apply(p, q);
        let curvature = dot(p, q);
        if !curvature.is_finite() {
            return Err(CgError::Breakdown { iteration });
        }
        if curvature <= 0.0 {
            return Err(CgError::NotPositiveDefinite {
                iteration,
                curvature,
            });
        }
        let alpha = rz / curvature;
        x.par_iter_mut()
            .zip(p.par_iter())
            .for_each(|(xi, pi)| *xi += alpha * pi);
        r.par_iter_mut()
            .zip(q.par_iter())
            .for_each(|(ri, qi)| *ri -= alpha * qi);
        res_norm = dot(r, r).sqrt();
        if !res_norm.is_finite() {
            return Err(CgError::Breakdown { iteration });
        }
        if res_norm <= threshold {
            return Ok(CgInfo {
                iterations: iteration,
                relative_residual: relative(res_norm),
                rhs_norm,
            });
        }
        precondition(gauss_seidel.as_ref(), two_level.as_ref(), inv_diag, r, z);
        let rz_next = dot(r, z);
        let beta = rz_next / rz;
        rz = rz_next;
        p.par_iter_mut()
            .zip(z.par_iter())
            .for_each(|(pi, zi)| *pi = zi + beta * *pi);
    }
    Err(CgError::NotConverged {
        info: CgInfo {
            iterations: params.max_iterations,
            relative_residual: relative(res_norm),
            rhs_norm,
        },
    })
}

fn precondition(
    gauss_seidel: Option<&SymmetricGaussSeidel>,
    two_level: Option<&TwoLevel>,
    inv_diag: &[f64],
    r: &[f64],
    z: &mut [f64],
) {
    if let Some(m) = gauss_seidel {
        m.apply(r, z);
        return;
    }
    if let Some(m) = two_level {
        m.apply(r, z);
        return;
    }
    z.par_iter_mut()
        .zip(r.par_iter().zip(inv_diag.par_iter()))
        .for_each(|(zi, (ri, di))| *zi = ri * di);
}
