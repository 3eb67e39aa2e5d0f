//! Exact arithmetic on floating-point expansions (Shewchuk, "Adaptive Precision
//! Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997).
//!
//! An expansion is a sum of `f64` components, nonoverlapping and sorted by increasing
//! magnitude, with zeros removed; its sign is the sign of its largest component. Sums,
//! differences and products of `f64` inputs are represented exactly, provided no intermediate
//! value overflows or underflows (Shewchuk's error-free transformations assume both). For
//! the predicates' polynomials, the triangulation guarantees this by scaling its input by a
//! power of two into the range derived in `src/regular/domain.rs` (every nonzero component
//! then stays a multiple of a normal power of two, and below `2^1016`).
//!
//! This is the slow, always-correct path of the predicates: the fast path is a floating-point
//! evaluation with an error bound (see [`crate::predicates`]). [`Ring`] lets each predicate be
//! written once and evaluated both with a running error bound ([`Bounded`]) and exactly
//! ([`Expansion`]).

use std::ops::{Add, Mul, Neg, Sub};

/// `2^27 + 1`, Dekker's splitter for `f64`.
const SPLITTER: f64 = 134_217_729.0;
/// Unit roundoff of `f64` (half an ulp of 1).
const UNIT_ROUNDOFF: f64 = 1.1102230246251565e-16;

#[inline(always)]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let x = a + b;
    let b_virtual = x - a;
    let a_virtual = x - b_virtual;
    let b_round = b - b_virtual;
    let a_round = a - a_virtual;
    (x, a_round + b_round)
}

#[inline(always)]
fn fast_two_sum(a: f64, b: f64) -> (f64, f64) {
    let x = a + b;
    let b_virtual = x - a;
    (x, b - b_virtual)
}

#[inline(always)]
fn split(a: f64) -> (f64, f64) {
    let c = SPLITTER * a;
    let a_big = c - a;
    let hi = c - a_big;
    (hi, a - hi)
}

#[inline(always)]
fn two_product_presplit(a: f64, b: f64, b_hi: f64, b_lo: f64) -> (f64, f64) {
    let x = a * b;
    let (a_hi, a_lo) = split(a);
    let err1 = x - a_hi * b_hi;
    let err2 = err1 - a_lo * b_hi;
    let err3 = err2 - a_hi * b_lo;
    (x, a_lo * b_lo - err3)
}

/// An exact sum of nonoverlapping `f64` components in increasing magnitude (zero-free).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Expansion(Vec<f64>);

impl Expansion {
    /// The expansion holding exactly `a`.
    pub fn from_f64(a: f64) -> Self {
        if a == 0.0 {
            Self(Vec::new())
        } else {
            Self(vec![a])
        }
    }

    /// The exact difference `a − b`.
    pub fn diff(a: f64, b: f64) -> Self {
        let x = a - b;
        let b_virtual = a - x;
        let a_virtual = x + b_virtual;
        let b_round = b_virtual - b;
        let a_round = a - a_virtual;
        let tail = a_round + b_round;
        let mut v = Vec::with_capacity(2);
        if tail != 0.0 {
            v.push(tail);
        }
        if x != 0.0 {
            v.push(x);
        }
        Self(v)
    }

    /// The components, smallest magnitude first.
    pub fn components(&self) -> &[f64] {
        &self.0
    }

    /// The sign of the exact value: −1, 0 or 1.
    pub fn sign(&self) -> i32 {
        match self.0.last() {
            None => 0,
            Some(&x) if x > 0.0 => 1,
            Some(_) => -1,
        }
    }

    /// A floating-point approximation of the value.
    pub fn estimate(&self) -> f64 {
        self.0.iter().sum()
    }

