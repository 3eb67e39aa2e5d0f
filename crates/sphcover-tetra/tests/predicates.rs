//! The adaptive predicates against an exact big-integer oracle (every `f64` is a dyadic
//! rational: scaled by `2^1100` it is an integer).
use num_bigint::BigInt;
use proptest::prelude::*;
use sphcover_tetra::predicates::{
    collinear, in_power_circle_sos, in_power_sphere_sos, orient3d, orthocentre_power_sign,
    power_test,
};

fn big(x: f64) -> BigInt {
    // x = m · 2^e exactly; return x · 2^1100.
    if x == 0.0 {
        return BigInt::from(0);
    }
    let bits = x.to_bits();
    let exp = ((bits >> 52) & 0x7ff) as i64;
    let frac = bits & ((1u64 << 52) - 1);
    let (m, e) = if exp == 0 {
        (frac, -1074)
    } else {
        (frac | (1u64 << 52), exp - 1075)
    };
    let v = BigInt::from(m) << ((e + 1100) as usize);
    if x < 0.0 { -v } else { v }
}

fn sign(x: &BigInt) -> i32 {
    match x.sign() {
        num_bigint::Sign::Minus => -1,
        num_bigint::Sign::NoSign => 0,
        num_bigint::Sign::Plus => 1,
    }
}

fn det3(m: &[[BigInt; 3]; 3]) -> BigInt {
    &m[0][0] * (&m[1][1] * &m[2][2] - &m[1][2] * &m[2][1])
        - &m[0][1] * (&m[1][0] * &m[2][2] - &m[1][2] * &m[2][0])
        + &m[0][2] * (&m[1][0] * &m[2][1] - &m[1][1] * &m[2][0])
}

