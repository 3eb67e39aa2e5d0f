//! Per-support records packed for the evaluation loop.
//!
//! A query visits ~10–40 supports scattered over the cover's arrays; reading centre, radius
//! and coefficients from four separate arrays costs four cache misses per support. Packing
//! everything the loop needs about a support into one record (one cache line for a linear
//! function, two for a quadratic) makes it one or two.

use crate::cover::Cover;
use crate::local_function::LocalFunctions;
use glam::{DMat3, DVec3};

/// What the evaluation loop reads about one support: centre, `1/(σ r)`, and the local
/// function at an offset `d = x − c`.
pub(super) trait PackedSupport: Copy + Send + Sync {
    fn centre(&self) -> DVec3;
    fn inv_radius(&self) -> f64;
    fn value(&self, d: DVec3) -> f64;
    fn value_gradient(&self, d: DVec3) -> (f64, DVec3);
    /// The Hessian is `None` when it is identically zero (linear functions), to skip the work.
    fn value_gradient_hessian(&self, d: DVec3) -> (f64, DVec3, Option<DMat3>);
}

/// A support with a linear local function: exactly one 64-byte cache line.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct LinearSupport {
    centre: DVec3,
    inv_radius: f64,
    alpha: DVec3,
    beta: f64,
}

/// A support with a quadratic local function, stored by its Hessian `H = A + Aᵀ` (the six
/// entries `xx, yy, zz, xy, xz, yz`): `g = ½ dᵀHd + b·d + k`, `∇g = H d + b`, `∇²g = H`.
/// Taking `H` from `A + Aᵀ` makes the derivatives right for a non-symmetric `A` too.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct QuadraticSupport {
    centre: DVec3,
    inv_radius: f64,
    hessian: [f64; 6],
    b: DVec3,
    k: f64,
}

impl QuadraticSupport {
    #[inline]
    fn hessian_times(&self, d: DVec3) -> DVec3 {
        let [xx, yy, zz, xy, xz, yz] = self.hessian;
        DVec3::new(
            xx * d.x + xy * d.y + xz * d.z,
            xy * d.x + yy * d.y + yz * d.z,
            xz * d.x + yz * d.y + zz * d.z,
        )
    }

    #[inline]
    fn value_with(&self, d: DVec3, hd: DVec3) -> f64 {
        0.5 * d.dot(hd) + self.b.dot(d) + self.k
    }
}

impl PackedSupport for LinearSupport {
    #[inline]
    fn centre(&self) -> DVec3 {
        self.centre
    }

    #[inline]
    fn inv_radius(&self) -> f64 {
        self.inv_radius
    }

    #[inline]
    fn value(&self, d: DVec3) -> f64 {
        self.alpha.dot(d) + self.beta
    }

    #[inline]
    fn value_gradient(&self, d: DVec3) -> (f64, DVec3) {
        (self.value(d), self.alpha)
    }

    #[inline]
    fn value_gradient_hessian(&self, d: DVec3) -> (f64, DVec3, Option<DMat3>) {
        (self.value(d), self.alpha, None)
    }
}

impl PackedSupport for QuadraticSupport {
    #[inline]
    fn centre(&self) -> DVec3 {
        self.centre
    }

    #[inline]
    fn inv_radius(&self) -> f64 {
        self.inv_radius
    }

    #[inline]
    fn value(&self, d: DVec3) -> f64 {
        self.value_with(d, self.hessian_times(d))
    }

    #[inline]
    fn value_gradient(&self, d: DVec3) -> (f64, DVec3) {
        let hd = self.hessian_times(d);
        (self.value_with(d, hd), hd + self.b)
    }

    #[inline]
    fn value_gradient_hessian(&self, d: DVec3) -> (f64, DVec3, Option<DMat3>) {
        let (v, g) = self.value_gradient(d);
        let [xx, yy, zz, xy, xz, yz] = self.hessian;
        let h = DMat3::from_cols(
            DVec3::new(xx, xy, xz),
            DVec3::new(xy, yy, yz),
            DVec3::new(xz, yz, zz),
        );
        (v, g, Some(h))
    }
}

/// The packed records of all supports, in support order.
#[derive(Clone, Debug)]
pub(super) enum PackedSupports {
    Linear(Vec<LinearSupport>),
    Quadratic(Vec<QuadraticSupport>),
}

impl PackedSupports {
    /// Packs `cover` with the expanded radii's reciprocals `1/(σ r_i)`.
    pub(super) fn new(cover: &Cover, sigma: f64) -> PackedSupports {
        let centres = cover.centres();
        let inv_radius = |i: usize| 1.0 / (sigma * cover.radii()[i]);
        match cover.funcs() {
            LocalFunctions::Linear { alpha, beta } => PackedSupports::Linear(
                (0..cover.len())
                    .map(|i| LinearSupport {
                        centre: centres[i],
                        inv_radius: inv_radius(i),
                        alpha: alpha[i],
                        beta: beta[i],
                    })
                    .collect(),
            ),
            LocalFunctions::Quadratic { a, b, k } => PackedSupports::Quadratic(
                (0..cover.len())
                    .map(|i| {
                        let h = a[i] + a[i].transpose();
                        QuadraticSupport {
                            centre: centres[i],
                            inv_radius: inv_radius(i),
                            hessian: [
                                h.x_axis.x, h.y_axis.y, h.z_axis.z, h.y_axis.x, h.z_axis.x,
                                h.z_axis.y,
                            ],
                            b: b[i],
                            k: k[i],
                        }
                    })
                    .collect(),
            ),
        }
    }

    /// Centre and `1/(σ r)` of support `i`.
    pub(super) fn centre_inv_radius(&self, i: usize) -> (DVec3, f64) {
        match self {
            PackedSupports::Linear(v) => (v[i].centre, v[i].inv_radius),
            PackedSupports::Quadratic(v) => (v[i].centre, v[i].inv_radius),
        }
    }
}
