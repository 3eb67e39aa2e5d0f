//! Consistent operators from a φ-weighted second-order least-squares fit over the graph
//! neighbours.
//!
//! The method is described on [`QuadraticFitOperators`].

use glam::DVec3;
use nalgebra::{DMatrix, SVector};
use rayon::prelude::*;

use crate::discrete_operators::DiscreteOperators;
use crate::least_squares_gradient::{gradient_row, refine_linear_exactness};
use crate::pair_geometry::{MassKind, PairGeometry, ROWS_PER_TASK};
use crate::weighted_fit::WeightedFit;

type Vec9 = SVector<f64, 9>;

/// Singular values of the weighted, column-scaled design matrix below this fraction of the
/// largest are treated as zero (1e-10 on the normal matrix's eigenvalues).
const RANK_TOLERANCE: f64 = 1e-5;
/// A functional counts as determined when its component in the null space is below this
/// fraction of its norm.
const DETERMINED_TOLERANCE: f64 = 1e-9;

/// How the rows of a [`QuadraticFitOperators`] were built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QuadraticFitStats {
    /// Supports whose Laplacian comes from the quadratic fit (exact on quadratics).
    pub quadratic_rows: usize,
    /// Supports whose Laplacian fell back to the linear-exact form.
    pub fallback_rows: usize,
    /// Supports whose gradient fell back to the linear least-squares one.
    pub gradient_fallback_rows: usize,
    /// Supports without usable neighbours (zero operators).
    pub isolated_rows: usize,
}

/// The consistent operator family from second-order least squares.
///
/// At support `i`, with offsets `d_j = c_j − c_i` scaled by `h = r_i` for conditioning, fit
///
/// ```text
/// u_j − u_i ≈ g·d_j + ½ d_jᵀ H d_j        (9 unknowns: g, and H symmetric)
/// ```
///
/// by least squares with weights `φ_ij`, interpolating `u_i` (so constants give exactly zero).
/// `Lap(u)_i = tr H`, `Grad(u)_i = g`, `Div(v)_i = Σ_j Grad_j · (v_j − v_i)` and
/// `Curl(v)_i = Σ_j Grad_j × (v_j − v_i)` with the per-neighbour gradient weights `Grad_j`.
/// All four are linear in the differences, so they are stored as per-entry coefficients
/// (one `f64` and one `DVec3` per stored neighbour) and applied like a sparse matrix.
///
/// Exactness. The fit is solved by a singular-value decomposition of the weighted,
/// column-scaled design matrix (not its normal matrix, whose condition number is the square).
/// The Laplacian is exact on every quadratic exactly when the functional `tr H` is determined
/// by the data (orthogonal to the numerical null space of the design): this holds with 9 or more
/// neighbours in general position, and also on symmetric stencils with fewer (six axis
/// neighbours determine `tr H` though not the mixed terms). Where it does not hold, the row
/// *falls back* to the linear-exact form
///
/// ```text
/// Lap(u)_i = (1/m_i) Σ_j φ_ij (u_j − u_i − Grad(u)_i · d_j),   m_i = (1/6) Σ_j φ_ij ‖d_j‖²
/// ```
///
/// with the least-squares gradient: exact on linear fields and on `|x|²`, not on every
/// quadratic. The gradient is exact on quadratics wherever it is determined, and otherwise is
/// the linear least-squares one.
///
/// Linear exactness by construction. Whatever the conditioning of the fit, the Laplacian
/// coefficients are finally projected, `L_k ← L_k − (Σ_l L_l d_l)·G_k` (twice) with the linear
/// least-squares gradient weights `G_k` (`Σ_k G_k d_kᵀ = I` to rounding), so `Σ_k L_k d_k`
/// vanishes to the rounding of that sum and `Lap` of a linear field is rounding on any cover;
/// the gradient weights are refined by `G ← (2I − Σ_k G_k d_kᵀ) G`, a left multiplication
/// that keeps their quadratic moments zero. [`QuadraticFitStats`] counts the fallbacks.
///
/// Trade-offs (measured by the `consistency` example): exact on quadratics and convergent on
/// irregular covers, where the thesis form is not, but `Lap` is no longer symmetric nor
/// guaranteed negative semi-definite, so it cannot go into conjugate gradients; use it to
/// evaluate, and the symmetric [`crate::PairGeometry`] Laplacian to solve.
#[derive(Clone, Debug)]
pub struct QuadraticFitOperators {
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    lap_coeff: Vec<f64>,
    grad_coeff: Vec<DVec3>,
    row_kinds: Vec<RowKind>,
    stats: QuadraticFitStats,
}

