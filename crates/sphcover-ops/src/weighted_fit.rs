//! φ-weighted least squares at one support, solved by a column-pivoted Householder QR of the
//! row- and column-scaled design matrix (never by normal equations).
//!
//! The normal matrix `BᵀΦB` squares the condition number of the fit: on nearly nested or
//! nearly coplanar neighbourhoods (condition 1e5 and more) its solution loses ten digits, which
//! is what broke linear exactness to 1e-7 on degenerate covers. Here the design matrix
//! `√Φ B C⁻¹` (rows weighted by `√φ_k`, columns scaled to unit norm by `C`) is reduced by
//! Householder reflections with its rows sorted by decreasing norm and its columns pivoted:
//! the ordering under which Householder QR is row-wise backward stable (Powell & Reid; Cox &
//! Higham), so a neighbour of tiny weight (a nearly nested ball) is fitted as accurately as a
//! heavy one, and an interpolating fit reproduces every datum to rounding whatever the spread
//! of the weights. The rank is read from the pivoted diagonal; a rank-deficient fit is
//! completed to the minimum-norm solution by a second QR (complete orthogonal decomposition).

use nalgebra::{DMatrix, DVector};

/// The linear map from the data of one support's usable neighbours to the fitted coefficients,
/// with the null space that decides which functionals of the coefficients the data determine.
#[derive(Clone, Debug)]
pub(crate) struct WeightedFit {
    /// `ncols × m`: coefficients = `coefficients · data` (data in the caller's row order).
    pub coefficients: DMatrix<f64>,
    /// Orthonormal basis of the numerical null space, in column-scaled coordinates.
    null_space: Vec<DVector<f64>>,
    /// Column norms `C` (1 for an empty column).
    column_scale: Vec<f64>,
    /// Largest over smallest kept pivot of the triangular factor (1 without any): an estimate
    /// of the condition number of the scaled design.
    pub condition: f64,
}

/// In-place Householder QR with column pivoting of the `m × n` matrix `a`; returns the column
/// permutation (`perm[k]` = original column in position `k`) and the reflectors' scalars.
/// On exit the upper triangle holds `R`, the part below the diagonal the reflectors' tails
/// (with unit leading entry implied).
fn householder_qrcp(a: &mut DMatrix<f64>) -> (Vec<usize>, Vec<f64>) {
    let (m, n) = a.shape();
    let steps = m.min(n);
    let mut perm: Vec<usize> = (0..n).collect();
    let mut tau = vec![0.0; steps];
    for k in 0..steps {
        // Pivot: the remaining column of largest norm below row k (first on ties).
        let norm2 = |a: &DMatrix<f64>, c: usize| (k..m).map(|r| a[(r, c)].powi(2)).sum::<f64>();
        let mut best = k;
        let mut best_norm = norm2(a, k);
        for c in k + 1..n {
            let v = norm2(a, c);
            if v > best_norm {
                best = c;
                best_norm = v;
            }
        }
        if best != k {
            a.swap_columns(k, best);
            perm.swap(k, best);
        }
        let alpha = a[(k, k)];
        let norm = best_norm.sqrt();
        if norm == 0.0 {
            continue;
        }
        let beta = if alpha >= 0.0 { -norm } else { norm };
        let v0 = alpha - beta;
        for r in k + 1..m {
            a[(r, k)] /= v0;
        }
        tau[k] = (beta - alpha) / beta;
        a[(k, k)] = beta;
        for c in k + 1..n {
            let mut dot = a[(k, c)];
            for r in k + 1..m {
                dot += a[(r, k)] * a[(r, c)];
            }
            let f = tau[k] * dot;
            a[(k, c)] -= f;
            for r in k + 1..m {
                let vr = a[(r, k)];
                a[(r, c)] -= f * vr;
            }
        }
    }
    (perm, tau)
}

