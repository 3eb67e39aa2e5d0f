//! Implicit (backward Euler) smoothing by the symmetric Laplacian: `(M − t L_W) u = M u₀`.
//!
//! The method is described on [`implicit_smoothing()`].

use rayon::prelude::*;
use sphcover_core::{LengthMismatch, ParameterError};

use crate::conjugate_gradient::{
    CgInfo, CgParams, CgScratch, SymmetricOperator, conjugate_gradient,
};
use crate::error::{OpsError, SolveError};
use crate::gauss_seidel::SparseRows;
use crate::pair_geometry::{MassKind, PairGeometry, ROWS_PER_TASK};

/// The operator `x ↦ M x − t L_W x`, with identity rows for supports of zero mass.
#[derive(Clone, Copy, Debug)]
pub struct ShiftedStiffness<'a> {
    geometry: &'a PairGeometry,
    mass: &'a [f64],
    time: f64,
}

impl<'a> ShiftedStiffness<'a> {
    /// `M − t L_W` on `geometry` with the given mass; `t` must be finite and non-negative.
    pub fn new(
        geometry: &'a PairGeometry,
        mass: MassKind,
        time: f64,
    ) -> Result<ShiftedStiffness<'a>, OpsError> {
        if !(time >= 0.0 && time.is_finite()) {
            return Err(OpsError::InvalidParameter(ParameterError {
                name: "time",
                value: time,
                expected: "finite and >= 0",
            }));
        }
        Ok(ShiftedStiffness {
            geometry,
            mass: geometry.mass(mass),
            time,
        })
    }
}

impl SymmetricOperator for ShiftedStiffness<'_> {
    fn dim(&self) -> usize {
        self.geometry.len()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(block, out)| {
                let first = block * ROWS_PER_TASK;
                for (local, yi) in out.iter_mut().enumerate() {
                    let i = first + local;
                    let m = self.mass[i];
                    *yi = if m > 0.0 {
                        m * x[i] - self.time * self.geometry.stiffness_row(i, x)
                    } else {
                        x[i]
                    };
                }
            });
    }

    fn diagonal(&self, diag: &mut [f64]) {
        let w = self.geometry.weight_sum();
        diag.par_iter_mut().enumerate().for_each(|(i, d)| {
            let m = self.mass[i];
            *d = if m > 0.0 { m + self.time * w[i] } else { 1.0 };
        });
    }

    fn matrix(&self) -> Option<SparseRows> {
        let g = self.geometry;
        let mut diagonal = vec![0.0; g.len()];
        self.diagonal(&mut diagonal);
        let values = g.phi().iter().map(|&phi| -self.time * phi).collect();
        Some(SparseRows {
            offsets: g.offsets().to_vec(),
            columns: g.neighbour_array().to_vec(),
            values,
            diagonal,
        })
    }
}

/// One implicit smoothing step of the scalar field `u0` (one value per support) over time
/// `t`: returns `u` with `(M − t L_W) u = M u₀`, starting CG from `u₀`.
///
/// One backward-Euler step of the heat equation `∂u/∂t = Lap u` with `Lap = M⁻¹ L_W`
/// (thesis §4, `L_W = W − diag(W·1)`). The matrix `M − t L_W` is symmetric positive definite
/// for `t ≥ 0` wherever `m_i > 0`, so conjugate gradients solve it; unconditionally stable, so
/// `t` can be as large as the smoothing wanted. A support without usable neighbours (zero
/// mass, zero row) keeps its value.
pub fn implicit_smoothing(
    geometry: &PairGeometry,
    mass: MassKind,
    time: f64,
    u0: &[f64],
    params: &CgParams,
) -> Result<(Vec<f64>, CgInfo), SolveError> {
    let op = ShiftedStiffness::new(geometry, mass, time)?;
    if u0.len() != geometry.len() {
        return Err(OpsError::LengthMismatch(LengthMismatch {
            array: "u0",
            expected: geometry.len(),
            found: u0.len(),
        })
        .into());
    }
    let m = geometry.mass(mass);
    let rhs: Vec<f64> = u0
        .par_iter()
        .zip(m.par_iter())
        .map(|(&u, &mi)| if mi > 0.0 { mi * u } else { u })
        .collect();
    let mut u = u0.to_vec();
    let info = conjugate_gradient(&op, &rhs, &mut u, params, &mut CgScratch::new())?;
    Ok((u, info))
}
