//! The input domain of the triangulation: where the predicates are exact, and the
//! power-of-two scaling that brings an input there.
//!
//! # Why the predicates have a domain
//!
//! Every predicate the construction and the dual complex evaluate is the sign of a polynomial
//! in coordinate differences and weights, computed in stages (see [`crate::predicates`]): a
//! float filter with a static relative error bound, exact `f64` and `i128` stages on dyadic
//! grids, a running-error evaluation ([`crate::expansion::Bounded`]) and Shewchuk's expansions.
//! Each stage is exact, or its bound rigorous, only while no value it forms underflows into
//! the subnormal range (Shewchuk's error-free transformations assume it never does; an
//! underflowed product of differences silently loses its low digits) or overflows.
//!
//! # Terms and their degrees
//!
//! A coordinate is a length and a weight `r²` a squared length. Every value a predicate forms
//! is a sum of terms `Δ^c·ω^w`: a product of `c` coordinate differences and `w` weights or
//! weight differences. The predicates, with the terms of their largest values:
//!
//! | predicate | terms `(c, w)` | used by |
//! |---|---|---|
//! | orient2d (collinearity) | `(2, 0)` | the first tetrahedron (`insert.rs`) |
//! | orient3d | `(3, 0)` | the walk, the perturbation, the checks |
//! | lifted power test | `(5, 0)`, `(3, 1)` | the conflict test (`conflict.rs`) |
//! | power circle | `(6, 0)`, `(4, 1)` | public only ([`crate::predicates::in_power_circle_sos`]) |
//! | orthocentre power `‖N‖² − 4·det²·w₀` | `(8, 0)`, `(6, 1)`, `(4, 2)` | the dual complex (`dual_complex.rs`) |
//!
//! Partial results have smaller terms (`(1, 0)`, `(0, 1)`, `(2, 1)`, …). Every term that
//! occurs lies in the convex hull of `(1, 0)`, `(0, 1)`, `(8, 0)` and `(4, 2)`, and a bound
//! that is linear in `(c, w)` in the logarithm holds for all terms once it holds at these four
//! corners. A triangulation's points and weights feed [`crate::dual_complex_of`] unchanged,
//! so the orthocentre power's terms are part of the domain.
//!
//! # Digits: no underflow
//!
//! Let every nonzero coordinate be an integer multiple of `2^L` and every nonzero weight one
//! of `2^M` (their *finest digits*). An exact sum, difference or product made of terms
//! `(c, w)` is an integer multiple of `2^{cL + wM}`, and rounding a nonzero multiple of a
//! normal power of two to `f64` gives a nonzero multiple of it again. So if `cL + wM ≥ −1022`
//! at the four corners, every nonzero value any stage forms (filter products, expansion
//! components, the halves of Dekker's split and the tails of exact products) is at least
//! `2^-1022` in magnitude: nothing is ever subnormal.
//!
//! # Magnitudes: no overflow
//!
//! Let every coordinate be below `2^E` in magnitude and every weight below `2^F`. A coordinate
//! difference is below `D = 2^{E+1}`, a weight difference below `W = 2^{F+1}`. The largest
//! polynomial is the orthocentre power (`predicates::OrthoPower`): `|α| ≤ 3D² + W`, each
//! cross product entry `≤ 2D²`, `|N_k| ≤ 6D²·(3D² + W)`, `4·det²·|w₀| ≤ 72·D⁶·W`; the sum of
//! the absolute values of its terms is at most `1800` times the largest of `D⁸`, `D⁶W`,
//! `D⁴W²`, below `2^11` times the largest corner term, and every other predicate's sum is
//! smaller. An expansion's components and running sums stay below twice the absolute sum of
//! the terms it holds, and Dekker's split multiplies a component by `2^27 + 1 < 2^28`: so with
//! `c(E + 1) + w(F + 1) ≤ 983` at the four corners every value stays below `2^1023`.
//!
//! The `f64` and `i128` stages for dyadic grids check their own ranges; inside these bounds
//! their rescalings of weight differences by the grid unit (at most `2^{±2(E+1)}`) stay normal
//! too, as `(4, 2)` keeps `M ≥ −511 − 2L`.
//!
//! # The scaling
//!
//! Multiplying every coordinate by `2^k` and every weight by `2^{2k}` moves `E` and `L` by `k`,
//! `F` and `M` by `2k`, and is exact while nothing over- or underflows. It changes no
//! decision of the construction: each predicate is homogeneous (a term `(c, w)` scales by
//! `2^{(c+2w)k}`, the same for all terms of one polynomial), the lexicographic ranks and equal
//! centres are the same, and the Hilbert keys of the insertion order are computed from
//! differences and ratios that scale without rounding. Each corner then bounds `k` from one
//! side, `(c + 2w)·k ≥ −1022 − cL − wM` and `(c + 2w)·k ≤ 983 − c(E + 1) − w(F + 1)`, and an
//! input is in the domain when some `k` satisfies all of them.
//!
//! For coordinates alone, `(8, 0)` gives `−127 − L ≤ k ≤ 121 − E`: they may span `E − L ≤ 248`
//! binary digits, about 74 decimal orders of magnitude, from the largest magnitude down to
//! the finest digit (one `f64` spans 53; unit-size coordinates with round-off residues of
//! `1e-30` span about 150). Beyond that they are refused with [`TetraError::CoordinateSpan`].
//! Weights enter through `(0, 1)` and `(4, 2)`: beside coordinates below 1 with digits down
//! to `2^-53` (uniform random doubles, `fixtures/tetra/random_3k`), radii from about `1e-117`
//! to `1e116` fit. Beyond, [`TetraError::RadiusScale`] names the radius too large or too
//! small for the coordinates. When the weights are formed from radii after the
//! scaling (the dual complex), the radii themselves must also scale exactly.
//!
//! Of the admissible `k`, we take the one nearest to putting the largest coordinate in
//! `[1/2, 1)`. The choice depends only on the exponents, which a power-of-two scaling of the
//! input moves by the same amount: scaled copies of an input become the same `f64` values and
//! give the same triangulation. Inputs already of that size are not changed at all, and at that
//! size the filters' absolute thresholds (the `1e-220` slack of the orientation and power
//! filters, the `1e±200` window of the orthocentre filter) send as few cases as possible to the
//! exact stages.