impl WeightedFit {
    /// Fits `rows[k] · y ≈ data[k]` with weights `weights[k] > 0`; pivots `|R_kk|` below
    /// `rank_tolerance × |R_00|` count as zero (minimum-norm solution in scaled coordinates).
    pub fn new(rows: &DMatrix<f64>, weights: &[f64], rank_tolerance: f64) -> WeightedFit {
        let (m, ncols) = rows.shape();
        let unit = |len: usize, c: usize| DVector::from_fn(len, |r, _| f64::from(u8::from(r == c)));
        let empty = WeightedFit {
            coefficients: DMatrix::zeros(ncols, m),
            null_space: (0..ncols).map(|c| unit(ncols, c)).collect(),
            column_scale: vec![1.0; ncols],
            condition: 1.0,
        };
        if m == 0 {
            return empty;
        }
        let sqrt_w: Vec<f64> = weights.iter().map(|w| w.sqrt()).collect();
        let column_scale: Vec<f64> = (0..ncols)
            .map(|c| {
                let norm = (0..m)
                    .map(|k| (sqrt_w[k] * rows[(k, c)]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                if norm > 0.0 && norm.is_finite() {
                    norm
                } else {
                    1.0
                }
            })
            .collect();
        let scaled_row = |k: usize, c: usize| sqrt_w[k] * rows[(k, c)] / column_scale[c];
        // Rows by decreasing norm, ties by index (deterministic).
        let row_norm: Vec<f64> = (0..m)
            .map(|k| (0..ncols).map(|c| scaled_row(k, c).powi(2)).sum::<f64>())
            .collect();
        let mut order: Vec<usize> = (0..m).collect();
        order.sort_by(|&a, &b| row_norm[b].total_cmp(&row_norm[a]).then(a.cmp(&b)));
        let mut qr = DMatrix::from_fn(m, ncols, |r, c| scaled_row(order[r], c));
        if !qr.iter().all(|v| v.is_finite()) {
            return empty;
        }
        let (perm, tau) = householder_qrcp(&mut qr);
        let steps = m.min(ncols);
        let largest = if steps > 0 { qr[(0, 0)].abs() } else { 0.0 };
        if largest.is_nan() || largest <= 0.0 {
            return empty;
        }
        let rank = (0..steps)
            .take_while(|&k| qr[(k, k)].abs() > rank_tolerance * largest)
            .count();
        let condition = largest / qr[(rank - 1, rank - 1)].abs();

        // Qᵀ applied to the unit data vectors, first `rank` rows: qt[(s, r)] = (Qᵀ e_r)_s.
        let mut qt = DMatrix::<f64>::zeros(rank, m);
        for r in 0..m {
            let mut e = vec![0.0; m];
            e[r] = 1.0;
            for k in 0..steps {
                if tau[k] == 0.0 {
                    continue;
                }
                let mut dot = e[k];
                for t in k + 1..m {
                    dot += qr[(t, k)] * e[t];
                }
                let f = tau[k] * dot;
                e[k] -= f;
                for t in k + 1..m {
                    e[t] -= f * qr[(t, k)];
                }
            }
            for s in 0..rank {
                qt[(s, r)] = e[s];
            }
        }
        // T = [R11 R12] (rank × ncols, pivoted columns); solutions z of T z = Qᵀb.
        let t = DMatrix::from_fn(rank, ncols, |r, c| if c >= r { qr[(r, c)] } else { 0.0 });
        let trailing_zero = (0..rank).all(|r| (rank..ncols).all(|c| t[(r, c)] == 0.0));
        // solution (pivoted scaled coordinates) of every unit datum: ncols × m.
        let mut solution = DMatrix::<f64>::zeros(ncols, m);
        let mut null_pivoted: Vec<DVector<f64>> = Vec::new();
        if rank == ncols || trailing_zero {
            // Back substitution with R11 (accurate for graded triangles); the trailing
            // coordinates are exactly undetermined and set to zero, which is minimum-norm.
            for r in 0..m {
                for s in (0..rank).rev() {
                    let mut acc = qt[(s, r)];
                    for c in s + 1..rank {
                        acc -= t[(s, c)] * solution[(c, r)];
                    }
                    solution[(s, r)] = acc / t[(s, s)];
                }
            }
            null_pivoted.extend((rank..ncols).map(|c| unit(ncols, c)));
        } else {
            // Complete orthogonal decomposition: Tᵀ = Z S, z = Z S⁻ᵀ (Qᵀ b).
            let qr_t = t.transpose().qr();
            let z = qr_t.q();
            let s_factor = qr_t.r();
            for r in 0..m {
                let mut w = vec![0.0; rank];
                for s in 0..rank {
                    let mut acc = qt[(s, r)];
                    for c in 0..s {
                        acc -= s_factor[(c, s)] * w[c];
                    }
                    w[s] = acc / s_factor[(s, s)];
                }
                for c in 0..ncols {
                    solution[(c, r)] = (0..rank).map(|s| z[(c, s)] * w[s]).sum();
                }
            }
            for c in 0..ncols {
                let mut e = unit(ncols, c);
                for _ in 0..2 {
                    for q in (0..rank)
                        .map(|s| z.column(s).into_owned())
                        .chain(null_pivoted.iter().cloned())
                        .collect::<Vec<_>>()
                    {
                        let p = q.dot(&e);
                        e -= q * p;
                    }
                }
                let norm = e.norm();
                if norm > 1e-6 && null_pivoted.len() + rank < ncols {
                    null_pivoted.push(e / norm);
                }
            }
        }
        // Undo the pivoting, the column scaling and the row order; fold in √w.
        let mut coefficients = DMatrix::zeros(ncols, m);
        for r in 0..m {
            let k = order[r];
            for p in 0..ncols {
                let c = perm[p];
                coefficients[(c, k)] = solution[(p, r)] * sqrt_w[k] / column_scale[c];
            }
        }
        let null_space = null_pivoted
            .iter()
            .map(|v| {
                let mut out = DVector::zeros(ncols);
                for p in 0..ncols {
                    out[perm[p]] = v[p];
                }
                out
            })
            .collect();
        WeightedFit {
            coefficients,
            null_space,
            column_scale,
            condition,
        }
    }

    /// Whether the data determine the functional `f · y` of the coefficients: its component in
    /// the null space is below `tolerance ×` its norm (both in scaled coordinates).
    pub fn determines(&self, f: &[f64], tolerance: f64) -> bool {
        let scaled = DVector::from_fn(f.len(), |r, _| f[r] / self.column_scale[r]);
        let leak: f64 = self
            .null_space
            .iter()
            .map(|v| v.dot(&scaled).powi(2))
            .sum::<f64>()
            .sqrt();
        leak <= tolerance * scaled.norm()
    }

    /// Number of null directions (0 when every coefficient is determined).
    pub fn nullity(&self) -> usize {
        self.null_space.len()
    }
}
