//! The Poisson problem `Lap u = f` with `Lap = M⁻¹ L_W`, fixed by an anchor or by Dirichlet
//! values.
//!
//! The method is described on [`solve_poisson()`].

use rayon::prelude::*;
use sphcover_core::LengthMismatch;

use crate::conjugate_gradient::{
    CgInfo, CgParams, CgScratch, SymmetricOperator, conjugate_gradient,
};
use crate::error::{OpsError, SolveError};
use crate::gauss_seidel::SparseRows;
use crate::pair_geometry::{MassKind, PairGeometry, ROWS_PER_TASK};

/// How the solution of [`solve_poisson`] is pinned down.
#[derive(Clone, Debug, PartialEq)]
pub enum PoissonBoundary {
    /// One support takes a given value; the graph of usable pairs must be connected.
    Anchor {
        /// The support.
        support: u32,
        /// Its value.
        value: f64,
    },
    /// Every listed support takes its value (later entries win on repeats).
    Dirichlet(Vec<(u32, f64)>),
}

/// `−L_W` restricted to the free supports, with identity rows at fixed ones.
#[derive(Clone, Debug)]
struct FreeStiffness<'a> {
    geometry: &'a PairGeometry,
    fixed: &'a [bool],
}

impl SymmetricOperator for FreeStiffness<'_> {
    fn dim(&self) -> usize {
        self.geometry.len()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let g = self.geometry;
        y.par_chunks_mut(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(block, out)| {
                let first = block * ROWS_PER_TASK;
                for (local, yi) in out.iter_mut().enumerate() {
                    let i = first + local;
                    if self.fixed[i] {
                        *yi = x[i];
                        continue;
                    }
                    let mut acc = 0.0;
                    for (&j, &phi) in g.neighbours(i).iter().zip(g.phi_row(i)) {
                        let xj = if self.fixed[j as usize] {
                            0.0
                        } else {
                            x[j as usize]
                        };
                        acc += phi * (x[i] - xj);
                    }
                    *yi = acc;
                }
            });
    }

    fn diagonal(&self, diag: &mut [f64]) {
        let w = self.geometry.weight_sum();
        diag.par_iter_mut().enumerate().for_each(|(i, d)| {
            *d = if self.fixed[i] { 1.0 } else { w[i] };
        });
    }

    fn matrix(&self) -> Option<SparseRows> {
        let g = self.geometry;
        let mut diagonal = vec![0.0; g.len()];
        self.diagonal(&mut diagonal);
        let nb = g.neighbour_array();
        let values = (0..g.len())
            .flat_map(|i| {
                (g.offsets()[i] as usize..g.offsets()[i + 1] as usize).map(move |k| {
                    if self.fixed[i] || self.fixed[nb[k] as usize] {
                        0.0
                    } else {
                        -g.phi()[k]
                    }
                })
            })
            .collect();
        Some(SparseRows {
            offsets: g.offsets().to_vec(),
            columns: nb.to_vec(),
            values,
            diagonal,
        })
    }
}

/// Solves `Lap u = f` (one value of `f` per support) with the given mass and boundary
/// condition; returns `u` and the CG report.
///
/// `L_W` is singular (constants are in its kernel on every connected component), so values
/// must be fixed somewhere. With the fixed set `F` and free set `U`, the system solved is
/// the free block of `−L_W u = −M f`, moving the known values to the right-hand side:
///
/// ```text
/// −L_W[U,U] u_U = −M_U f_U + L_W[U,F] g_F
/// ```
///
/// which is symmetric positive definite when every connected component of the usable pairs
/// (`φ > 0`) holds a fixed support; conjugate gradients solve it. A component without one is
/// an error ([`OpsError::UnconstrainedComponent`]), except a support without any usable pair,
/// which gets 0 (its Laplacian is identically zero, so no equation constrains it). At fixed
/// supports the equation `Lap u = f` is replaced by the fixed value.
pub fn solve_poisson(
    geometry: &PairGeometry,
    mass: MassKind,
    f: &[f64],
    boundary: &PoissonBoundary,
    params: &CgParams,
) -> Result<(Vec<f64>, CgInfo), SolveError> {
    let n = geometry.len();
    if f.len() != n {
        return Err(OpsError::LengthMismatch(LengthMismatch {
            array: "f",
            expected: n,
            found: f.len(),
        })
        .into());
    }
    if let Some(index) = f.iter().position(|v| !v.is_finite()) {
        return Err(OpsError::NonFiniteValue { array: "f", index }.into());
    }
    let mut fixed = vec![false; n];
    let mut values = vec![0.0; n];
    let pinned: Vec<(u32, f64)> = match boundary {
        PoissonBoundary::Anchor { support, value } => vec![(*support, *value)],
        PoissonBoundary::Dirichlet(list) => list.clone(),
    };
    for (support, value) in pinned {
        if support as usize >= n {
            return Err(OpsError::BoundarySupportOutOfRange { support, len: n }.into());
        }
        if !value.is_finite() {
            return Err(OpsError::NonFiniteValue {
                array: "boundary",
                index: support as usize,
            }
            .into());
        }
        fixed[support as usize] = true;
        values[support as usize] = value;
    }
    let w = geometry.weight_sum();
    for i in 0..n {
        if w[i] == 0.0 {
            fixed[i] = true;
        }
    }
    check_every_component_fixed(geometry, &fixed)?;

    let m = geometry.mass(mass);
    let rhs: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| {
            if fixed[i] {
                return 0.0;
            }
            let mut known = 0.0;
            for (&j, &phi) in geometry.neighbours(i).iter().zip(geometry.phi_row(i)) {
                if fixed[j as usize] {
                    known += phi * values[j as usize];
                }
            }
            known - m[i] * f[i]
        })
        .collect();
    let op = FreeStiffness {
        geometry,
        fixed: &fixed,
    };
    let mut u = vec![0.0; n];
    let info = conjugate_gradient(&op, &rhs, &mut u, params, &mut CgScratch::new())?;
    for i in 0..n {
        if fixed[i] {
            u[i] = values[i];
        }
    }
    Ok((u, info))
}

/// Fails when a connected component of the usable pairs has no fixed support.
fn check_every_component_fixed(geometry: &PairGeometry, fixed: &[bool]) -> Result<(), OpsError> {
    let n = geometry.len();
    let mut seen = vec![false; n];
    let mut stack = Vec::new();
    for start in 0..n {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut has_fixed = false;
        while let Some(i) = stack.pop() {
            has_fixed |= fixed[i];
            for (&j, &phi) in geometry.neighbours(i).iter().zip(geometry.phi_row(i)) {
                if phi > 0.0 && !seen[j as usize] {
                    seen[j as usize] = true;
                    stack.push(j as usize);
                }
            }
        }
        if !has_fixed {
            return Err(OpsError::UnconstrainedComponent { support: start });
        }
    }
    Ok(())
}