/// The monomial basis `[x, y, z, x²/2, y²/2, z²/2, xy, xz, yz]` at `d`.
#[inline]
fn basis(d: DVec3) -> Vec9 {
    Vec9::from([
        d.x,
        d.y,
        d.z,
        0.5 * d.x * d.x,
        0.5 * d.y * d.y,
        0.5 * d.z * d.z,
        d.x * d.y,
        d.x * d.z,
        d.y * d.z,
    ])
}

/// How one row of a [`QuadraticFitOperators`] was built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RowKind {
    /// From the quadratic fit: `Lap` exact on every quadratic.
    Quadratic,
    /// The linear-exact fallback (the neighbourhood does not determine `tr H`).
    Fallback,
    /// No usable neighbour: zero operators.
    Isolated,
}

impl QuadraticFitOperators {
    /// Fits every support's neighbourhood, in parallel (deterministic for any thread count).
    pub fn new(geometry: &PairGeometry) -> QuadraticFitOperators {
        let n = geometry.len();
        let offsets = geometry.offsets();
        let mut lap_coeff = vec![0.0; geometry.stored_entries()];
        let mut grad_coeff = vec![DVec3::ZERO; geometry.stored_entries()];
        let mut tasks = Vec::new();
        {
            let (mut lap_rest, mut grad_rest) = (&mut lap_coeff[..], &mut grad_coeff[..]);
            let mut row = 0;
            while row < n {
                let end = (row + ROWS_PER_TASK).min(n);
                let len = (offsets[end] - offsets[row]) as usize;
                let (lap_here, lap_next) = lap_rest.split_at_mut(len);
                let (grad_here, grad_next) = grad_rest.split_at_mut(len);
                tasks.push((row..end, lap_here, grad_here));
                lap_rest = lap_next;
                grad_rest = grad_next;
                row = end;
            }
        }
        let per_task: Vec<(QuadraticFitStats, Vec<RowKind>)> = tasks
            .into_par_iter()
            .map(|(rows, lap_out, grad_out)| {
                let base = offsets[rows.start] as usize;
                let mut stats = QuadraticFitStats::default();
                let mut kinds = Vec::with_capacity(rows.len());
                for i in rows {
                    let range = offsets[i] as usize - base..offsets[i + 1] as usize - base;
                    let (kind, grad_fallback) = fit_row(
                        geometry,
                        i,
                        &mut lap_out[range.clone()],
                        &mut grad_out[range],
                    );
                    match kind {
                        RowKind::Quadratic => stats.quadratic_rows += 1,
                        RowKind::Fallback => stats.fallback_rows += 1,
                        RowKind::Isolated => stats.isolated_rows += 1,
                    }
                    stats.gradient_fallback_rows += usize::from(grad_fallback);
                    kinds.push(kind);
                }
                (stats, kinds)
            })
            .collect();
        let mut stats = QuadraticFitStats::default();
        let mut row_kinds = Vec::with_capacity(n);
        for (s, kinds) in per_task {
            stats.quadratic_rows += s.quadratic_rows;
            stats.fallback_rows += s.fallback_rows;
            stats.gradient_fallback_rows += s.gradient_fallback_rows;
            stats.isolated_rows += s.isolated_rows;
            row_kinds.extend(kinds);
        }
        QuadraticFitOperators {
            offsets: offsets.to_vec(),
            neighbours: geometry.neighbour_array().to_vec(),
            lap_coeff,
            grad_coeff,
            row_kinds,
            stats,
        }
    }

    /// How row `i` was built (panics when out of range).
    pub fn row_kind(&self, i: usize) -> RowKind {
        self.row_kinds[i]
    }

    /// How many rows are quadratic-exact, fell back, or are isolated.
    pub fn stats(&self) -> QuadraticFitStats {
        self.stats
    }

    /// Laplacian coefficient of every stored entry: `Lap(u)_i = Σ_j L_ij (u_j − u_i)`.
    pub fn lap_coefficients(&self) -> &[f64] {
        &self.lap_coeff
    }

    /// The rows' start offsets and the neighbour of every stored entry (the graph's).
    pub(crate) fn structure(&self) -> (&[u32], &[u32]) {
        (&self.offsets, &self.neighbours)
    }

    /// Gradient coefficient of every stored entry: `Grad(u)_i = Σ_j G_ij (u_j − u_i)`.
    pub fn grad_coefficients(&self) -> &[DVec3] {
        &self.grad_coeff
    }

    fn rows<T: Send>(&self, row: impl Fn(usize, std::ops::Range<usize>) -> T + Sync) -> Vec<T> {
        (0..self.offsets.len() - 1)
            .into_par_iter()
            .map(|i| row(i, self.offsets[i] as usize..self.offsets[i + 1] as usize))
            .collect()
    }
}

