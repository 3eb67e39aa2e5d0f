//! Exact, adaptive geometric predicates with symbolic perturbation.
//!
//! Every predicate returns the sign of a polynomial in the `f64` inputs *exactly*. Evaluation
//! is staged: a floating-point evaluation with a static error bound (Shewchuk-style, from the
//! permanent of the polynomial), then, for inputs whose coordinate differences are exact small
//! multiples of a common power of two (grids, octrees: where exact ties live), an `i128`
//! evaluation, then expansion arithmetic (module `expansion`). The triangulation adds an
//! exact plain-`f64` stage for power tests on a grid of small extent (`grid_lifted_sign`):
//! before the filter for equal weights, where most tests are exact ties, after it otherwise.
//!
//! Conventions:
//! * [`orient3d`]`(a, b, c, d)` is the sign of `det[b − a; c − a; d − a]`: positive when `d` lies
//!   on the side of the plane `abc` that `(b − a) × (c − a)` points to. A tetrahedron is
//!   *positively oriented* when this is positive.
//! * Weighted points `(p, w)` with `w = r²`; the power of `x` is `‖x − p‖² − w`. The lifted
//!   coordinate of `p` is `‖p‖² − w`.
//!
//! Symbolic perturbation (Devillers and Teillaud, "Perturbations for Delaunay and weighted
//! Delaunay 3D triangulations", 2011): the lifted coordinate of each point is raised by
//! `ε^k`, with `k` smaller for points later in lexicographic `(x, y, z)` order. In a tie
//! the largest point of the configuration decides: if it is the query, the query is not in
//! conflict; otherwise replacing that point by the query gives a simplex whose orientation
//! decides, falling to the next point when it is flat. CGAL's regular triangulation uses the
//! same rule, so tied configurations are split as CGAL splits them. Distinct points are
//! required (the triangulation removes duplicated centres before inserting).
//!
//! Exactness domain: the stages are exact (and the filters' bounds rigorous) while no value
//! they form underflows into the subnormal range or overflows. Taking coordinates as lengths
//! and weights as squared lengths, that holds for instance when every coordinate is below
//! `2^121` in magnitude and a multiple of `2^-127`, and every weight below `2^242` and a
//! multiple of `2^-254`: every nonzero value formed from up to eight lengths (the orthocentre
//! power has degree 8) is then a multiple of `2^-1016`, and stays below `2^1016` even through
//! Dekker's splitter. [`crate::regular::RegularTriangulation`] scales its input by a power of
//! two, which changes no sign, into the range where this holds (derived term by term in
//! `src/regular/domain.rs`), and refuses inputs that no such scaling brings there. Called
//! directly, the predicates are exact on any input for which nothing under- or overflows.

use crate::expansion::{Expansion, Ring};

/// A point in 3D as plain coordinates.
pub type Point = [f64; 3];

/// Unit roundoff of `f64`.
const U: f64 = 1.1102230246251565e-16;
/// Shewchuk's `o3derrboundA = (7 + 56ε)ε`.
const ORIENT3D_BOUND: f64 = 7.771561172376103e-16;
/// Rounding steps on the longest path of the lifted determinant (18), plus slack.
const LIFTED_BOUND: f64 = 22.0 * U;
/// Absolute slack of the orientation and power filters. Inside the exactness domain (module
/// docs) nothing underflows and the relative bounds alone are rigorous; the slack keeps the
/// filters sound for direct callers whose values underflow, as long as coordinates stay below
/// about `1e20` and weights below `1e40`: each underflowed rounding errs by at most `2^-1075`,
/// and the products it enters scale that by at most `2e20 · 1e41`, far below `1e-220`.
const UNDERFLOW_SLACK: f64 = 1e-220;

// ------------------------------------------------------------------------------------------
// orient3d
// ------------------------------------------------------------------------------------------

/// Exact sign of `det[b − a; c − a; d − a]` (−1, 0 or 1).
#[inline]
pub fn orient3d(a: &Point, b: &Point, c: &Point, d: &Point) -> i32 {
    match orient3d_filter(a, b, c, d) {
        Some(s) => s,
        None => orient3d_exact(a, b, c, d),
    }
}

/// The floating-point stage of [`orient3d`]: the sign when the static error bound certifies
/// it.
#[inline]
pub(crate) fn orient3d_filter(a: &Point, b: &Point, c: &Point, d: &Point) -> Option<i32> {
    let ba_x = b[0] - a[0];
    let ba_y = b[1] - a[1];
    let ba_z = b[2] - a[2];
    let cax = c[0] - a[0];
    let cay = c[1] - a[1];
    let caz = c[2] - a[2];
    let dax = d[0] - a[0];
    let day = d[1] - a[1];
    let daz = d[2] - a[2];
    let m1 = cay * daz;
    let m2 = caz * day;
    let m3 = cax * daz;
    let m4 = caz * dax;
    let m5 = cax * day;
    let m6 = cay * dax;
    let det = ba_x * (m1 - m2) - ba_y * (m3 - m4) + ba_z * (m5 - m6);
    let permanent = ba_x.abs() * (m1.abs() + m2.abs())
        + ba_y.abs() * (m3.abs() + m4.abs())
        + ba_z.abs() * (m5.abs() + m6.abs());
    let bound = ORIENT3D_BOUND * permanent + UNDERFLOW_SLACK;
    if det > bound {
        return Some(1);
    }
    if det < -bound {
        return Some(-1);
    }
    None
}