use crate::error::TetraError;
use crate::predicates::Point;

/// Nonzero values must stay at least `2^MIN_LOG2` in magnitude: the smallest normal `f64`.
const MIN_LOG2: i32 = -1022;
/// The bound on the largest term's exponent: below `2^1023` after the factor `2^12` of the
/// sums and `2^28` of Dekker's splitter.
const MAX_LOG2: i32 = 983;
/// The corners `(c, w)` of the terms the predicates form (module docs).
const CORNERS: [(i32, i32); 4] = [(1, 0), (0, 1), (8, 0), (4, 2)];
/// The binary digits coordinates alone may span: from the corner `(8, 0)`,
/// `(k ≥ −127 − L) ∧ (k ≤ 121 − E)`.
const MAX_SPAN_BITS: i32 = (MAX_LOG2 / 8 - 1) - (MIN_LOG2 / 8);

/// The binary extent of a set of values: every one below `2^high` in magnitude and an integer
/// multiple of `2^low`, with the indices of the values that set the two bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Extent {
    high: i32,
    high_index: usize,
    low: i32,
    low_index: usize,
}

impl Extent {
    /// The extent of one finite nonzero value: `|x| < 2^high` (the least such), and `2^low` its
    /// lowest set bit.
    fn of_value(x: f64, index: usize) -> Self {
        let raw = x.to_bits() & !(1u64 << 63);
        let biased = (raw >> 52) as i32;
        let fraction = raw & ((1u64 << 52) - 1);
        let (significand, exponent) = if biased == 0 {
            // Subnormal: fraction · 2^-1074.
            (fraction, -1074)
        } else {
            (fraction | (1u64 << 52), biased - 1075)
        };
        Extent {
            high: exponent + 64 - significand.leading_zeros() as i32,
            high_index: index,
            low: exponent + significand.trailing_zeros() as i32,
            low_index: index,
        }
    }