    fn sum(e: &[f64], f: &[f64]) -> Self {
        if e.is_empty() {
            return Self(f.to_vec());
        }
        if f.is_empty() {
            return Self(e.to_vec());
        }
        // fast_expansion_sum_zeroelim: merge by magnitude, then carry a running sum.
        let mut h = Vec::with_capacity(e.len() + f.len());
        let (mut ei, mut fi) = (0usize, 0usize);
        let mut enow = e[0];
        let mut fnow = f[0];
        let mut q;
        if (fnow > enow) == (fnow > -enow) {
            q = enow;
            ei += 1;
        } else {
            q = fnow;
            fi += 1;
        }
        if ei < e.len() && fi < f.len() {
            enow = e[ei];
            fnow = f[fi];
            let (qn, hh) = if (fnow > enow) == (fnow > -enow) {
                ei += 1;
                fast_two_sum(enow, q)
            } else {
                fi += 1;
                fast_two_sum(fnow, q)
            };
            q = qn;
            if hh != 0.0 {
                h.push(hh);
            }
            while ei < e.len() && fi < f.len() {
                enow = e[ei];
                fnow = f[fi];
                let (qn, hh) = if (fnow > enow) == (fnow > -enow) {
                    ei += 1;
                    two_sum(q, enow)
                } else {
                    fi += 1;
                    two_sum(q, fnow)
                };
                q = qn;
                if hh != 0.0 {
                    h.push(hh);
                }
            }
        }
        while ei < e.len() {
            let (qn, hh) = two_sum(q, e[ei]);
            ei += 1;
            q = qn;
            if hh != 0.0 {
                h.push(hh);
            }
        }
        while fi < f.len() {
            let (qn, hh) = two_sum(q, f[fi]);
            fi += 1;
            q = qn;
            if hh != 0.0 {
                h.push(hh);
            }
        }
        if q != 0.0 {
            h.push(q);
        }
        Self(h)
    }

    fn scale(e: &[f64], b: f64) -> Self {
        if e.is_empty() || b == 0.0 {
            return Self(Vec::new());
        }
        let mut h = Vec::with_capacity(2 * e.len());
        let (b_hi, b_lo) = split(b);
        let (mut q, hh) = two_product_presplit(e[0], b, b_hi, b_lo);
        if hh != 0.0 {
            h.push(hh);
        }
        for &enow in &e[1..] {
            let (p1, p0) = two_product_presplit(enow, b, b_hi, b_lo);
            let (sum, hh) = two_sum(q, p0);
            if hh != 0.0 {
                h.push(hh);
            }
            let (qn, hh) = fast_two_sum(p1, sum);
            q = qn;
            if hh != 0.0 {
                h.push(hh);
            }
        }
        if q != 0.0 {
            h.push(q);
        }
        Self(h)
    }

    fn product(e: &[f64], f: &[f64]) -> Self {
        let (long, short) = if e.len() >= f.len() { (e, f) } else { (f, e) };
        let mut acc = Self(Vec::new());
        for &b in short {
            let part = Self::scale(long, b);
            acc = Self::sum(&acc.0, &part.0);
        }
        acc
    }
}

impl Add for &Expansion {
    type Output = Expansion;
    fn add(self, rhs: &Expansion) -> Expansion {
        Expansion::sum(&self.0, &rhs.0)
    }
}

impl Neg for &Expansion {
    type Output = Expansion;
    fn neg(self) -> Expansion {
        Expansion(self.0.iter().map(|x| -x).collect())
    }
}

impl Sub for &Expansion {
    type Output = Expansion;
    fn sub(self, rhs: &Expansion) -> Expansion {
        let neg: Vec<f64> = rhs.0.iter().map(|x| -x).collect();
        Expansion::sum(&self.0, &neg)
    }
}

impl Mul for &Expansion {
    type Output = Expansion;
    fn mul(self, rhs: &Expansion) -> Expansion {
        Expansion::product(&self.0, &rhs.0)
    }
}

/// A number type a predicate polynomial can be evaluated in: exactly ([`Expansion`]) or in
/// floating point with a running error bound ([`Bounded`]).
pub trait Ring: Clone {
    /// The input value `a` (exact).
    fn input(a: f64) -> Self;
    /// The difference `a − b` of two inputs.
    fn input_diff(a: f64, b: f64) -> Self;
    /// `self + rhs`.
    fn add(&self, rhs: &Self) -> Self;
    /// `self − rhs`.
    fn sub(&self, rhs: &Self) -> Self;
    /// `self · rhs`.
    fn mul(&self, rhs: &Self) -> Self;
    /// The sign if it is certain, `None` if the error bound does not decide it.
    fn certain_sign(&self) -> Option<i32>;
}