/// Exact [`orient3d`] for points on a dyadic grid of unit `u = 2^e`, when every difference
/// to `a` is below `limit = 2^16·u`; `None` otherwise. The caller ensures `|e| ≤ 300`.
///
/// Why plain `f64` arithmetic is exact here: the differences are exact multiples of `u`
/// below `2^16·u`, the 2×2 minors exact multiples of `u²` below `2^33·u²`, the three terms
/// multiples of `u³` below `2^49·u³` and their sum below `2^51·u³`: every value fits the
/// 53-bit significand, and `|e| ≤ 300` keeps all of them far from under- and overflow. On
/// grids this replaces the float filter's error bound (cheaper than the permanent) and
/// settles the exactly coplanar cases, frequent there, without the integer stage.
#[inline(always)]
pub(crate) fn orient3d_grid(a: &Point, b: &Point, c: &Point, d: &Point, limit: f64) -> Option<i32> {
    let ba_x = b[0] - a[0];
    let ba_y = b[1] - a[1];
    let ba_z = b[2] - a[2];
    let cax = c[0] - a[0];
    let cay = c[1] - a[1];
    let caz = c[2] - a[2];
    let dax = d[0] - a[0];
    let day = d[1] - a[1];
    let daz = d[2] - a[2];
    // `<` is false for NaN too.
    let small = ba_x.abs() < limit
        && ba_y.abs() < limit
        && ba_z.abs() < limit
        && cax.abs() < limit
        && cay.abs() < limit
        && caz.abs() < limit
        && dax.abs() < limit
        && day.abs() < limit
        && daz.abs() < limit;
    if !small {
        return None;
    }
    let det = ba_x * (cay * daz - caz * day) - ba_y * (cax * daz - caz * dax)
        + ba_z * (cax * day - cay * dax);
    Some(sign_of(det))
}

#[cold]
fn orient3d_exact(a: &Point, b: &Point, c: &Point, d: &Point) -> i32 {
    let mut diffs = [0i64; 9];
    let vals = [
        b[0] - a[0],
        b[1] - a[1],
        b[2] - a[2],
        c[0] - a[0],
        c[1] - a[1],
        c[2] - a[2],
        d[0] - a[0],
        d[1] - a[1],
        d[2] - a[2],
    ];
    let exact = exact_diff(b[0], a[0], vals[0])
        && exact_diff(b[1], a[1], vals[1])
        && exact_diff(b[2], a[2], vals[2])
        && exact_diff(c[0], a[0], vals[3])
        && exact_diff(c[1], a[1], vals[4])
        && exact_diff(c[2], a[2], vals[5])
        && exact_diff(d[0], a[0], vals[6])
        && exact_diff(d[1], a[1], vals[7])
        && exact_diff(d[2], a[2], vals[8]);
    if exact && to_fixed(&vals, 40, &mut diffs).is_some() {
        let v = |i: usize| diffs[i] as i128;
        let det = v(0) * (v(4) * v(8) - v(5) * v(7)) - v(1) * (v(3) * v(8) - v(5) * v(6))
            + v(2) * (v(3) * v(7) - v(4) * v(6));
        return det.signum() as i32;
    }
    Orient3d { a, b, c, d }.eval::<Expansion>().sign()
}

struct Orient3d<'a> {
    a: &'a Point,
    b: &'a Point,
    c: &'a Point,
    d: &'a Point,
}

impl Orient3d<'_> {
    fn eval<R: Ring>(&self) -> R {
        let (a, b, c, d) = (self.a, self.b, self.c, self.d);
        let ba: [R; 3] = std::array::from_fn(|k| R::input_diff(b[k], a[k]));
        let ca: [R; 3] = std::array::from_fn(|k| R::input_diff(c[k], a[k]));
        let da: [R; 3] = std::array::from_fn(|k| R::input_diff(d[k], a[k]));
        det3(&ba, &ca, &da)
    }
}

fn det3<R: Ring>(r0: &[R; 3], r1: &[R; 3], r2: &[R; 3]) -> R {
    let m0 = r1[1].mul(&r2[2]).sub(&r1[2].mul(&r2[1]));
    let m1 = r1[0].mul(&r2[2]).sub(&r1[2].mul(&r2[0]));
    let m2 = r1[0].mul(&r2[1]).sub(&r1[1].mul(&r2[0]));
    r0[0].mul(&m0).sub(&r0[1].mul(&m1)).add(&r0[2].mul(&m2))
}

fn det2<R: Ring>(a: &R, b: &R, c: &R, d: &R) -> R {
    a.mul(d).sub(&b.mul(c))
}

fn dot3<R: Ring>(a: &[R; 3], b: &[R; 3]) -> R {
    a[0].mul(&b[0]).add(&a[1].mul(&b[1])).add(&a[2].mul(&b[2]))
}

/// `true` when `a − b` rounded to `d` is exact.
#[inline]
fn exact_diff(a: f64, b: f64, d: f64) -> bool {
    let b_virtual = a - d;
    let a_virtual = d + b_virtual;
    let b_round = b_virtual - b;
    let a_round = a - a_virtual;
    a_round + b_round == 0.0
}