    /// The extent of the nonzero values (`None` when all are zero), indexed by `index_of`
    /// their position.
    fn of_values(
        values: impl Iterator<Item = f64>,
        index_of: impl Fn(usize) -> usize,
    ) -> Option<Self> {
        values
            .enumerate()
            .filter(|(_, x)| *x != 0.0)
            .map(|(i, x)| Self::of_value(x, index_of(i)))
            .reduce(|a, b| Extent {
                high: a.high.max(b.high),
                high_index: if b.high > a.high {
                    b.high_index
                } else {
                    a.high_index
                },
                low: a.low.min(b.low),
                low_index: if b.low < a.low {
                    b.low_index
                } else {
                    a.low_index
                },
            })
    }
}

/// `2^e` for a normal or subnormal exponent `e` (−1074..=1023), exactly.
fn pow2(e: i32) -> f64 {
    if e >= -1022 {
        f64::from_bits(((e + 1023) as u64) << 52)
    } else {
        f64::from_bits(1u64 << (e + 1074))
    }
}

/// One side of the admissible scalings: `slope·k ≥ limit` (a lower bound) or `slope·k ≤
/// limit` (an upper one), and whether the weights (or radii) take part in it.
#[derive(Clone, Copy, Debug)]
struct Side {
    slope: i32,
    limit: i32,
    weights: bool,
}

impl Side {
    /// The least `k` it admits, as a lower bound.
    fn least(self) -> i32 {
        -(-self.limit).div_euclid(self.slope)
    }

    /// The largest `k` it admits, as an upper bound.
    fn most(self) -> i32 {
        self.limit.div_euclid(self.slope)
    }
}

/// The input as the domain sees it: the extents of the coordinates and of the weights (in
/// the caller's units), and for weights formed from radii after the scaling, the radii's own
/// extent (they must scale exactly too).
struct Input<'a> {
    points: &'a [Point],
    coordinates: Option<Extent>,
    weights: Option<Extent>,
    radii: Option<Extent>,
    /// The radius of weight or sphere `i`, for the error message.
    radius_of: &'a dyn Fn(usize) -> f64,
}

/// The coordinates' extent, indexed by point, after refusing non-finite ones.
fn coordinate_extent(points: &[Point]) -> Result<Option<Extent>, TetraError> {
    if let Some(index) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(TetraError::InvalidPoint { index });
    }
    Ok(Extent::of_values(points.iter().flatten().copied(), |i| {
        i / 3
    }))
}

/// The exponent `k` that brings `points` and `weights` into the exact range (coordinates
/// times `2^k`, weights times `2^{2k}`), or why there is none.
pub(super) fn scale_for_weights(points: &[Point], weights: &[f64]) -> Result<i32, TetraError> {
    let coordinates = coordinate_extent(points)?;
    if let Some(index) = weights.iter().position(|w| !w.is_finite()) {
        return Err(TetraError::InvalidWeight { index });
    }
    choose(&Input {
        points,
        coordinates,
        weights: Extent::of_values(weights.iter().copied(), |i| i),
        radii: None,
        radius_of: &|i| weights[i].abs().sqrt(),
    })
}

/// The exponent `k` that brings `points` and the weights `(shrink·r·2^k)²` into the exact
/// range, the weights formed after the scaling (so that radii whose squares would under- or
/// overflow in the caller's units still work), or why there is none. `radii` are finite and
/// non-negative, `shrink` finite and positive.
pub(super) fn scale_for_radii(
    points: &[Point],
    radii: &[f64],
    shrink: f64,
) -> Result<i32, TetraError> {
    let coordinates = coordinate_extent(points)?;
    let r = Extent::of_values(radii.iter().copied(), |i| i);
    let s = Extent::of_value(shrink, 0);
    // `shrink·r` is below 2^(high_r + high_s) before rounding and at most that after, a
    // multiple of 2^(low_r + low_s); its square is below twice the square of that bound.
    let weights = r.map(|r| Extent {
        high: 2 * (r.high + s.high) + 1,
        low: 2 * (r.low + s.low),
        ..r
    });
    choose(&Input {
        points,
        coordinates,
        weights,
        radii: r,
        radius_of: &|i| radii[i],
    })
}

