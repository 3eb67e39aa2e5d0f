//! The thesis operators at centres (thesis eq. 4.21, 4.22, 4.27, 4.29, 4.39–4.41), plus the
//! curl built the same way (the thesis left it as future work, §7.2):
//!
//! The method is described on [`ThesisOperators`].

use glam::DVec3;
use rayon::prelude::*;

use crate::discrete_operators::DiscreteOperators;
use crate::least_squares_gradient::LeastSquaresGradient;
use crate::pair_geometry::{MassKind, PairGeometry};

/// Which value of the vector field a pair's flux uses in `Div` and `Curl`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum FluxKind {
    /// `v_j`, the thesis form (eq. 4.18).
    #[default]
    Neighbour,
    /// `(v_i + v_j) / 2`.
    Central,
}

/// The thesis operator family on a [`PairGeometry`].
///
/// ```text
/// Div(v)_i  = (1/m_i) Σ_j φ_ij v_j · (c_j − c_i)        (neighbour flux, eq. 4.18)
/// Lap(u)_i  = (1/m_i) Σ_j φ_ij (u_j − u_i)
/// Curl(v)_i = (1/m_i) Σ_j φ_ij (c_j − c_i) × v_j
/// Grad(u)_i = φ-weighted least squares of u_j = u_i + Grad·(c_j − c_i)
/// ```
///
/// `φ_ij (c_j − c_i)` is the intersection disk `D_ij` times the unit direction to the
/// neighbour: a discrete Stokes/Gauss sum over the disks that bound the support. The neighbour
/// flux doubles the divergence of `v(x) = x` relative to the central flux `(v_i + v_j)/2`,
/// both satisfy `Div(Grad(u)) = Lap(u)` for linear `u`; [`FluxKind`] selects. Neither vanishes
/// on constant fields unless `Σ_j φ_ij (c_j − c_i) = 0` (overlapping caps do not close the
/// surface), which the consistency example measures.
///
/// The mass is the thesis mass or the moment-matched one ([`MassKind`]); with the latter this
/// is the "moment-matched" family of the documentation.
#[derive(Clone, Debug)]
pub struct ThesisOperators<'g> {
    geometry: &'g PairGeometry,
    mass: MassKind,
    flux: FluxKind,
    gradient: LeastSquaresGradient,
}

impl<'g> ThesisOperators<'g> {
    /// The operators with the given mass and flux; precomputes the gradient's 3×3 inverses.
    pub fn new(geometry: &'g PairGeometry, mass: MassKind, flux: FluxKind) -> ThesisOperators<'g> {
        ThesisOperators {
            geometry,
            mass,
            flux,
            gradient: LeastSquaresGradient::new(geometry),
        }
    }

    /// The geometry the operators live on.
    pub fn geometry(&self) -> &'g PairGeometry {
        self.geometry
    }

    /// The mass in use.
    pub fn mass_kind(&self) -> MassKind {
        self.mass
    }

    /// The flux of `Div` and `Curl`.
    pub fn flux_kind(&self) -> FluxKind {
        self.flux
    }

    /// The least-squares gradient.
    pub fn gradient(&self) -> &LeastSquaresGradient {
        &self.gradient
    }

    /// `(1/m_i) Σ_j φ_ij f(d_ij, flux value)` per support, zero where `m_i = 0`.
    fn flux_sum<T, F>(&self, v: &[DVec3], combine: F) -> Vec<T>
    where
        T: Default + Send + std::ops::AddAssign + std::ops::Mul<f64, Output = T>,
        F: Fn(DVec3, DVec3) -> T + Sync,
    {
        let g = self.geometry;
        assert_eq!(v.len(), g.len(), "v has the wrong length");
        let c = g.centres();
        let m = g.mass(self.mass);
        (0..g.len())
            .into_par_iter()
            .map(|i| {
                if m[i] <= 0.0 {
                    return T::default();
                }
                let mut acc = T::default();
                for (&j, &phi) in g.neighbours(i).iter().zip(g.phi_row(i)) {
                    let j = j as usize;
                    let value = match self.flux {
                        FluxKind::Neighbour => v[j],
                        FluxKind::Central => 0.5 * (v[i] + v[j]),
                    };
                    acc += combine(phi * (c[j] - c[i]), value);
                }
                acc * (1.0 / m[i])
            })
            .collect()
    }
}

impl DiscreteOperators for ThesisOperators<'_> {
    fn len(&self) -> usize {
        self.geometry.len()
    }

    fn grad(&self, u: &[f64]) -> Vec<DVec3> {
        self.gradient.apply(self.geometry, u)
    }

    fn div(&self, v: &[DVec3]) -> Vec<f64> {
        self.flux_sum(v, |area_normal, value| area_normal.dot(value))
    }

    fn lap(&self, u: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; u.len()];
        self.geometry.apply_laplacian(self.mass, u, &mut out);
        out
    }

    fn curl(&self, v: &[DVec3]) -> Vec<DVec3> {
        self.flux_sum(v, |area_normal, value| area_normal.cross(value))
    }
}