/// Writes `vals` as integer multiples of a common power of two `2^e` and returns `e`, if
/// every multiple is below `2^bits` in magnitude (`bits ≤ 62`). Works on the bit patterns:
/// no floating-point scaling.
#[inline]
fn to_fixed(vals: &[f64], bits: i32, out: &mut [i64]) -> Option<i32> {
    let mut low = i32::MAX;
    let mut high = i32::MIN;
    for &v in vals {
        let raw = v.to_bits();
        let biased = ((raw >> 52) & 0x7ff) as i32;
        if biased == 0 {
            if raw << 1 == 0 {
                continue;
            }
            return None; // subnormal
        }
        if biased == 0x7ff {
            return None;
        }
        let mantissa = (raw & ((1u64 << 52) - 1)) | (1u64 << 52);
        let exponent = biased - 1075;
        low = low.min(exponent + mantissa.trailing_zeros() as i32);
        high = high.max(exponent + 53);
    }
    if low == i32::MAX {
        out.iter_mut().for_each(|o| *o = 0);
        return Some(0);
    }
    if high - low > bits {
        return None;
    }
    for (o, &v) in out.iter_mut().zip(vals) {
        let raw = v.to_bits();
        if raw << 1 == 0 {
            *o = 0;
            continue;
        }
        let mantissa = (raw & ((1u64 << 52) - 1)) | (1u64 << 52);
        let exponent = ((raw >> 52) & 0x7ff) as i32 - 1075;
        let shift = exponent - low;
        let m = if shift >= 0 {
            (mantissa << shift) as i64
        } else {
            (mantissa >> -shift) as i64
        };
        *o = if raw >> 63 == 1 { -m } else { m };
    }
    Some(low)
}

/// `v · 2^e`, exact when the result is a normal number, or when `v` and the exact result
/// are representable (a scaling that undoes an exact one): a large `e` is applied in two
/// halves, and the intermediate value lies between `v` and the result.
#[inline]
pub(crate) fn scale_pow2(v: f64, e: i32) -> f64 {
    if (-1022..=1023).contains(&e) {
        v * f64::from_bits(((e + 1023) as u64) << 52)
    } else {
        // Split the scaling so no factor overflows.
        let half = e / 2;
        scale_pow2(scale_pow2(v, half), e - half)
    }
}

// ------------------------------------------------------------------------------------------
// lifted (power) test
// ------------------------------------------------------------------------------------------

/// Exact sign of the lifted determinant
/// `det[[p_i − q, ‖p_i − q‖² − (w_i − w_q)]]_{i=0..3}` (a 4×4 determinant).
///
/// When `p_0..p_3` are positively oriented ([`orient3d`] > 0), the sign is negative exactly
/// when `q` has negative power with respect to their orthosphere, i.e. `q` conflicts with
/// the tetrahedron in a regular triangulation; zero is the tie.
#[inline]
pub fn power_test(p: [&Point; 4], w: [f64; 4], q: &Point, wq: f64) -> i32 {
    match power_test_filter(p, w, q, wq) {
        Some(s) => s,
        None => power_test_exact(p, w, q, wq),
    }
}

/// The floating-point stage of [`power_test`]: the sign when the static error bound
/// certifies it.
#[inline]
pub(crate) fn power_test_filter(p: [&Point; 4], w: [f64; 4], q: &Point, wq: f64) -> Option<i32> {
    let a: [[f64; 3]; 4] =
        std::array::from_fn(|i| [p[i][0] - q[0], p[i][1] - q[1], p[i][2] - q[2]]);
    let dw: [f64; 4] = std::array::from_fn(|i| w[i] - wq);
    let lam: [f64; 4] =
        std::array::from_fn(|i| a[i][0] * a[i][0] + a[i][1] * a[i][1] + a[i][2] * a[i][2] - dw[i]);
    let lam_p: [f64; 4] = std::array::from_fn(|i| {
        a[i][0] * a[i][0] + a[i][1] * a[i][1] + a[i][2] * a[i][2] + dw[i].abs()
    });
    // 2×2 minors of the x, y columns.
    let m = |i: usize, j: usize| a[i][0] * a[j][1] - a[j][0] * a[i][1];
    let mp = |i: usize, j: usize| (a[i][0] * a[j][1]).abs() + (a[j][0] * a[i][1]).abs();
    let (m01, m02, m03, m12, m13, m23) = (m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3));
    let (p01, p02, p03, p12, p13, p23) =
        (mp(0, 1), mp(0, 2), mp(0, 3), mp(1, 2), mp(1, 3), mp(2, 3));
    let z = |i: usize| a[i][2];
    let za = |i: usize| a[i][2].abs();
    let d123 = z(1) * m23 - z(2) * m13 + z(3) * m12;
    let d023 = z(0) * m23 - z(2) * m03 + z(3) * m02;
    let d013 = z(0) * m13 - z(1) * m03 + z(3) * m01;
    let d012 = z(0) * m12 - z(1) * m02 + z(2) * m01;
    let e123 = za(1) * p23 + za(2) * p13 + za(3) * p12;
    let e023 = za(0) * p23 + za(2) * p03 + za(3) * p02;
    let e013 = za(0) * p13 + za(1) * p03 + za(3) * p01;
    let e012 = za(0) * p12 + za(1) * p02 + za(2) * p01;
    let det = -lam[0] * d123 + lam[1] * d023 - lam[2] * d013 + lam[3] * d012;
    let permanent = lam_p[0] * e123 + lam_p[1] * e023 + lam_p[2] * e013 + lam_p[3] * e012;
    let bound = LIFTED_BOUND * permanent + UNDERFLOW_SLACK;
    if det > bound {
        return Some(1);
    }
    if det < -bound {
        return Some(-1);
    }
    None
}

/// The exact stages of [`power_test`].
#[cold]
pub(crate) fn power_test_exact(p: [&Point; 4], w: [f64; 4], q: &Point, wq: f64) -> i32 {
    if let Some(s) = power_test_integer(p, w, q, wq) {
        return s;
    }
    LiftedDet { p, w, q, wq }.eval::<Expansion>().sign()
}