impl Ring for Expansion {
    fn input(a: f64) -> Self {
        Expansion::from_f64(a)
    }
    fn input_diff(a: f64, b: f64) -> Self {
        Expansion::diff(a, b)
    }
    fn add(&self, rhs: &Self) -> Self {
        self + rhs
    }
    fn sub(&self, rhs: &Self) -> Self {
        self - rhs
    }
    fn mul(&self, rhs: &Self) -> Self {
        self * rhs
    }
    fn certain_sign(&self) -> Option<i32> {
        Some(self.sign())
    }
}

/// A floating-point value with a rigorous bound on its distance to the exact value
/// (running error analysis: every rounding adds `u·|result|`, every operation also adds
/// `f64::MIN_POSITIVE` to cover gradual underflow). Overflow turns the value into an
/// infinity or NaN, whose sign is never reported as certain.
#[derive(Clone, Copy, Debug)]
pub struct Bounded {
    /// The computed value.
    pub value: f64,
    /// An upper bound on `|value − exact|`.
    pub error: f64,
}

impl Ring for Bounded {
    #[inline(always)]
    fn input(a: f64) -> Self {
        Bounded {
            value: a,
            error: 0.0,
        }
    }
    #[inline(always)]
    fn input_diff(a: f64, b: f64) -> Self {
        let v = a - b;
        Bounded {
            value: v,
            error: UNIT_ROUNDOFF * v.abs() + f64::MIN_POSITIVE,
        }
    }
    #[inline(always)]
    fn add(&self, rhs: &Self) -> Self {
        let v = self.value + rhs.value;
        Bounded {
            value: v,
            error: self.error + rhs.error + UNIT_ROUNDOFF * v.abs() + f64::MIN_POSITIVE,
        }
    }
    #[inline(always)]
    fn sub(&self, rhs: &Self) -> Self {
        let v = self.value - rhs.value;
        Bounded {
            value: v,
            error: self.error + rhs.error + UNIT_ROUNDOFF * v.abs() + f64::MIN_POSITIVE,
        }
    }
    #[inline(always)]
    fn mul(&self, rhs: &Self) -> Self {
        let v = self.value * rhs.value;
        Bounded {
            value: v,
            error: self.value.abs() * rhs.error
                + rhs.value.abs() * self.error
                + self.error * rhs.error
                + UNIT_ROUNDOFF * v.abs()
                + f64::MIN_POSITIVE,
        }
    }
    #[inline(always)]
    fn certain_sign(&self) -> Option<i32> {
        // The bound itself was computed with rounding; the factor absorbs that.
        let margin = self.error * (1.0 + 1e-6);
        if self.value > margin {
            Some(1)
        } else if self.value < -margin {
            Some(-1)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn to_i128(e: &Expansion, scale_log2: i32) -> i128 {
        e.components()
            .iter()
            .map(|&c| (c * 2f64.powi(scale_log2)) as i128)
            .sum()
    }

    #[test]
    fn products_of_large_integers_are_exact() {
        let a = Expansion::from_f64(123_456_789.0);
        let b = Expansion::from_f64(987_654_321.0);
        let c = Expansion::from_f64(555_555_555_555.0);
        let p = &(&a * &b) * &c;
        assert_eq!(
            to_i128(&p, 0),
            123_456_789i128 * 987_654_321 * 555_555_555_555
        );
        let d = &p - &p;
        assert_eq!(d.sign(), 0);
    }

    #[test]
    fn diff_is_exact() {
        let e = Expansion::diff(1.0, 1e-30);
        assert_eq!(e.components(), &[-1e-30, 1.0]);
        assert_eq!(Expansion::diff(0.3, 0.3).sign(), 0);
    }
}
