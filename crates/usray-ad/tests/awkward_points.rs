//! Reference derivatives at awkward points, in forward and reverse mode, with
//! the value also checked against plain `f64`. Expected derivatives are the
//! textbook formulas evaluated by hand (see each comment); where the true
//! derivative is infinite or undefined, the documented convention is checked.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
use usray_ad::reverse::{Recording, Var};
use usray_ad::{Dual, Real};

/// `(f64 value, dual value, dual derivative, reverse value, reverse derivative)`
/// of the expression `$body` in the variable `$t` at `$x`.
macro_rules! d1 {
    ($x:expr, |$t:ident| $body:expr) => {{
        let xv: f64 = $x;
        let vf: f64 = {
            let $t = xv;
            $body
        };
        let fd: Dual<1> = {
            let $t = Dual::<1>::variable(xv, 0);
            $body
        };
        let (vr, gr) = {
            let rec = Recording::start();
            let $t = rec.input(xv);
            let y: Var = $body;
            let mut g = [0.0];
            rec.gradient(y, &mut g);
            (y.value(), g[0])
        };
        (vf, fd.re, fd.eps[0], vr, gr)
    }};
}

/// Two variables `$a`, `$b` at `($x, $y)`: values and both partials.
macro_rules! d2 {
    ($x:expr, $y:expr, |$a:ident, $b:ident| $body:expr) => {{
        let (xv, yv): (f64, f64) = ($x, $y);
        let vf: f64 = {
            let ($a, $b) = (xv, yv);
            $body
        };
        let fd: Dual<2> = {
            let ($a, $b) = (Dual::<2>::variable(xv, 0), Dual::<2>::variable(yv, 1));
            $body
        };
        let (vr, gr) = {
            let rec = Recording::start();
            let ($a, $b) = (rec.input(xv), rec.input(yv));
            let z: Var = $body;
            let mut g = [0.0; 2];
            rec.gradient(z, &mut g);
            (z.value(), g)
        };
        (vf, fd.re, fd.eps, vr, gr)
    }};
}

/// Equal as reference values: same bits for ±∞ and exact values, both NaN, or
/// within `rel` relative error.
fn same(a: f64, b: f64, rel: f64) -> bool {
    if a.is_nan() || b.is_nan() {
        return a.is_nan() && b.is_nan();
    }
    if a.is_infinite() || b.is_infinite() || rel == 0.0 {
        return a == b;
    }
    (a - b).abs() <= rel * a.abs().max(b.abs())
}

#[track_caller]
fn check1(r: (f64, f64, f64, f64, f64), value: f64, deriv: f64, rel: f64) {
    let (vf, vd, gd, vr, gr) = r;
    assert!(same(vf, value, rel), "f64 value {vf} ≠ {value}");
    assert!(
        same(vd, vf, 0.0) || (vd.is_nan() && vf.is_nan()),
        "dual value {vd} ≠ f64 {vf}"
    );
    assert!(
        same(vr, vf, 0.0) || (vr.is_nan() && vf.is_nan()),
        "reverse value {vr} ≠ f64 {vf}"
    );
    assert!(same(gd, deriv, rel), "dual derivative {gd} ≠ {deriv}");
    assert!(same(gr, deriv, rel), "reverse derivative {gr} ≠ {deriv}");
}

#[track_caller]
fn check2(r: (f64, f64, [f64; 2], f64, [f64; 2]), value: f64, grad: [f64; 2], rel: f64) {
    let (vf, vd, gd, vr, gr) = r;
    assert!(same(vf, value, rel), "f64 value {vf} ≠ {value}");
    assert!(same(vd, vf, 0.0), "dual value {vd} ≠ f64 {vf}");
    assert!(same(vr, vf, 0.0), "reverse value {vr} ≠ f64 {vf}");
    for i in 0..2 {
        assert!(
            same(gd[i], grad[i], rel),
            "dual ∂{i} {} ≠ {}",
            gd[i],
            grad[i]
        );
        assert!(
            same(gr[i], grad[i], rel),
            "reverse ∂{i} {} ≠ {}",
            gr[i],
            grad[i]
        );
    }
}

const R: f64 = 4.0 * f64::EPSILON;

/// The constant `v` in the number type of `_like`.
fn k<T: Real>(_like: T, v: f64) -> T {
    T::from_f64(v)
}