/// The sign of an exactly computed `f64` (0 for ±0).
#[inline(always)]
fn sign_of(v: f64) -> i32 {
    (v > 0.0) as i32 - (v < 0.0) as i32
}

/// Exact sign of the lifted determinant when the five centres lie on a grid of unit
/// `1 / inv_unit` (a power of two) and every difference `p_i − q` is below `2^9` units;
/// `None` otherwise (or when a weight difference is not exact in `f64`, or far out of
/// range). Equal weights make it the plain in-sphere determinant.
///
/// Why plain `f64` arithmetic is exact here: on such a grid the differences and their
/// scaling are exact, so every value of the in-sphere part is an integer, and each stays
/// below `2^53`: `‖a_i‖² < 3·2^18`, the 2×2 minors below `2^19`, the 3×3 cofactors `c_i`
/// below `3·2^28`, `x = Σ ‖a_i‖²·c_i` below `36·2^46`. The weight part `Σ δ_i·c_i` (with
/// `δ_i = (w_i − w_q)·inv_unit²`, exact) is summed exactly as error-free products. Octree and
/// voxel covers are full of exactly co-spherical cells: this settles those ties without the
/// wider `i128` and expansion stages.
#[inline(always)]
pub(crate) fn grid_lifted_sign(
    p: [&Point; 4],
    w: [f64; 4],
    q: &Point,
    wq: f64,
    inv_unit: f64,
) -> Option<i32> {
    let a: [[f64; 3]; 4] = std::array::from_fn(|i| {
        [
            (p[i][0] - q[0]) * inv_unit,
            (p[i][1] - q[1]) * inv_unit,
            (p[i][2] - q[2]) * inv_unit,
        ]
    });
    // `<` is false for NaN too.
    let mut small = true;
    for row in &a {
        for d in row {
            small &= d.abs() < 512.0;
        }
    }
    if !small {
        return None;
    }
    let sq = |i: usize| a[i][0] * a[i][0] + a[i][1] * a[i][1] + a[i][2] * a[i][2];
    let m = |i: usize, j: usize| a[i][0] * a[j][1] - a[j][0] * a[i][1];
    let (m01, m02, m03, m12, m13, m23) = (m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3));
    let z = |i: usize| a[i][2];
    // The signed cofactors of the lifted column, as in `lifted_sign_fixed`.
    let c = [
        -(z(1) * m23 - z(2) * m13 + z(3) * m12),
        z(0) * m23 - z(2) * m03 + z(3) * m02,
        -(z(0) * m13 - z(1) * m03 + z(3) * m01),
        z(0) * m12 - z(1) * m02 + z(2) * m01,
    ];
    let x = sq(0) * c[0] + sq(1) * c[1] + sq(2) * c[2] + sq(3) * c[3];
    if w.iter().all(|&wi| wi == wq) {
        return Some(sign_of(x));
    }
    grid_lifted_sign_weighted(x, c, w, wq, inv_unit)
}

/// The weighted end of [`grid_lifted_sign`]: `sign(x − Σ δ_i·c_i)`, every term exact (kept
/// out of line: the equal-weight case above is the hot one).
#[inline(never)]
fn grid_lifted_sign_weighted(
    x: f64,
    c: [f64; 4],
    w: [f64; 4],
    wq: f64,
    inv_unit: f64,
) -> Option<i32> {
    let scale = inv_unit * inv_unit;
    if !scale.is_normal() {
        return None;
    }
    let mut terms = [0.0f64; 9];
    terms[0] = x;
    for i in 0..4 {
        let dw = w[i] - wq;
        if !exact_diff(w[i], wq, dw) {
            return None;
        }
        let delta = dw * scale;
        // Far from under- and overflow, so that the scaling and the products are exact.
        if dw != 0.0 && !(delta.abs() > 1e-250 && delta.abs() < 1e250) {
            return None;
        }
        let (hi, lo) = two_product(delta, c[i]);
        terms[1 + 2 * i] = -hi;
        terms[2 + 2 * i] = -lo;
    }
    Some(exact_sign_of_sum(&terms))
}

/// The `i128` stage, for coordinate differences that are exact multiples `n·2^e` with
/// `|n| < 2^22` (grids, octrees). The 3×3 minors `D_i` and `Σ ±‖a_i‖²·D_i` are then exact
/// integers; the weight differences enter either as integers (multiples of `2^{2e}`) or as
/// exact `f64` products with the minors, summed exactly without allocation.
fn power_test_integer(p: [&Point; 4], w: [f64; 4], q: &Point, wq: f64) -> Option<i32> {
    let mut vals = [0.0; 12];
    for i in 0..4 {
        for k in 0..3 {
            let d = p[i][k] - q[k];
            if !exact_diff(p[i][k], q[k], d) {
                return None;
            }
            vals[3 * i + k] = d;
        }
    }
    let mut ints = [0i64; 12];
    let e = to_fixed(&vals, 22, &mut ints)?;
    lifted_sign_fixed(&ints, e, w, wq)
}