/// Builds the coefficients of row `i`; returns the row kind and whether the gradient fell
/// back.
fn fit_row(
    geometry: &PairGeometry,
    i: usize,
    lap_out: &mut [f64],
    grad_out: &mut [DVec3],
) -> (RowKind, bool) {
    let c = geometry.centres();
    let phi = geometry.phi_row(i);
    let nb = geometry.neighbours(i);
    let mass = geometry.mass(MassKind::MomentMatched)[i];
    if mass <= 0.0 {
        return (RowKind::Isolated, false);
    }
    let offset = |k: usize| c[nb[k] as usize] - c[i];
    let usable: Vec<usize> = (0..nb.len()).filter(|&k| phi[k] > 0.0).collect();
    let h = geometry.radii()[i].max(f64::MIN_POSITIVE);
    let rows = DMatrix::from_fn(usable.len(), 9, |r, col| basis(offset(usable[r]) / h)[col]);
    let weights: Vec<f64> = usable.iter().map(|&k| phi[k]).collect();
    let fit = WeightedFit::new(&rows, &weights, RANK_TOLERANCE);
    let e_lap = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
    let lap_determined = fit.determines(&e_lap, DETERMINED_TOLERANCE);
    let grad_determined = (0..3).all(|a| {
        let mut e = [0.0; 9];
        e[a] = 1.0;
        fit.determines(&e, DETERMINED_TOLERANCE)
    });

    // Linear least-squares gradient weights: the fallbacks, and the projection that makes
    // the Laplacian annihilate linear fields to rounding.
    let mut linear = vec![DVec3::ZERO; nb.len()];
    gradient_row(geometry, i, &mut linear);
    if grad_determined {
        for (r, &k) in usable.iter().enumerate() {
            let w = fit.coefficients.column(r);
            grad_out[k] = DVec3::new(w[0], w[1], w[2]) / h;
        }
        // Left multiplication: keeps Σ_k G_k q(d_k) = 0 on the quadratic monomials.
        refine_linear_exactness(grad_out, offset, &usable);
    } else {
        grad_out.copy_from_slice(&linear);
    }
    let kind = if lap_determined {
        for (r, &k) in usable.iter().enumerate() {
            let w = fit.coefficients.column(r);
            lap_out[k] = (w[3] + w[4] + w[5]) / (h * h);
        }
        RowKind::Quadratic
    } else {
        // Linear-exact fallback: (1/m) Σ_j (φ_j − s·G_j)(u_j − u_i), s = Σ_k φ_k d_k, which
        // is the projection below applied to φ/m.
        for &k in &usable {
            lap_out[k] = phi[k] / mass;
        }
        RowKind::Fallback
    };
    // Project out the linear part: L_k ← L_k − (Σ_l L_l d_l)·G_k with the linear weights G
    // (Σ_k G_k d_kᵀ = I to rounding), twice, so that Σ_k L_k d_k vanishes to the rounding of
    // the sum itself however badly conditioned the fit. Where the offsets do not span ℝ³,
    // G_k reproduces the span and Σ_k L_k d_k lies in it.
    for _ in 0..2 {
        let mut s = DVec3::ZERO;
        for &k in &usable {
            s += lap_out[k] * offset(k);
        }
        for &k in &usable {
            lap_out[k] -= s.dot(linear[k]);
        }
    }
    (kind, !grad_determined)
}

impl DiscreteOperators for QuadraticFitOperators {
    fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    fn grad(&self, u: &[f64]) -> Vec<DVec3> {
        assert_eq!(u.len(), self.len(), "u has the wrong length");
        self.rows(|i, range| {
            let mut acc = DVec3::ZERO;
            for k in range {
                acc += self.grad_coeff[k] * (u[self.neighbours[k] as usize] - u[i]);
            }
            acc
        })
    }

    fn div(&self, v: &[DVec3]) -> Vec<f64> {
        assert_eq!(v.len(), self.len(), "v has the wrong length");
        self.rows(|i, range| {
            let mut acc = 0.0;
            for k in range {
                acc += self.grad_coeff[k].dot(v[self.neighbours[k] as usize] - v[i]);
            }
            acc
        })
    }

    fn lap(&self, u: &[f64]) -> Vec<f64> {
        assert_eq!(u.len(), self.len(), "u has the wrong length");
        self.rows(|i, range| {
            let mut acc = 0.0;
            for k in range {
                acc += self.lap_coeff[k] * (u[self.neighbours[k] as usize] - u[i]);
            }
            acc
        })
    }

    fn curl(&self, v: &[DVec3]) -> Vec<DVec3> {
        assert_eq!(v.len(), self.len(), "v has the wrong length");
        self.rows(|i, range| {
            let mut acc = DVec3::ZERO;
            for k in range {
                acc += self.grad_coeff[k].cross(v[self.neighbours[k] as usize] - v[i]);
            }
            acc
        })
    }
}