#[test]
fn sqrt_and_safe_sqrt_at_zero() {
    // d√x/dx = 1/(2√x): +∞ at 0 (one-sided), finite elsewhere.
    check1(d1!(0.0, |x| x.sqrt()), 0.0, f64::INFINITY, 0.0);
    check1(d1!(4.0, |x| x.sqrt()), 2.0, 0.25, 0.0);
    // safe_sqrt: subgradient 0 at and below 0, value √max(x,0).
    check1(d1!(0.0, |x| x.safe_sqrt()), 0.0, 0.0, 0.0);
    check1(d1!(-1e-300, |x| x.safe_sqrt()), 0.0, 0.0, 0.0);
    check1(d1!(-3.0, |x| x.safe_sqrt()), 0.0, 0.0, 0.0);
    check1(d1!(1e-300, |x| x.safe_sqrt()), 1e-150, 5e149, R);
}

#[test]
fn acos_asin_and_safe_variants_at_plus_minus_one() {
    // d acos/dx = −1/√(1−x²) → −∞ at ±1; d asin/dx = +1/√(1−x²) → +∞.
    check1(d1!(1.0, |x| x.acos()), 0.0, f64::NEG_INFINITY, 0.0);
    check1(d1!(-1.0, |x| x.acos()), PI, f64::NEG_INFINITY, 0.0);
    check1(d1!(1.0, |x| x.asin()), FRAC_PI_2, f64::INFINITY, 0.0);
    check1(d1!(-1.0, |x| x.asin()), -FRAC_PI_2, f64::INFINITY, 0.0);
    // Interior: acos'(½) = −1/√(3/4) = −2/√3.
    check1(d1!(0.5, |x| x.acos()), 0.5f64.acos(), -2.0 / 3f64.sqrt(), R);
    check1(
        d1!(0.5, |x| x.safe_acos()),
        0.5f64.acos(),
        -2.0 / 3f64.sqrt(),
        R,
    );
    check1(
        d1!(0.5, |x| x.safe_asin()),
        0.5f64.asin(),
        2.0 / 3f64.sqrt(),
        R,
    );
    // safe_*: clamp to [−1, 1], subgradient 0 at and beyond ±1.
    let past = 1.0 + f64::EPSILON;
    check1(d1!(1.0, |x| x.safe_acos()), 0.0, 0.0, 0.0);
    check1(d1!(-1.0, |x| x.safe_acos()), PI, 0.0, 0.0);
    check1(d1!(past, |x| x.safe_acos()), 0.0, 0.0, 0.0);
    check1(d1!(-past, |x| x.safe_acos()), PI, 0.0, 0.0);
    check1(d1!(1.0, |x| x.safe_asin()), FRAC_PI_2, 0.0, 0.0);
    check1(d1!(-1.0, |x| x.safe_asin()), -FRAC_PI_2, 0.0, 0.0);
    check1(d1!(past, |x| x.safe_asin()), FRAC_PI_2, 0.0, 0.0);
    check1(d1!(-past, |x| x.safe_asin()), -FRAC_PI_2, 0.0, 0.0);
}

#[test]
fn large_magnitudes() {
    let x = 1e150;
    check1(d1!(x, |t| t * t), 1e300, 2e150, R); // d(x²) = 2x
    check1(d1!(x, |t| t.powi(2)), 1e300, 2e150, R);
    check1(d1!(x, |t| t.sqrt()), 1e75, 0.5e-75, R); // 1/(2√x)
    check1(d1!(x, |t| t.ln()), x.ln(), 1e-150, R); // 1/x
    check1(d1!(x, |t| t.recip()), 1e-150, -1e-300, R); // −1/x²
    check1(d1!(x, |t| t.abs()), x, 1.0, 0.0);
    check1(d1!(-x, |t| t.abs()), x, -1.0, 0.0);
    // atan2 at huge arguments: x² + y² would overflow; ∂/∂y = x/(x²+y²) = 1/(2·10²⁰⁰).
    check2(
        d2!(1e200, 1e200, |y, x| y.atan2(x)),
        FRAC_PI_4,
        [0.5e-200, -0.5e-200],
        R,
    );
    // Beyond the range, the derivative overflows honestly: d(x³) = 3x² = 3e300·1e0 ok,
    // but d(x⁴)/dx = 4x³ = 4e450 → +∞ (and so does the value).
    check1(d1!(x, |t| t.powi(4)), f64::INFINITY, f64::INFINITY, 0.0);
}