/// The exact sign of the lifted determinant from the coordinate differences `p_i − q` given
/// as integers `ints` (row-major, units of `2^e`, magnitudes below `2^22`) and the weights.
/// `None` when a weight difference is not exact in `f64` (then expansions decide).
pub(crate) fn lifted_sign_fixed(ints: &[i64; 12], e: i32, w: [f64; 4], wq: f64) -> Option<i32> {
    let mut dw = [0.0; 4];
    for i in 0..4 {
        dw[i] = w[i] - wq;
        if !exact_diff(w[i], wq, dw[i]) {
            return None;
        }
    }
    // Below 2^22 in magnitude: 2×2 minors fit in i64, the rest in i128.
    let a = |i: usize, k: usize| ints[3 * i + k];
    let sq = |i: usize| (a(i, 0) * a(i, 0) + a(i, 1) * a(i, 1) + a(i, 2) * a(i, 2)) as i128;
    let m = |i: usize, j: usize| (a(i, 0) * a(j, 1) - a(j, 0) * a(i, 1)) as i128;
    let (m01, m02, m03, m12, m13, m23) = (m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3));
    let z = |i: usize| a(i, 2) as i128;
    // Signed cofactors of the lifted column.
    let c = [
        -(z(1) * m23 - z(2) * m13 + z(3) * m12),
        z(0) * m23 - z(2) * m03 + z(3) * m02,
        -(z(0) * m13 - z(1) * m03 + z(3) * m01),
        z(0) * m12 - z(1) * m02 + z(2) * m01,
    ];
    let x: i128 = (0..4).map(|i| sq(i) * c[i]).sum();
    if dw.iter().all(|&d| d == 0.0) {
        return Some(x.signum() as i32);
    }
    // Weight differences in units of 2^{2e}, when they are small integers there.
    if 2 * e.abs() < 1000 {
        let scaled = dw.map(|d| scale_pow2(d, -2 * e));
        if scaled
            .iter()
            .all(|s| s.abs() < 70_368_744_177_664.0 && s.fract() == 0.0)
        {
            let lam_w: i128 = (0..4).map(|i| scaled[i] as i128 * c[i]).sum();
            return Some((x - lam_w).signum() as i32);
        }
        // Otherwise: sign(x·2^{2e} − Σ dw_i·c_i), all terms exact f64 values.
        let mut terms = [0.0f64; 19];
        let xs = split_i128(x);
        for k in 0..3 {
            terms[k] = scale_pow2(xs[k], 2 * e);
        }
        for i in 0..4 {
            let ci = split_i128(c[i]);
            for (j, &part) in ci[..2].iter().enumerate() {
                let (hi, lo) = two_product(dw[i], part);
                terms[3 + 4 * i + 2 * j] = -hi;
                terms[3 + 4 * i + 2 * j + 1] = -lo;
            }
            if ci[2] != 0.0 {
                return None;
            }
        }
        return Some(exact_sign_of_sum(&terms));
    }
    None
}

/// Splits an integer below `2^117` into three `f64` whose exact sum it is.
fn split_i128(x: i128) -> [f64; 3] {
    let hi = x as f64;
    let r1 = x - hi as i128;
    let mid = r1 as f64;
    let lo = (r1 - mid as i128) as f64;
    [hi, mid, lo]
}

#[inline]
fn two_product(a: f64, b: f64) -> (f64, f64) {
    let x = a * b;
    (x, a.mul_add(b, -x))
}

/// The exact sign of a sum of at most 32 `f64` terms (repeated exact growth of an expansion
/// in a fixed buffer).
fn exact_sign_of_sum(terms: &[f64]) -> i32 {
    let mut h = [0.0f64; 40];
    let mut len = 0;
    for &b in terms {
        if b == 0.0 {
            continue;
        }
        let mut q = b;
        let mut k = 0;
        for i in 0..len {
            let s = q + h[i];
            let b_virtual = s - q;
            let a_virtual = s - b_virtual;
            let err = (q - a_virtual) + (h[i] - b_virtual);
            q = s;
            if err != 0.0 {
                h[k] = err;
                k += 1;
            }
        }
        if q != 0.0 {
            h[k] = q;
            k += 1;
        }
        len = k;
    }
    if len == 0 {
        0
    } else if h[len - 1] > 0.0 {
        1
    } else {
        -1
    }
}

struct LiftedDet<'a> {
    p: [&'a Point; 4],
    w: [f64; 4],
    q: &'a Point,
    wq: f64,
}

impl LiftedDet<'_> {
    fn eval<R: Ring>(&self) -> R {
        let a: [[R; 3]; 4] = std::array::from_fn(|i| {
            std::array::from_fn(|k| R::input_diff(self.p[i][k], self.q[k]))
        });
        let lam: [R; 4] =
            std::array::from_fn(|i| dot3(&a[i], &a[i]).sub(&R::input_diff(self.w[i], self.wq)));
        let d123 = det3(&a[1], &a[2], &a[3]);
        let d023 = det3(&a[0], &a[2], &a[3]);
        let d013 = det3(&a[0], &a[1], &a[3]);
        let d012 = det3(&a[0], &a[1], &a[2]);
        lam[1]
            .mul(&d023)
            .sub(&lam[0].mul(&d123))
            .sub(&lam[2].mul(&d013))
            .add(&lam[3].mul(&d012))
    }
}

