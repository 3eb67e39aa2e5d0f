//! Local functions of the supports, in the form centred at the support centre (thesis §3.2,
//! eq. 3.2 and 3.8).
//!
//! The thesis writes the quadratic in raw monomials of `x`; the centred form
//! `g(x) = (x − c)ᵀA(x − c) + b·(x − c) + k` spans the same space and stays well conditioned
//! for small supports far from the origin. Every method takes the *offset* `d = x − c` from
//! the support centre `c`.

use glam::{DMat3, DVec3};

/// A linear local function `g(x) = α·(x − c) + β`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LinearFunction {
    /// The gradient `α`.
    pub alpha: DVec3,
    /// The value `β` at the support centre.
    pub beta: f64,
}

impl LinearFunction {
    /// The value at offset `d = x − c`.
    #[inline]
    pub fn value(&self, d: DVec3) -> f64 {
        self.alpha.dot(d) + self.beta
    }

    /// The gradient (constant).
    #[inline]
    pub fn gradient(&self) -> DVec3 {
        self.alpha
    }

    /// True when every coefficient is finite.
    pub fn is_finite(&self) -> bool {
        self.alpha.is_finite() && self.beta.is_finite()
    }
}

/// A quadratic local function `g(x) = (x − c)ᵀA(x − c) + b·(x − c) + k`.
///
/// `A` is stored as a full [`DMat3`] and is meant to be symmetric. Only its symmetric part
/// `(A + Aᵀ)/2` affects the value, and the derivatives are computed from that symmetric part,
/// so a non-symmetric `A` still yields a consistent value, gradient and Hessian.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct QuadraticFunction {
    /// The quadratic coefficients `A` (symmetric).
    pub a: DMat3,
    /// The gradient `b` at the support centre.
    pub b: DVec3,
    /// The value `k` at the support centre.
    pub k: f64,
}

impl QuadraticFunction {
    /// The value at offset `d = x − c`.
    #[inline]
    pub fn value(&self, d: DVec3) -> f64 {
        d.dot(self.a * d) + self.b.dot(d) + self.k
    }

    /// The gradient `(A + Aᵀ) d + b` at offset `d = x − c`.
    #[inline]
    pub fn gradient(&self, d: DVec3) -> DVec3 {
        self.a * d + self.a.transpose() * d + self.b
    }

    /// The Hessian `A + Aᵀ` (constant).
    #[inline]
    pub fn hessian(&self) -> DMat3 {
        self.a + self.a.transpose()
    }

    /// The quadratic with `A = 0` equal to a linear function.
    pub fn from_linear(linear: LinearFunction) -> QuadraticFunction {
        QuadraticFunction {
            a: DMat3::ZERO,
            b: linear.alpha,
            k: linear.beta,
        }
    }

    /// The quadratic `xᵀQx + p·x + q` of the raw coordinates, rewritten in the form centred at
    /// `centre`: `A = Q`, `b = (Q + Qᵀ)c + p`, `k = cᵀQc + p·c + q`.
    pub fn from_global(q_mat: DMat3, p: DVec3, q: f64, centre: DVec3) -> QuadraticFunction {
        QuadraticFunction {
            a: q_mat,
            b: q_mat * centre + q_mat.transpose() * centre + p,
            k: centre.dot(q_mat * centre) + p.dot(centre) + q,
        }
    }

    /// True when every coefficient is finite.
    pub fn is_finite(&self) -> bool {
        self.a.is_finite() && self.b.is_finite() && self.k.is_finite()
    }
}

impl LinearFunction {
    /// The linear function `p·x + q` of the raw coordinates, rewritten in the form centred at
    /// `centre`: `α = p`, `β = p·c + q`.
    pub fn from_global(p: DVec3, q: f64, centre: DVec3) -> LinearFunction {
        LinearFunction {
            alpha: p,
            beta: p.dot(centre) + q,
        }
    }
}

/// One local function, either kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LocalFunction {
    /// A linear local function.
    Linear(LinearFunction),
    /// A quadratic local function.
    Quadratic(QuadraticFunction),
}

impl LocalFunction {
    /// The value at offset `d = x − c`.
    pub fn value(&self, d: DVec3) -> f64 {
        match self {
            LocalFunction::Linear(g) => g.value(d),
            LocalFunction::Quadratic(g) => g.value(d),
        }
    }

    /// The gradient at offset `d = x − c`.
    pub fn gradient(&self, d: DVec3) -> DVec3 {
        match self {
            LocalFunction::Linear(g) => g.gradient(),
            LocalFunction::Quadratic(g) => g.gradient(d),
        }
    }

