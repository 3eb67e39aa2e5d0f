//! The cover: supports (balls) with their local functions and the weight kernel (thesis §3.2).

use crate::LengthMismatch;
use crate::kernel::Kernel;
use crate::local_function::{LocalFunction, LocalFunctions};
use glam::DVec3;

/// Why a cover (or an evaluator over it) could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CoverError {
    /// An array does not have one entry per support.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
    /// More supports than `u32` indices can name.
    #[error("{count} supports exceed the u32 index range")]
    TooManySupports {
        /// Number of supports given.
        count: usize,
    },
    /// A centre has a NaN or infinite coordinate.
    #[error("support {index}: centre {centre} is not finite")]
    NonFiniteCentre {
        /// Index of the support.
        index: usize,
        /// The centre given.
        centre: DVec3,
    },
    /// A radius is NaN, infinite, zero, negative or subnormal (its reciprocal must be finite).
    #[error("support {index}: radius {radius} is not a finite positive normal number")]
    InvalidRadius {
        /// Index of the support.
        index: usize,
        /// The radius given.
        radius: f64,
    },
    /// A local function has a NaN or infinite coefficient.
    #[error("support {index}: local function has a non-finite coefficient")]
    NonFiniteFunction {
        /// Index of the support.
        index: usize,
    },
    /// The expansion factor σ is not finite or below 1.
    #[error("expansion factor {sigma} is not finite and ≥ 1")]
    InvalidExpansion {
        /// The factor given.
        sigma: f64,
    },
    /// A radius times the expansion factor overflows to infinity.
    #[error("support {index}: radius {radius} times expansion factor {sigma} is not finite")]
    ExpandedRadiusOverflow {
        /// Index of the support.
        index: usize,
        /// The radius of the support.
        radius: f64,
        /// The expansion factor.
        sigma: f64,
    },
    /// A cover evaluated over support lists gathered from other balls.
    #[error(
        "support {index}: centre or radius differs from the cover the support lists were gathered from"
    )]
    OtherBalls {
        /// Index of the first support that differs.
        index: usize,
    },
    /// Support lists asked for values at other points than they were gathered for.
    #[error("point {index} differs from the point the support lists were gathered for")]
    OtherPoints {
        /// Index of the first point that differs.
        index: usize,
    },
}

/// A cover of space by balls `s_i = (c_i, r_i)`, each carrying a local function `g_i`, blended
/// by the partition of unity of the kernel weights (thesis eq. 3.1):
///
/// ```text
/// f(x) = Σ_i w_i(x) g_i(x) / Σ_i w_i(x),   w_i(x) = ψ(‖x − c_i‖ / r_i)
/// ```
///
/// Stored as struct-of-arrays; support `i` is `(centres[i], radii[i], funcs.get(i))`. The
/// constructor validates every entry, so a `Cover` always has finite centres, finite positive
/// radii and finite local functions, one per support. Evaluate it with
/// [`crate::PuEvaluator`].
///
/// # Example
///
/// ```
/// use sphcover_core::{Cover, DVec3, Kernel, LinearFunction, LocalFunctions, PuEvaluator};
///
/// // Two overlapping supports on the x axis, both carrying g(x) = 1 − x (in centred form).
/// let centres = vec![DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0)];
/// let radii = vec![1.0, 1.5];
/// let funcs = LocalFunctions::from_linear(
///     centres.iter().map(|&c| LinearFunction::from_global(DVec3::new(-1.0, 0.0, 0.0), 1.0, c)),
/// );
/// let cover = Cover::new(centres, radii, funcs, Kernel::WendlandC2)?;
///
/// let eval = PuEvaluator::new(&cover, 1.0)?;
/// let x = DVec3::new(0.5, 0.2, 0.0);
/// let fg = eval.value_gradient(x).expect("x lies inside a support");
/// assert!((fg.value - 0.5).abs() < 1e-12);
/// assert!((fg.gradient - DVec3::new(-1.0, 0.0, 0.0)).length() < 1e-12);
/// // Far from every ball the function is undefined.
/// assert_eq!(eval.value(DVec3::new(10.0, 0.0, 0.0)), None);
/// # Ok::<(), sphcover_core::CoverError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Cover {
    centres: Vec<DVec3>,
    radii: Vec<f64>,
    funcs: LocalFunctions,
    kernel: Kernel,
}

impl Cover {
    /// Builds a cover after checking that every array has one entry per support, that centres
    /// and local functions are finite, that radii are finite, positive and normal (not
    /// subnormal, so `1/r` is finite), and that the supports can be indexed by `u32`.
    pub fn new(
        centres: Vec<DVec3>,
        radii: Vec<f64>,
        funcs: LocalFunctions,
        kernel: Kernel,
    ) -> Result<Cover, CoverError> {
        let n = centres.len();
        if u32::try_from(n).is_err() {
            return Err(CoverError::TooManySupports { count: n });
        }
        if radii.len() != n {
            return Err(CoverError::LengthMismatch(LengthMismatch {
                array: "radii",
                expected: n,
                found: radii.len(),
            }));
        }
        check_funcs(&funcs, n)?;
        if let Some(index) = centres.iter().position(|c| !c.is_finite()) {
            return Err(CoverError::NonFiniteCentre {
                index,
                centre: centres[index],
            });
        }
        if let Some(index) = radii.iter().position(|&r| !(r.is_normal() && r > 0.0)) {
            return Err(CoverError::InvalidRadius {
                index,
                radius: radii[index],
            });
        }
        Ok(Cover {
            centres,
            radii,
            funcs,
            kernel,
        })
    }

    /// Number of supports.
    pub fn len(&self) -> usize {
        self.centres.len()
    }

    /// True when the cover has no support.
    pub fn is_empty(&self) -> bool {
        self.centres.is_empty()
    }

    /// Support centres `c_i`.
    pub fn centres(&self) -> &[DVec3] {
        &self.centres
    }

    /// Support radii `r_i`.
    pub fn radii(&self) -> &[f64] {
        &self.radii
    }

    /// Local functions `g_i`.
    pub fn funcs(&self) -> &LocalFunctions {
        &self.funcs
    }

    /// The local function of support `i`, or `None` when `i` is out of range.
    pub fn func(&self, i: usize) -> Option<LocalFunction> {
        self.funcs.get(i)
    }

    /// The weight kernel.
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// Replaces the kernel.
    pub fn set_kernel(&mut self, kernel: Kernel) {
        self.kernel = kernel;
    }

    /// Replaces the local functions (e.g. after diffusion, thesis §5.2.3), with the same checks
    /// as [`Cover::new`]. On error the cover is unchanged.
    pub fn set_funcs(&mut self, funcs: LocalFunctions) -> Result<(), CoverError> {
        check_funcs(&funcs, self.len())?;
        self.funcs = funcs;
        Ok(())
    }

    /// Takes the cover apart: `(centres, radii, funcs, kernel)`.
    pub fn into_parts(self) -> (Vec<DVec3>, Vec<f64>, LocalFunctions, Kernel) {
        (self.centres, self.radii, self.funcs, self.kernel)
    }
}

fn check_funcs(funcs: &LocalFunctions, n: usize) -> Result<(), CoverError> {
    for (array, len) in funcs.array_lengths() {
        if len != n {
            return Err(CoverError::LengthMismatch(LengthMismatch {
                array,
                expected: n,
                found: len,
            }));
        }
    }
    match funcs.first_non_finite() {
        Some(index) => Err(CoverError::NonFiniteFunction { index }),
        None => Ok(()),
    }
}