/// Whether `q` is in conflict with the positively oriented tetrahedron `p` (its power with
/// respect to the orthosphere is negative), ties broken by the symbolic perturbation.
/// The five points must be distinct.
#[inline]
pub fn in_power_sphere_sos(p: [&Point; 4], w: [f64; 4], q: &Point, wq: f64) -> bool {
    let s = power_test(p, w, q, wq);
    if s != 0 {
        return s < 0;
    }
    let pt = |i: usize| if i == 4 { q } else { p[i] };
    let mut order = [0usize, 1, 2, 3, 4];
    order.sort_unstable_by(|&i, &j| {
        let (a, b) = (pt(i), pt(j));
        (a[0], a[1], a[2])
            .partial_cmp(&(b[0], b[1], b[2]))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut rank = [0u32; 5];
    for (r, &i) in order.iter().enumerate() {
        rank[i] = r as u32;
    }
    power_sphere_perturbed(p, q, rank)
}

/// Decides a tie of [`power_test`] (a zero result) for the positively oriented `p` and the
/// query `q` by the symbolic perturbation, given the lexicographic ranks of the five points
/// (`rank[4]` is the query's; any numbers ordered as the points are): from the largest point
/// down, the query loses if it is the largest, otherwise the orientation of the cell with
/// that point replaced by the query decides.
#[cold]
pub fn power_sphere_perturbed(p: [&Point; 4], q: &Point, rank: [u32; 5]) -> bool {
    let mut visited = [false; 5];
    for _ in 0..5 {
        let mut i = 5;
        for j in 0..5 {
            if !visited[j] && (i == 5 || rank[j] > rank[i]) {
                i = j;
            }
        }
        if i == 4 {
            return false;
        }
        visited[i] = true;
        let mut r = p;
        r[i] = q;
        let o = orient3d(r[0], r[1], r[2], r[3]);
        if o != 0 {
            return o > 0;
        }
    }
    // Unreachable for distinct points: the cell itself is not flat.
    false
}

// ------------------------------------------------------------------------------------------
// coplanar (power circle) test, for queries on the plane of a hull facet
// ------------------------------------------------------------------------------------------

struct PowerCircle<'a> {
    a: &'a Point,
    b: &'a Point,
    c: &'a Point,
    q: &'a Point,
    w: [f64; 4],
}

impl PowerCircle<'_> {
    /// `det[[⟨e_b,e_b⟩, ⟨e_b,e_c⟩, α_b], [⟨e_c,e_b⟩, ⟨e_c,e_c⟩, α_c], [⟨e_q,e_b⟩, ⟨e_q,e_c⟩, α_q]]`
    /// with `e_x = x − a`, `α_x = ‖e_x‖² + w_a − w_x`: the power of `q` with respect to the
    /// power circle of `abc` times the (positive) Gram determinant, when `q` is coplanar.
    fn eval<R: Ring>(&self) -> R {
        let e = |x: &Point| -> [R; 3] { std::array::from_fn(|k| R::input_diff(x[k], self.a[k])) };
        let (eb, ec, eq) = (e(self.b), e(self.c), e(self.q));
        let alpha = |ex: &[R; 3], wx: f64| dot3(ex, ex).add(&R::input_diff(self.w[0], wx));
        let row = |ex: &[R; 3], wx: f64| [dot3(ex, &eb), dot3(ex, &ec), alpha(ex, wx)];
        det3(
            &row(&eb, self.w[1]),
            &row(&ec, self.w[2]),
            &row(&eq, self.w[3]),
        )
    }
}

/// Exact in-plane orientation of `(a, b, c)` projected along `axis` (dropping that coordinate).
fn orient2d_projected(a: &Point, b: &Point, c: &Point, axis: usize) -> i32 {
    let (i, j) = match axis {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    };
    let e = det2(
        &Expansion::diff(b[i], a[i]),
        &Expansion::diff(b[j], a[j]),
        &Expansion::diff(c[i], a[i]),
        &Expansion::diff(c[j], a[j]),
    );
    e.sign()
}

/// Whether `a`, `b`, `c` lie on one line (exact).
pub fn collinear(a: &Point, b: &Point, c: &Point) -> bool {
    (0..3).all(|axis| orient2d_projected(a, b, c, axis) == 0)
}

