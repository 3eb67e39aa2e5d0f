//! The operators as explicit sparse matrices, for callers that compose, factor or inspect
//! them (SciPy, a direct solver) instead of applying them.
//!
//! Every operator of [`ThesisOperators`] and [`QuadraticFitOperators`] is linear and reads
//! only a support and its neighbours in the sphere intersection graph, so each row is the
//! row's stored coefficients plus a diagonal term. Vector fields are laid out interleaved,
//! `(x₀, y₀, z₀, x₁, …)`, which is the row-major order of an `(n, 3)` array: `Grad` is
//! `3n × n`, `Div` is `n × 3n`, `Lap` is `n × n`.

use glam::DVec3;

use crate::pair_geometry::PairGeometry;
use crate::quadratic_fit_operators::QuadraticFitOperators;
use crate::thesis_operators::{FluxKind, ThesisOperators};

/// A sparse matrix in compressed sparse rows: the entries of row `r` are
/// `columns[offsets[r]..offsets[r + 1]]` with `values` alike, columns ascending, each at most
/// once. Stored zeros are kept (a row's structure is the graph's, whatever the values).
#[derive(Clone, Debug, PartialEq)]
pub struct CsrMatrix {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// Start of each row in `columns` and `values`, and the end of the last (`rows + 1`).
    pub offsets: Vec<usize>,
    /// Column of each entry.
    pub columns: Vec<u32>,
    /// Value of each entry.
    pub values: Vec<f64>,
}

impl CsrMatrix {
    /// `y = A x`.
    ///
    /// Panics when `x` does not have [`CsrMatrix::cols`] entries.
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        assert_eq!(x.len(), self.cols, "x has the wrong length");
        (0..self.rows)
            .map(|r| {
                let range = self.offsets[r]..self.offsets[r + 1];
                self.columns[range.clone()]
                    .iter()
                    .zip(&self.values[range])
                    .map(|(&c, &v)| v * x[c as usize])
                    .sum()
            })
            .collect()
    }
}

/// Builds a matrix row by row; `row` pushes `(column, value)` pairs in any order, and
/// repeated columns are summed.
fn build(rows: usize, cols: usize, mut row: impl FnMut(usize, &mut Vec<(u32, f64)>)) -> CsrMatrix {
    let mut m = CsrMatrix {
        rows,
        cols,
        offsets: Vec::with_capacity(rows + 1),
        columns: Vec::new(),
        values: Vec::new(),
    };
    m.offsets.push(0);
    let mut entries = Vec::new();
    for r in 0..rows {
        entries.clear();
        row(r, &mut entries);
        entries.sort_by_key(|e| e.0);
        for &(c, v) in &entries {
            if m.columns.len() > m.offsets[r] && *m.columns.last().unwrap_or(&u32::MAX) == c {
                *m.values.last_mut().expect("an entry was pushed") += v;
            } else {
                m.columns.push(c);
                m.values.push(v);
            }
        }
        m.offsets.push(m.columns.len());
    }
    m
}

/// `Grad`, `Div` and `Lap` of one operator family as matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct OperatorMatrices {
    /// `Grad`: `3n × n`, scalar field to interleaved vector field.
    pub grad: CsrMatrix,
    /// `Div`: `n × 3n`, interleaved vector field to scalar field.
    pub div: CsrMatrix,
    /// `Lap`: `n × n`.
    pub lap: CsrMatrix,
}

/// The matrix of `x ↦ (Σ_k c_k (x_{nb_k} − x_i))_i` for coefficients aligned with the
/// geometry's stored neighbours: `Grad` when `c` are vectors (`dims = 3` output rows per
/// support), `Lap` when they are scalars.
fn difference_rows(
    offsets: &[u32],
    neighbours: &[u32],
    n: usize,
    dims: usize,
    coefficient: impl Fn(usize, usize) -> f64,
) -> CsrMatrix {
    build(dims * n, n, |r, row| {
        let (i, a) = (r / dims, r % dims);
        let mut diagonal = 0.0;
        for k in offsets[i] as usize..offsets[i + 1] as usize {
            let c = coefficient(k, a);
            row.push((neighbours[k], c));
            diagonal -= c;
        }
        row.push((i as u32, diagonal));
    })
}

/// The matrix of `v ↦ (Σ_k c_k · (v_{nb_k} − v_i))_i` with vector coefficients.
fn divergence_of_differences(
    offsets: &[u32],
    neighbours: &[u32],
    n: usize,
    coefficient: impl Fn(usize) -> DVec3,
) -> CsrMatrix {
    build(n, 3 * n, |i, row| {
        let mut diagonal = DVec3::ZERO;
        for k in offsets[i] as usize..offsets[i + 1] as usize {
            let c = coefficient(k);
            let j = neighbours[k];
            for a in 0..3 {
                row.push((3 * j + a as u32, c[a]));
            }
            diagonal -= c;
        }
        for a in 0..3 {
            row.push((3 * i as u32 + a as u32, diagonal[a]));
        }
    })
}

