//! A support as the builders produce it, and how the accepted ones become a [`Cover`].
//!
//! The grid builder and the scattered-sample builder share it: both fit coefficients in the
//! frame `u = (x − c)/r` and hand them over here, so the conversion to local functions and
//! the statistics of the result exist once.

use glam::{DMat3, DVec3};

use super::fit::QUADRATIC;
use super::{VolumeCoverError, VolumeCoverParams, VolumeCoverStats, VolumeCoverVariant};
use crate::cover::Cover;
use crate::local_function::{LinearFunction, LocalFunctions, QuadraticFunction};

/// One accepted support (or a speculative fit).
#[derive(Clone, Copy, Debug)]
pub(super) struct Support {
    pub(super) centre: u32,
    pub(super) radius: f64,
    /// Squared distance (frame `d/h`) of the outermost shell inside the ball.
    pub(super) shell_d2: f64,
    /// Number of offsets (in table order) inside the ball.
    pub(super) offsets: usize,
    /// Coefficients in the frame `u = (x − c)/r`, constant term relative to `shift`.
    pub(super) coef: [f64; QUADRATIC],
    pub(super) shift: f64,
    pub(super) rms: f64,
}

impl Support {
    fn quadratic(&self) -> QuadraticFunction {
        let c = &self.coef;
        let (s1, s2) = (1.0 / self.radius, 1.0 / (self.radius * self.radius));
        let (xy, yz, xz) = (0.5 * c[7] * s2, 0.5 * c[8] * s2, 0.5 * c[9] * s2);
        QuadraticFunction {
            a: DMat3::from_cols(
                DVec3::new(c[4] * s2, xy, xz),
                DVec3::new(xy, c[5] * s2, yz),
                DVec3::new(xz, yz, c[6] * s2),
            ),
            b: DVec3::new(c[1], c[2], c[3]) * s1,
            k: c[0] + self.shift,
        }
    }

    fn linear(&self) -> LinearFunction {
        let c = &self.coef;
        LinearFunction {
            alpha: DVec3::new(c[1], c[2], c[3]) / self.radius,
            beta: c[0] + self.shift,
        }
    }
}

/// Assembles the cover of the accepted supports (centres given) and fills the statistics.
pub(super) fn supports_to_cover(
    supports: &[Support],
    centres: Vec<DVec3>,
    params: &VolumeCoverParams,
    stats: &mut VolumeCoverStats,
) -> Result<Cover, VolumeCoverError> {
    stats.supports = supports.len();
    let radii: Vec<f64> = supports.iter().map(|s| s.radius).collect();
    stats.radius_min = radii.iter().copied().fold(f64::INFINITY, f64::min);
    stats.radius_max = radii.iter().copied().fold(0.0, f64::max);
    stats.radius_mean = radii.iter().sum::<f64>() / radii.len().max(1) as f64;
    stats.max_rms = supports.iter().map(|s| s.rms).fold(0.0, f64::max);
    stats.above_tolerance = supports.iter().filter(|s| s.rms > params.tolerance).count();
    let funcs = match params.variant {
        VolumeCoverVariant::ObjectQuadratic => {
            LocalFunctions::from_quadratic(supports.iter().map(|s| s.quadratic()))
        }
        VolumeCoverVariant::BoundingBoxLinear => {
            LocalFunctions::from_linear(supports.iter().map(|s| s.linear()))
        }
    };
    Ok(Cover::new(centres, radii, funcs, params.kernel)?)
}