/// Whether `q`, coplanar with the non-collinear `a, b, c`, is in conflict with their power
/// circle (the 2D regular triangulation on a hull facet's plane), ties broken by the same
/// symbolic perturbation as [`in_power_sphere_sos`]. `w` holds the weights of `a, b, c, q`.
pub fn in_power_circle_sos(a: &Point, b: &Point, c: &Point, q: &Point, w: [f64; 4]) -> bool {
    let s = PowerCircle { a, b, c, q, w }.eval::<Expansion>().sign();
    if s != 0 {
        return s < 0;
    }
    // In-plane orientations, measured in a projection where abc is not flat.
    let tri = [a, b, c];
    let Some((axis, base)) = (0..3).find_map(|axis| {
        let o = orient2d_projected(a, b, c, axis);
        (o != 0).then_some((axis, o))
    }) else {
        return false;
    };
    let mut order = [0usize, 1, 2, 3];
    let pt = |i: usize| if i == 3 { q } else { tri[i] };
    order.sort_unstable_by(|&i, &j| {
        let (x, y) = (pt(i), pt(j));
        (x[0], x[1], x[2])
            .partial_cmp(&(y[0], y[1], y[2]))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    for &i in order.iter().rev() {
        if i == 3 {
            return false;
        }
        let mut r = tri;
        r[i] = q;
        let o = orient2d_projected(r[0], r[1], r[2], axis);
        if o != 0 {
            return o == base;
        }
    }
    false
}

// ------------------------------------------------------------------------------------------
// orthocentre power (the dual-complex filter)
// ------------------------------------------------------------------------------------------

struct OrthoPower<'a> {
    p: [&'a Point; 4],
    w: [f64; 4],
}

impl OrthoPower<'_> {
    /// `‖N‖² − 4·det²·w_0`, where the orthocentre is `p_0 + N / (2·det)`: its sign is the sign
    /// of the orthocentre's power `‖x* − p_i‖² − w_i`.
    fn eval<R: Ring>(&self) -> R {
        let p = self.p;
        let e = |i: usize| -> [R; 3] { std::array::from_fn(|k| R::input_diff(p[i][k], p[0][k])) };
        let (b, c, d) = (e(1), e(2), e(3));
        let alpha = |x: &[R; 3], i: usize| dot3(x, x).add(&R::input_diff(self.w[0], self.w[i]));
        let (ab, ac, ad) = (alpha(&b, 1), alpha(&c, 2), alpha(&d, 3));
        let cross = |u: &[R; 3], v: &[R; 3]| -> [R; 3] {
            [
                u[1].mul(&v[2]).sub(&u[2].mul(&v[1])),
                u[2].mul(&v[0]).sub(&u[0].mul(&v[2])),
                u[0].mul(&v[1]).sub(&u[1].mul(&v[0])),
            ]
        };
        let (cd, db, bc) = (cross(&c, &d), cross(&d, &b), cross(&b, &c));
        let n: [R; 3] =
            std::array::from_fn(|k| ab.mul(&cd[k]).add(&ac.mul(&db[k])).add(&ad.mul(&bc[k])));
        let det = dot3(&b, &cd);
        let four_w = R::input(4.0 * self.w[0]);
        dot3(&n, &n).sub(&det.mul(&det).mul(&four_w))
    }
}

/// Exact sign of the power of the orthocentre of the non-flat tetrahedron `p` (weights `w`):
/// negative when the four balls share interior points lying in no other of the four's
/// complement (the lifted 4D spheres of thesis §3.5 meet), zero when they touch at one point.
pub fn orthocentre_power_sign(p: [&Point; 4], w: [f64; 4]) -> i32 {
    // Static filter: the polynomial of `OrthoPower` in f64, with its permanent. The longest
    // chain of roundings is 30 steps; 34u leaves slack for rounding the permanent itself.
    let o = p[0];
    let e = |i: usize| [p[i][0] - o[0], p[i][1] - o[1], p[i][2] - o[2]];
    let (b, c, d) = (e(1), e(2), e(3));
    let sq = |x: [f64; 3]| x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    let (ab, ac, ad) = (
        sq(b) + (w[0] - w[1]),
        sq(c) + (w[0] - w[2]),
        sq(d) + (w[0] - w[3]),
    );
    let (pab, pac, pad) = (
        sq(b) + (w[0] - w[1]).abs(),
        sq(c) + (w[0] - w[2]).abs(),
        sq(d) + (w[0] - w[3]).abs(),
    );
    let cross = |u: [f64; 3], v: [f64; 3]| {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    };
    let cross_p = |u: [f64; 3], v: [f64; 3]| {
        [
            (u[1] * v[2]).abs() + (u[2] * v[1]).abs(),
            (u[2] * v[0]).abs() + (u[0] * v[2]).abs(),
            (u[0] * v[1]).abs() + (u[1] * v[0]).abs(),
        ]
    };
    let (cd, db, bc) = (cross(c, d), cross(d, b), cross(b, c));
    let (pcd, pdb, pbc) = (cross_p(c, d), cross_p(d, b), cross_p(b, c));
    let n: [f64; 3] = std::array::from_fn(|k| ab * cd[k] + ac * db[k] + ad * bc[k]);
    let pn: [f64; 3] = std::array::from_fn(|k| pab * pcd[k] + pac * pdb[k] + pad * pbc[k]);
    let det = b[0] * cd[0] + b[1] * cd[1] + b[2] * cd[2];
    let pdet = b[0].abs() * pcd[0] + b[1].abs() * pcd[1] + b[2].abs() * pcd[2];
    let value = sq(n) - det * det * (4.0 * w[0]);
    let permanent = sq(pn) + pdet * pdet * (4.0 * w[0].abs());
    let bound = 34.0 * U * permanent;
    // Degree-8 terms can underflow for tiny tetrahedra: leave those to the exact path.
    if permanent > 1e-200 && permanent < 1e200 {
        if value > bound {
            return 1;
        }
        if value < -bound {
            return -1;
        }
    }
    let f = OrthoPower { p, w };
    if let Some(s) = f.eval::<crate::expansion::Bounded>().certain_sign() {
        return s;
    }
    f.eval::<Expansion>().sign()
}

/// The orthocentre of the tetrahedron `p` with weights `w` (the point of equal power to the
/// four), in floating point, and its power. `None` when the tetrahedron is flat.
pub fn orthocentre(p: [&Point; 4], w: [f64; 4]) -> Option<(Point, f64)> {
    let o = p[0];
    let e = |i: usize| [p[i][0] - o[0], p[i][1] - o[1], p[i][2] - o[2]];
    let (b, c, d) = (e(1), e(2), e(3));
    let alpha = |x: [f64; 3], i: usize| x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + w[0] - w[i];
    let cross = |u: [f64; 3], v: [f64; 3]| {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    };
    let (cd, db, bc) = (cross(c, d), cross(d, b), cross(b, c));
    let det = b[0] * cd[0] + b[1] * cd[1] + b[2] * cd[2];
    if det == 0.0 {
        return None;
    }
    let (ab, ac, ad) = (alpha(b, 1), alpha(c, 2), alpha(d, 3));
    let s = 0.5 / det;
    let u: [f64; 3] = std::array::from_fn(|k| (ab * cd[k] + ac * db[k] + ad * bc[k]) * s);
    let x = [o[0] + u[0], o[1] + u[1], o[2] + u[2]];
    let power = u[0] * u[0] + u[1] * u[1] + u[2] * u[2] - w[0];
    Some((x, power))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orient_convention() {
        let o = [0.0, 0.0, 0.0];
        let x = [1.0, 0.0, 0.0];
        let y = [0.0, 1.0, 0.0];
        let z = [0.0, 0.0, 1.0];
        assert_eq!(orient3d(&o, &x, &y, &z), 1);
        assert_eq!(orient3d(&o, &y, &x, &z), -1);
        assert_eq!(orient3d(&o, &x, &y, &[3.0, 7.0, 0.0]), 0);
    }

    #[test]
    fn centre_is_in_conflict_and_far_point_is_not() {
        let o = [0.0, 0.0, 0.0];
        let x = [1.0, 0.0, 0.0];
        let y = [0.0, 1.0, 0.0];
        let z = [0.0, 0.0, 1.0];
        let w = [0.0; 4];
        assert!(power_test([&o, &x, &y, &z], w, &[0.2, 0.2, 0.2], 0.0) < 0);
        assert!(power_test([&o, &x, &y, &z], w, &[5.0, 5.0, 5.0], 0.0) > 0);
        // A heavy query far away conflicts.
        assert!(power_test([&o, &x, &y, &z], w, &[5.0, 5.0, 5.0], 1000.0) < 0);
        // Co-spherical: the corner (1,1,1) of the unit cube.
        assert_eq!(power_test([&o, &x, &y, &z], w, &[1.0, 1.0, 1.0], 0.0), 0);
    }

    #[test]
    fn grid_lifted_sign_is_the_exact_power_test() {
        // Points on a grid of unit 1/8 (spans up to 600 units: both sides of the 2^9 limit),
        // weights equal or of octree levels (w, 4w, 16w) or zero: the grid stage, when it
        // answers, agrees with the staged predicate, ties included.
        let mut rng = sphcover_core::random::SplitMix64::new(3);
        let (mut answered, mut ties) = (0, 0);
        for round in 0..40_000 {
            let span = [4u64, 40, 600][rng.below(3) as usize];
            let mut pt = || std::array::from_fn(|_| (rng.below(span) as f64 - 7.0) * 0.125);
            let (a, b, c, d, q): (Point, Point, Point, Point, Point) =
                (pt(), pt(), pt(), pt(), pt());
            let base = 0.3 * 0.75f64.sqrt();
            let levels = [base, 4.0 * base, 16.0 * base, 0.0];
            let mut weight = || {
                if round % 2 == 0 {
                    base
                } else {
                    levels[rng.below(4) as usize]
                }
            };
            let (w, wq) = ([weight(), weight(), weight(), weight()], weight());
            let expected = power_test([&a, &b, &c, &d], w, &q, wq);
            if let Some(s) = grid_lifted_sign([&a, &b, &c, &d], w, &q, wq, 8.0) {
                assert_eq!(s, expected, "{a:?} {b:?} {c:?} {d:?} {q:?} {w:?} {wq}");
                answered += 1;
                ties += (s == 0) as u32;
            }
        }
        assert!(
            answered > 20_000 && ties > 100,
            "{answered} answered, {ties} ties"
        );
    }

    #[test]
    fn grid_orientation_is_the_exact_orientation() {
        // Grids of unit 2^e for e in {-300, -3, 0, 40, 300} (the range the triangulation uses
        // it for), spans on both sides of the 2^16 limit and tiny ones (many coplanar
        // quadruples): when it answers it agrees with the staged predicate, zeros included.
        let mut rng = sphcover_core::random::SplitMix64::new(7);
        let (mut answered, mut zeros) = (0, 0);
        for round in 0..40_000 {
            let e = [-300, -3, 0, 40, 300][round % 5];
            let unit = 2f64.powi(e);
            let span = [3u64, 50, 70_000][rng.below(3) as usize];
            let offset = (span / 2) as f64;
            let mut pt = || std::array::from_fn(|_| (rng.below(span) as f64 - offset) * unit);
            let (a, b, c, d): (Point, Point, Point, Point) = (pt(), pt(), pt(), pt());
            if let Some(s) = orient3d_grid(&a, &b, &c, &d, 65536.0 * unit) {
                assert_eq!(s, orient3d(&a, &b, &c, &d), "{a:?} {b:?} {c:?} {d:?} 2^{e}");
                answered += 1;
                zeros += (s == 0) as u32;
            }
        }
        assert!(
            answered > 20_000 && zeros > 1000,
            "{answered} answered, {zeros} zeros"
        );
    }

    #[test]
    fn orthocentre_power_of_unit_tet() {
        let o = [0.0, 0.0, 0.0];
        let x = [1.0, 0.0, 0.0];
        let y = [0.0, 1.0, 0.0];
        let z = [0.0, 0.0, 1.0];
        // Circumcentre (0.5,0.5,0.5), squared circumradius 0.75.
        assert_eq!(orthocentre_power_sign([&o, &x, &y, &z], [0.75; 4]), 0);
        assert_eq!(orthocentre_power_sign([&o, &x, &y, &z], [0.76; 4]), -1);
        assert_eq!(orthocentre_power_sign([&o, &x, &y, &z], [0.74; 4]), 1);
        let (c, pw) = orthocentre([&o, &x, &y, &z], [0.0; 4]).unwrap();
        assert!((c[0] - 0.5).abs() < 1e-15 && (pw - 0.75).abs() < 1e-15);
    }
}