/// The admissible scaling nearest to the largest coordinate in `[1/2, 1)` (module docs), or
/// the typed reason there is none.
fn choose(input: &Input<'_>) -> Result<i32, TetraError> {
    let Some(c) = input.coordinates else {
        // All centres at the origin: at most one distinct centre, no predicate is ever
        // evaluated, and the construction reports the missing dimensions.
        return Ok(0);
    };
    let mut lower = Vec::with_capacity(6);
    let mut upper = Vec::with_capacity(6);
    for (cd, wd) in CORNERS {
        if wd > 0 && input.weights.is_none() {
            continue;
        }
        let w = input.weights.unwrap_or(c);
        // The corner's finest digit and largest magnitude, unscaled.
        let (digit, magnitude) = if wd == 0 {
            (cd * c.low, cd * (c.high + 1))
        } else if cd == 0 {
            (wd * w.low, wd * (w.high + 1))
        } else {
            (
                cd * c.low + wd * w.low,
                cd * (c.high + 1) + wd * (w.high + 1),
            )
        };
        let slope = cd + 2 * wd;
        let weights = wd > 0;
        lower.push(Side {
            slope,
            limit: MIN_LOG2 - digit,
            weights,
        });
        upper.push(Side {
            slope,
            limit: MAX_LOG2 - magnitude,
            weights,
        });
    }
    if let Some(r) = input.radii {
        // Radii scaled before the weights are formed: r·2^k normal and finite.
        lower.push(Side {
            slope: 1,
            limit: MIN_LOG2 - r.low,
            weights: true,
        });
        upper.push(Side {
            slope: 1,
            limit: 1023 - r.high,
            weights: true,
        });
    }
    let tightest_lower = lower
        .iter()
        .copied()
        .max_by_key(|s| s.least())
        .expect("the coordinate corners are always present");
    let tightest_upper = upper
        .iter()
        .copied()
        .min_by_key(|s| s.most())
        .expect("the coordinate corners are always present");
    let (lowest, highest) = (tightest_lower.least(), tightest_upper.most());
    if lowest <= highest {
        return Ok((-c.high).clamp(lowest, highest));
    }
    if !tightest_lower.weights && !tightest_upper.weights {
        let bits = c.high - c.low;
        return Err(TetraError::CoordinateSpan {
            orders: (bits as f64 * std::f64::consts::LOG10_2).round() as u32,
            max_orders: (MAX_SPAN_BITS as f64 * std::f64::consts::LOG10_2).floor() as u32,
            largest: largest_coordinate(input.points, c),
            largest_point: c.high_index,
            finest_digit: pow2(c.low),
            finest_point: c.low_index,
        });
    }
    // The weights stretch the range past its top (too large) or its bottom (too small). When
    // both bounds involve them, the one that conflicts with the coordinates alone is named,
    // failing that the top.
    let too_large = if tightest_lower.weights && tightest_upper.weights {
        let coordinates_lowest = lower.iter().filter(|s| !s.weights).map(|s| s.least()).max();
        let coordinates_highest = upper.iter().filter(|s| !s.weights).map(|s| s.most()).min();
        coordinates_lowest.is_some_and(|l| l > highest)
            || coordinates_highest.is_none_or(|h| lowest <= h)
    } else {
        tightest_upper.weights
    };
    let w = input.weights.expect("a bound involving weights exists");
    let index = if too_large { w.high_index } else { w.low_index };
    Err(TetraError::RadiusScale {
        index,
        radius: (input.radius_of)(index),
        too_large,
        largest_coordinate: largest_coordinate(input.points, c),
        finest_coordinate_digit: pow2(c.low),
    })
}