fn oracle_orient(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> i32 {
    let r = |p: [f64; 3]| -> [BigInt; 3] { std::array::from_fn(|k| big(p[k]) - big(a[k])) };
    sign(&det3(&[r(b), r(c), r(d)]))
}

fn oracle_power(p: [[f64; 3]; 4], w: [f64; 4], q: [f64; 3], wq: f64) -> i32 {
    // Work at scale 2^1100 for coordinates and 2^2200 for weights.
    let a: Vec<[BigInt; 3]> = p
        .iter()
        .map(|x| std::array::from_fn(|k| big(x[k]) - big(q[k])))
        .collect();
    let lam: Vec<BigInt> = (0..4)
        .map(|i| {
            let s: BigInt = a[i].iter().map(|x| x * x).sum();
            s - ((big(w[i]) - big(wq)) << 1100usize)
        })
        .collect();
    let minor = |skip: usize| -> BigInt {
        let rows: Vec<[BigInt; 3]> = (0..4)
            .filter(|&i| i != skip)
            .map(|i| a[i].clone())
            .collect();
        det3(&[rows[0].clone(), rows[1].clone(), rows[2].clone()])
    };
    let det = -(&lam[0] * minor(0)) + &lam[1] * minor(1) - &lam[2] * minor(2) + &lam[3] * minor(3);
    sign(&det)
}

fn small_grid_point() -> impl Strategy<Value = [f64; 3]> {
    prop::array::uniform3(-4i32..=4).prop_map(|v| v.map(|x| x as f64 * 0.25))
}

fn offset_point() -> impl Strategy<Value = [f64; 3]> {
    // Non-dyadic offsets: differences are not exact, ties are rare but near-ties frequent.
    (small_grid_point(), prop::array::uniform3(-1e-12f64..1e-12))
        .prop_map(|(p, e)| [0.1 + p[0] + e[0], 0.7 + p[1] + e[1], 0.3 + p[2] + e[2]])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn orient3d_is_exact_on_grids(a in small_grid_point(), b in small_grid_point(),
                                 c in small_grid_point(), d in small_grid_point()) {
        prop_assert_eq!(orient3d(&a, &b, &c, &d), oracle_orient(a, b, c, d));
    }

    #[test]
    fn orient3d_is_exact_off_grid(a in offset_point(), b in offset_point(),
                                  c in offset_point(), d in offset_point()) {
        prop_assert_eq!(orient3d(&a, &b, &c, &d), oracle_orient(a, b, c, d));
    }

    #[test]
    fn power_test_is_exact_on_grids(p in prop::array::uniform4(small_grid_point()),
                                   q in small_grid_point(),
                                   w in prop::array::uniform5(0i32..4)) {
        // Dyadic weights (the integer stage) and non-dyadic ones (the mixed stage).
        for scale in [0.0625, 0.1] {
            let wf = w.map(|x| x as f64 * scale);
            let pw = [wf[0], wf[1], wf[2], wf[3]];
            prop_assert_eq!(
                power_test([&p[0], &p[1], &p[2], &p[3]], pw, &q, wf[4]),
                oracle_power(p, pw, q, wf[4])
            );
        }
    }

    #[test]
    fn power_test_is_exact_off_grid(p in prop::array::uniform4(offset_point()),
                                   q in offset_point(),
                                   w in prop::array::uniform5(0.0f64..0.2)) {
        let pw = [w[0], w[1], w[2], w[3]];
        prop_assert_eq!(
            power_test([&p[0], &p[1], &p[2], &p[3]], pw, &q, w[4]),
            oracle_power(p, pw, q, w[4])
        );
    }

    #[test]
    fn power_circle_equals_power_sphere_of_any_apex(
        t in prop::array::uniform4(prop::array::uniform2(-3i32..=3)),
        apex in prop::array::uniform3(-3i32..=3),
        w in prop::array::uniform5(0i32..3),
    ) {
        // Four points on the plane z = x + 2y (so ties and perturbation cases are frequent);
        // the 2D power-circle test of the fourth against the first three must equal the 3D
        // test against the tetrahedron with any apex off the plane, perturbation included.
        let on = |u: [i32; 2]| [u[0] as f64, u[1] as f64, (u[0] + 2 * u[1]) as f64];
        let (a, b, c, q) = (on(t[0]), on(t[1]), on(t[2]), on(t[3]));
        let d = [apex[0] as f64, apex[1] as f64, apex[2] as f64 + 0.5];
        let wf = w.map(|x| x as f64 * 0.5);
        let distinct = [a, b, c, q].iter().enumerate().all(|(i, x)| {
            [a, b, c, q].iter().skip(i + 1).all(|y| x != y)
        });
        if distinct && !collinear(&a, &b, &c) && orient3d(&a, &b, &c, &d) != 0 {
            let (pa, pb, wa, wb) = if orient3d(&a, &b, &c, &d) > 0 {
                (&a, &b, wf[0], wf[1])
            } else {
                (&b, &a, wf[1], wf[0])
            };
            let sphere = in_power_sphere_sos([pa, pb, &c, &d], [wa, wb, wf[2], wf[4]], &q, wf[3]);
            let circle = in_power_circle_sos(&a, &b, &c, &q, [wf[0], wf[1], wf[2], wf[3]]);
            prop_assert_eq!(sphere, circle);
        }
    }

    #[test]
    fn perturbed_test_agrees_when_not_tied(p in prop::array::uniform4(small_grid_point()),
                                          q in small_grid_point()) {
        let o = orient3d(&p[0], &p[1], &p[2], &p[3]);
        let pts = if o > 0 { [&p[0], &p[1], &p[2], &p[3]] } else { [&p[1], &p[0], &p[2], &p[3]] };
        if o != 0 && !p.contains(&q) {
            let s = power_test(pts, [0.0; 4], &q, 0.0);
            let sos = in_power_sphere_sos(pts, [0.0; 4], &q, 0.0);
            if s != 0 {
                prop_assert_eq!(sos, s < 0);
            }
        }
    }
}

#[test]
fn orthocentre_sign_matches_oracle_on_near_ties() {
    // Regular tetrahedron corners of the unit cube; circumradius² = 0.75 exactly.
    let p = [
        [0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [1.0, 0.0, 1.0],
        [0.0, 1.0, 1.0],
    ];
    let pts = [&p[0], &p[1], &p[2], &p[3]];
    assert_eq!(orient3d(pts[0], pts[1], pts[2], pts[3]).abs(), 1);
    let pts = if orient3d(pts[0], pts[1], pts[2], pts[3]) > 0 {
        pts
    } else {
        [pts[1], pts[0], pts[2], pts[3]]
    };
    assert_eq!(orthocentre_power_sign(pts, [0.75; 4]), 0);
    let up = f64::from_bits(0.75f64.to_bits() + 1);
    let down = f64::from_bits(0.75f64.to_bits() - 1);
    assert_eq!(orthocentre_power_sign(pts, [up; 4]), -1);
    assert_eq!(orthocentre_power_sign(pts, [down; 4]), 1);
}