#[test]
fn tiny_magnitudes() {
    let x = 1e-300;
    check1(d1!(x, |t| t.sqrt()), 1e-150, 5e149, R);
    check1(d1!(x, |t| t.ln()), x.ln(), 1e300, R);
    check1(d1!(x, |t| t * t), 0.0, 2e-300, R); // value underflows, derivative does not
    check1(d1!(1e-150, |t| t.recip()), 1e150, -1e300, R);
    // −1/x² = −10⁶⁰⁰ is beyond f64: −∞, not garbage from a subnormal x².
    check1(d1!(x, |t| t.recip()), 1e300, f64::NEG_INFINITY, R);
    // atan2 at tiny arguments: x² + y² underflows to 0 unless scaled.
    check2(
        d2!(1e-300, 1e-300, |y, x| y.atan2(x)),
        FRAC_PI_4,
        [5e299, -5e299],
        R,
    );
    check2(
        d2!(3e-300, 4e-300, |y, x| y.atan2(x)),
        0.75f64.atan(),
        [0.16e300, -0.12e300],
        R,
    );
}

#[test]
fn atan2_at_the_origin_and_axes() {
    // Undefined at the origin: value atan2(0, 0) = 0, partials taken as 0.
    check2(d2!(0.0, 0.0, |y, x| y.atan2(x)), 0.0, [0.0, 0.0], 0.0);
    // On the axes: ∂/∂y = x/r², ∂/∂x = −y/r².
    check2(d2!(0.0, 2.0, |y, x| y.atan2(x)), 0.0, [0.5, 0.0], 0.0);
    check2(
        d2!(2.0, 0.0, |y, x| y.atan2(x)),
        FRAC_PI_2,
        [0.0, -0.5],
        0.0,
    );
    check2(d2!(0.0, -2.0, |y, x| y.atan2(x)), PI, [-0.5, 0.0], 0.0);
}

#[test]
fn abs_at_zero() {
    check1(d1!(0.0, |x| x.abs()), 0.0, 0.0, 0.0);
    check1(d1!(-0.0, |x| x.abs()), 0.0, 0.0, 0.0);
    check1(d1!(-2.0, |x| x.abs()), 2.0, -1.0, 0.0);
}

#[test]
fn min_max_ties_follow_the_first_argument() {
    check2(d2!(1.0, 1.0, |a, b| a.min(b)), 1.0, [1.0, 0.0], 0.0);
    check2(d2!(1.0, 1.0, |a, b| a.max(b)), 1.0, [1.0, 0.0], 0.0);
    check2(d2!(1.0, 2.0, |a, b| a.min(b)), 1.0, [1.0, 0.0], 0.0);
    check2(d2!(1.0, 2.0, |a, b| a.max(b)), 2.0, [0.0, 1.0], 0.0);
    // clamp(x, lo, hi): derivative follows whichever value is returned.
    check2(
        d2!(0.5, 0.7, |a, b| a.clamp(k(a, 0.0), b)),
        0.5,
        [1.0, 0.0],
        0.0,
    );
    check2(
        d2!(0.9, 0.7, |a, b| a.clamp(k(a, 0.0), b)),
        0.7,
        [0.0, 1.0],
        0.0,
    );
}

#[test]
fn clip01_at_bounds_inside_and_outside() {
    // The paper's map: derivative 1 strictly inside (0, 1), 0 at and beyond the bounds.
    check1(d1!(0.0, |x| x.clip01()), 0.0, 0.0, 0.0);
    check1(d1!(1.0, |x| x.clip01()), 1.0, 0.0, 0.0);
    check1(d1!(0.25, |x| x.clip01()), 0.25, 1.0, 0.0);
    check1(d1!(-0.5, |x| x.clip01()), 0.0, 0.0, 0.0);
    check1(d1!(1.5, |x| x.clip01()), 1.0, 0.0, 0.0);
}