/// The largest coordinate magnitude, read from the point that sets `c.high`.
fn largest_coordinate(points: &[Point], c: Extent) -> f64 {
    points[c.high_index]
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extent_of_values() {
        let e = Extent::of_value(1.0, 0);
        assert_eq!((e.high, e.low), (1, 0));
        let e = Extent::of_value(-0.75, 0);
        assert_eq!((e.high, e.low), (0, -2));
        let e = Extent::of_value(f64::MIN_POSITIVE, 0);
        assert_eq!((e.high, e.low), (-1021, -1022));
        let e = Extent::of_value(f64::from_bits(6), 0);
        assert_eq!((e.high, e.low), (-1071, -1073));
        let e = Extent::of_value(f64::MAX, 0);
        assert_eq!((e.high, e.low), (1024, 971));
        let e = Extent::of_values([0.0, 12.0, 0.375].into_iter(), |i| i).unwrap();
        assert_eq!((e.high, e.high_index, e.low, e.low_index), (4, 1, -3, 2));
        assert_eq!(Extent::of_values([0.0, -0.0].into_iter(), |i| i), None);
    }

    #[test]
    fn pow2_is_exact_down_to_the_smallest_subnormal() {
        assert_eq!(pow2(0), 1.0);
        assert_eq!(pow2(-1022), f64::MIN_POSITIVE);
        assert_eq!(pow2(-1074), f64::from_bits(1));
        assert_eq!(pow2(1023), 2f64.powi(1023));
    }

    #[test]
    fn sides_round_inwards() {
        let s = Side {
            slope: 8,
            limit: -1021,
            weights: false,
        };
        assert_eq!(s.least(), -127);
        assert_eq!(s.most(), -128);
        let s = Side {
            slope: 8,
            limit: 975,
            weights: false,
        };
        assert_eq!((s.least(), s.most()), (122, 121));
        let s = Side {
            slope: 8,
            limit: 976,
            weights: false,
        };
        assert_eq!((s.least(), s.most()), (122, 122));
    }

    #[test]
    fn unit_inputs_are_not_scaled_and_scaled_copies_shift_the_exponent() {
        let p = [[0.5, 0.25, 0.125], [0.9, 0.1, 0.3]];
        let w = [0.01, 0.02];
        assert_eq!(scale_for_weights(&p, &w), Ok(0));
        for k in [-1000, -130, -3, 5, 600, 1000] {
            let pk: Vec<Point> = p.iter().map(|x| x.map(|c| c * 2f64.powi(k))).collect();
            // The weights would leave the f64 range at 2^(2k); formed from radii they need not.
            assert_eq!(scale_for_radii(&pk, &[0.1 * 2f64.powi(k); 2], 0.75), Ok(-k));
        }
        // Largest coordinate 1: scaled into [1/2, 1).
        assert_eq!(scale_for_weights(&[[1.0, 0.0, 0.0]], &[0.0]), Ok(-1));
        assert_eq!(scale_for_weights(&[[0.0; 3]], &[0.0]), Ok(0));
    }

    #[test]
    fn coordinates_may_span_248_binary_digits() {
        // 1 (below 2^1) and 2^-247: 248 digits, accepted; with 2^-248, 249 digits: refused.
        let edge = [[1.0, 0.0, 0.0], [2f64.powi(-247), 0.0, 0.0]];
        assert!(scale_for_weights(&edge, &[0.0; 2]).is_ok());
        let refused = [[1.0, 0.0, 0.0], [2f64.powi(-248), 0.0, 0.0]];
        assert_eq!(
            scale_for_weights(&refused, &[0.0; 2]),
            Err(TetraError::CoordinateSpan {
                orders: 75,
                max_orders: 74,
                largest: 1.0,
                largest_point: 0,
                finest_digit: 2f64.powi(-248),
                finest_point: 1,
            })
        );
    }
}