impl ThesisOperators<'_> {
    /// `Grad`, `Div` and `Lap` as sparse matrices: applied to a field they give what
    /// [`crate::DiscreteOperators`] gives, to rounding (the sums run in another order).
    pub fn matrices(&self) -> OperatorMatrices {
        let g: &PairGeometry = self.geometry();
        let n = g.len();
        let offsets = g.offsets();
        let neighbours = g.neighbour_array();
        let weights = self.gradient().weights();
        let grad = difference_rows(offsets, neighbours, n, 3, |k, a| weights[k][a]);
        let mass = g.mass(self.mass_kind());
        let phi = g.phi();
        let inverse_mass = |i: usize| if mass[i] > 0.0 { 1.0 / mass[i] } else { 0.0 };
        // Zero-mass rows stay zero, as `apply_laplacian` and the flux sums make them.
        let lap = difference_rows(offsets, neighbours, n, 1, |k, _| {
            phi[k] * inverse_mass(row_of(offsets, k))
        });
        let c = g.centres();
        let flux = self.flux_kind();
        let div = build(n, 3 * n, |i, row| {
            let scale = inverse_mass(i);
            let mut own = DVec3::ZERO;
            for k in offsets[i] as usize..offsets[i + 1] as usize {
                let j = neighbours[k];
                let area_normal = phi[k] * (c[j as usize] - c[i]) * scale;
                let (to_neighbour, to_self) = match flux {
                    FluxKind::Neighbour => (area_normal, DVec3::ZERO),
                    FluxKind::Central => (0.5 * area_normal, 0.5 * area_normal),
                };
                for a in 0..3 {
                    row.push((3 * j + a as u32, to_neighbour[a]));
                }
                own += to_self;
            }
            for a in 0..3 {
                row.push((3 * i as u32 + a as u32, own[a]));
            }
        });
        OperatorMatrices { grad, div, lap }
    }
}

/// The row whose stored entries include entry `k` (offsets ascending).
fn row_of(offsets: &[u32], k: usize) -> usize {
    offsets.partition_point(|&o| o as usize <= k) - 1
}

impl QuadraticFitOperators {
    /// `Grad`, `Div` and `Lap` as sparse matrices: applied to a field they give what
    /// [`crate::DiscreteOperators`] gives, to rounding.
    pub fn matrices(&self) -> OperatorMatrices {
        let (offsets, neighbours) = self.structure();
        let n = offsets.len() - 1;
        let grad_c = self.grad_coefficients();
        let lap_c = self.lap_coefficients();
        OperatorMatrices {
            grad: difference_rows(offsets, neighbours, n, 3, |k, a| grad_c[k][a]),
            div: divergence_of_differences(offsets, neighbours, n, |k| grad_c[k]),
            lap: difference_rows(offsets, neighbours, n, 1, |k, _| lap_c[k]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DiscreteOperators, MassKind};
    use sphcover_core::SphereIntersectionGraph;
    use sphcover_core::random::XorShift64;

    fn flatten(v: &[DVec3]) -> Vec<f64> {
        v.iter().flat_map(|p| p.to_array()).collect()
    }

    fn close(a: &[f64], b: &[f64]) {
        assert_eq!(a.len(), b.len());
        let scale = b.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-11 * scale, "{x} != {y}");
        }
    }

    #[test]
    fn the_matrices_apply_as_the_operators() {
        let mut rng = XorShift64::new(7);
        let n = 300;
        let centres: Vec<DVec3> = (0..n)
            .map(|_| DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()))
            .collect();
        let radii = vec![0.2; n];
        let graph = SphereIntersectionGraph::build(&centres, &radii, 1.0).unwrap();
        let geometry = PairGeometry::build(&centres, &radii, &graph).unwrap();
        let u: Vec<f64> = centres
            .iter()
            .map(|c| (3.0 * c.x).sin() + c.y * c.z)
            .collect();
        let v: Vec<DVec3> = centres
            .iter()
            .map(|c| DVec3::new(c.y, c.z * c.x, 1.0))
            .collect();
        let check = |ops: &dyn DiscreteOperators, m: &OperatorMatrices| {
            close(&m.grad.apply(&u), &flatten(&ops.grad(&u)));
            close(&m.div.apply(&flatten(&v)), &ops.div(&v));
            close(&m.lap.apply(&u), &ops.lap(&u));
        };
        for flux in [FluxKind::Neighbour, FluxKind::Central] {
            let thesis = ThesisOperators::new(&geometry, MassKind::Thesis, flux);
            check(&thesis, &thesis.matrices());
        }
        let quadratic = QuadraticFitOperators::new(&geometry);
        check(&quadratic, &quadratic.matrices());
    }
}