#[test]
fn powf_with_non_positive_base() {
    // ∂(xʸ)/∂x = y·xʸ⁻¹; ∂/∂y = xʸ ln x for x > 0, taken as 0 for x ≤ 0.
    check2(d2!(0.0, 2.0, |x, y| x.powf(y)), 0.0, [0.0, 0.0], 0.0);
    check2(d2!(0.0, 1.0, |x, y| x.powf(y)), 0.0, [1.0, 0.0], 0.0);
    check2(
        d2!(0.0, 0.5, |x, y| x.powf(y)),
        0.0,
        [f64::INFINITY, 0.0],
        0.0,
    );
    check2(d2!(0.0, 0.0, |x, y| x.powf(y)), 1.0, [0.0, 0.0], 0.0);
    check2(
        d2!(0.0, -1.0, |x, y| x.powf(y)),
        f64::INFINITY,
        [f64::NEG_INFINITY, 0.0],
        0.0,
    );
    check2(d2!(-2.0, 3.0, |x, y| x.powf(y)), -8.0, [12.0, 0.0], 0.0);
    check2(d2!(-2.0, 2.0, |x, y| x.powf(y)), 4.0, [-4.0, 0.0], 0.0);
    // Non-integer power of a negative number: NaN value (as f64::powf), documented.
    let (vf, vd, _, vr, _) = d2!(-2.0, 0.5, |x, y| x.powf(y));
    assert!(vf.is_nan() && vd.is_nan() && vr.is_nan());
    // Positive base, for reference: ∂/∂y = xʸ ln x.
    check2(
        d2!(2.0, 3.0, |x, y| x.powf(y)),
        8.0,
        [12.0, 8.0 * 2f64.ln()],
        R,
    );
}

#[test]
fn powi_at_zero() {
    check1(d1!(0.0, |x| x.powi(2)), 0.0, 0.0, 0.0);
    check1(d1!(0.0, |x| x.powi(1)), 0.0, 1.0, 0.0);
    check1(d1!(0.0, |x| x.powi(0)), 1.0, 0.0, 0.0);
    check1(
        d1!(0.0, |x| x.powi(-1)),
        f64::INFINITY,
        f64::NEG_INFINITY,
        0.0,
    );
    check1(d1!(-2.0, |x| x.powi(3)), -8.0, 12.0, 0.0);
}

#[test]
fn zero_times_infinity_is_zero_in_both_modes() {
    // A constant through sqrt(0): no tangent, no NaN.
    let c = Dual::<1>::constant(0.0).sqrt();
    assert_eq!((c.re, c.eps[0]), (0.0, 0.0));
    // y = x + 0·√x at x = 0: the √x path has a zero factor, so dy/dx = 1.
    let zero = 0.0;
    check1(d1!(0.0, |x| x + x.sqrt().scale(zero)), 0.0, 1.0, 0.0);
    check1(d1!(0.0, |x| x + x.sqrt() * k(x, zero)), 0.0, 1.0, 0.0);
    // y = √(0·x): identically 0, derivative 0 (an infinite partial meets a
    // zero tangent in forward mode and a zero partial in reverse mode).
    check1(d1!(1.0, |x| (x * k(x, zero)).sqrt()), 0.0, 0.0, 0.0);
}

#[test]
fn detach_cuts_the_derivative_and_keeps_the_value() {
    check1(d1!(3.0, |x| x * x.detach()), 9.0, 3.0, 0.0);
    check1(d1!(0.25, |x| x / x.detach()), 1.0, 4.0, 0.0);
}

#[test]
fn is_finite_checks_partials_of_duals() {
    assert!(Dual::<2>::variable(1.0, 0).is_finite());
    assert!(!Dual::<1>::variable(0.0, 0).sqrt().is_finite());
    assert!(!Dual::<1>::variable(1.0, 0).acos().is_finite());
    assert!(Dual::<1>::variable(1.0, 0).safe_acos().is_finite());
    assert!(!Dual::<1>::constant(f64::NAN).is_finite());
}

/// Sums start from `−0.0`, the IEEE additive identity that `f64`'s `Sum` uses, so an
/// empty sum (or a sum of negative zeros) has the same sign in every mode (a
/// proptest found `−Σ[]` = `+0.0` in `f64` but `−0.0` in `Dual`).
#[test]
fn empty_and_negative_zero_sums_match_f64_bits() {
    let f64_empty: f64 = core::iter::empty::<f64>().sum();
    let d: Dual<1> = core::iter::empty::<Dual<1>>().sum();
    assert_eq!(d.value().to_bits(), f64_empty.to_bits());
    let negs: f64 = [-0.0f64, -0.0].iter().sum();
    let dn: Dual<1> = [Dual::<1>::constant(-0.0), Dual::constant(-0.0)]
        .iter()
        .sum();
    assert_eq!(dn.value().to_bits(), negs.to_bits());
    let rec = Recording::start();
    let v: Var = core::iter::empty::<Var>().sum();
    assert_eq!(v.value().to_bits(), f64_empty.to_bits());
    drop(rec);
}