    /// The Hessian (constant for both kinds).
    pub fn hessian(&self) -> DMat3 {
        match self {
            LocalFunction::Linear(_) => DMat3::ZERO,
            LocalFunction::Quadratic(g) => g.hessian(),
        }
    }
}

/// The local functions of all supports of a cover, stored as struct-of-arrays; entry `i`
/// belongs to support `i`.
#[derive(Clone, Debug, PartialEq)]
pub enum LocalFunctions {
    /// Linear functions `α_i·(x − c_i) + β_i` (surface pipeline, thesis §3.4.1).
    Linear {
        /// Gradients `α_i`.
        alpha: Vec<DVec3>,
        /// Values `β_i` at the centres.
        beta: Vec<f64>,
    },
    /// Quadratic functions `(x − c_i)ᵀA_i(x − c_i) + b_i·(x − c_i) + k_i` (volume pipeline,
    /// thesis §3.4.2), `A_i` symmetric.
    Quadratic {
        /// Quadratic coefficients `A_i` (symmetric).
        a: Vec<DMat3>,
        /// Gradients `b_i` at the centres.
        b: Vec<DVec3>,
        /// Values `k_i` at the centres.
        k: Vec<f64>,
    },
}

impl LocalFunctions {
    /// Linear storage from a sequence of linear functions.
    pub fn from_linear(funcs: impl IntoIterator<Item = LinearFunction>) -> LocalFunctions {
        let (alpha, beta) = funcs.into_iter().map(|g| (g.alpha, g.beta)).unzip();
        LocalFunctions::Linear { alpha, beta }
    }

    /// Quadratic storage from a sequence of quadratic functions.
    pub fn from_quadratic(funcs: impl IntoIterator<Item = QuadraticFunction>) -> LocalFunctions {
        let mut a = Vec::new();
        let mut b = Vec::new();
        let mut k = Vec::new();
        for g in funcs {
            a.push(g.a);
            b.push(g.b);
            k.push(g.k);
        }
        LocalFunctions::Quadratic { a, b, k }
    }

    /// `n` linear functions that are identically zero.
    pub fn zero_linear(n: usize) -> LocalFunctions {
        LocalFunctions::Linear {
            alpha: vec![DVec3::ZERO; n],
            beta: vec![0.0; n],
        }
    }

    /// The same functions in quadratic storage (linear ones get `A = 0`).
    pub fn to_quadratic(&self) -> LocalFunctions {
        match self {
            LocalFunctions::Linear { alpha, beta } => LocalFunctions::Quadratic {
                a: vec![DMat3::ZERO; alpha.len()],
                b: alpha.clone(),
                k: beta.clone(),
            },
            LocalFunctions::Quadratic { .. } => self.clone(),
        }
    }

    /// Number of functions. For storage whose arrays disagree in length (rejected by
    /// [`crate::Cover::new`]) this is the shortest array's length.
    pub fn len(&self) -> usize {
        match self {
            LocalFunctions::Linear { alpha, beta } => alpha.len().min(beta.len()),
            LocalFunctions::Quadratic { a, b, k } => a.len().min(b.len()).min(k.len()),
        }
    }

    /// True when there is no function.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// True for linear storage.
    pub fn is_linear(&self) -> bool {
        matches!(self, LocalFunctions::Linear { .. })
    }

    /// Function `i`, or `None` when `i` is out of range.
    pub fn get(&self, i: usize) -> Option<LocalFunction> {
        if i >= self.len() {
            return None;
        }
        Some(match self {
            LocalFunctions::Linear { alpha, beta } => LocalFunction::Linear(LinearFunction {
                alpha: alpha[i],
                beta: beta[i],
            }),
            LocalFunctions::Quadratic { a, b, k } => LocalFunction::Quadratic(QuadraticFunction {
                a: a[i],
                b: b[i],
                k: k[i],
            }),
        })
    }

    /// Lengths of the coefficient arrays with their names, for validation messages.
    pub(crate) fn array_lengths(&self) -> Vec<(&'static str, usize)> {
        match self {
            LocalFunctions::Linear { alpha, beta } => {
                vec![("alpha", alpha.len()), ("beta", beta.len())]
            }
            LocalFunctions::Quadratic { a, b, k } => {
                vec![("a", a.len()), ("b", b.len()), ("k", k.len())]
            }
        }
    }

    /// Index of the first function with a non-finite coefficient.
    pub(crate) fn first_non_finite(&self) -> Option<usize> {
        (0..self.len()).find(|&i| match self.get(i) {
            Some(LocalFunction::Linear(g)) => !g.is_finite(),
            Some(LocalFunction::Quadratic(g)) => !g.is_finite(),
            None => false,
        })
    }
}
