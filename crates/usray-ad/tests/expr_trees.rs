//! Random expression trees built from every elementary function, evaluated in
//! `f64`, forward mode (`Dual`) and reverse mode (`Var`): values must agree
//! exactly, gradients must agree with each other to 1e-12 and with
//! Richardson-extrapolated central differences to a derived tolerance.

mod common;

use common::{eval, point, tree, Tree, NVARS};
use proptest::prelude::*;
use usray_ad::helpers::{value_and_gradient_forward, value_and_gradient_reverse};
use usray_ad::reverse::{Recording, Var};
use usray_ad::{Dual, Real};

/// Forward-mode gradient with all three inputs seeded at once.
fn grad_dual(e: &common::E, x: &[f64]) -> (f64, [f64; NVARS]) {
    let xs: Vec<Dual<NVARS>> = (0..NVARS).map(|i| Dual::variable(x[i], i)).collect();
    let y = eval(e, &xs);
    (y.re, y.eps)
}

/// Reverse-mode gradient through the scoped API.
fn grad_rev(e: &common::E, x: &[f64]) -> (f64, [f64; NVARS]) {
    let rec = Recording::start();
    let xs: [Var; NVARS] = rec.inputs_array(x);
    let y = eval(e, &xs);
    let mut g = [0.0; NVARS];
    rec.gradient(y, &mut g);
    (y.value(), g)
}

/// Cross-mode agreement: |a − b| ≤ 1e-12·max(|a|, |b|) + 1e-12·max(1, ‖g‖∞).
///
/// Forward and reverse mode multiply the same partials along each path from an
/// input to the output, but associate the products (and sum the paths) in
/// opposite orders, so they differ by rounding: a few ulps of each path's
/// contribution. Relative to the component that is ~1e-14 for these trees
/// (depth ≤ 5); the absolute floor, 1e-12 in units of the largest gradient
/// component (at least 1), covers components that cancel to nearly zero, where a
/// relative comparison is meaningless.
fn close_modes(a: f64, b: f64, gmax: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()) + 1e-12 * gmax.max(1.0)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1024))]

    /// Values are bit-identical in every number type (a replay in an AD type
    /// must take the same branches as the `f64` render); gradients by Dual<3>,
    /// chunked Dual<2>, Dual<1> and reverse agree.
    #[test]
    fn modes_agree(e in tree(), x in point()) {
        let f = eval(&e, &x);
        prop_assume!(f.is_finite());
        let (vd, gd) = grad_dual(&e, &x);
        let (vr, gr) = grad_rev(&e, &x);
        prop_assert_eq!(f.to_bits(), vd.to_bits(), "f64 vs Dual value");
        prop_assert_eq!(f.to_bits(), vr.to_bits(), "f64 vs reverse value");

        let mut g2 = [0.0; NVARS];
        let mut g1 = [0.0; NVARS];
        let mut gh = [0.0; NVARS];
        let v2 = value_and_gradient_forward::<2, _>(&Tree(e.clone()), &x, &mut g2);
        let v1 = value_and_gradient_forward::<1, _>(&Tree(e.clone()), &x, &mut g1);
        let vh = value_and_gradient_reverse(&Tree(e.clone()), &x, &mut gh);
        prop_assert_eq!(f.to_bits(), v2.to_bits());
        prop_assert_eq!(f.to_bits(), v1.to_bits());
        prop_assert_eq!(f.to_bits(), vh.to_bits());

        let gmax = gd.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        for i in 0..NVARS {
            prop_assert!(gd[i].is_finite() && gr[i].is_finite(), "{gd:?} {gr:?}");
            // Forward mode computes each partial independently of how many are
            // carried: bit-identical across N.
            prop_assert_eq!(gd[i].to_bits(), g2[i].to_bits());
            prop_assert_eq!(gd[i].to_bits(), g1[i].to_bits());
            prop_assert_eq!(gr[i].to_bits(), gh[i].to_bits());
            prop_assert!(close_modes(gd[i], gr[i], gmax),
                "∂f/∂x{}: dual {} vs reverse {} (tree {:?})", i, gd[i], gr[i], e);
        }
    }

    /// Gradients against central finite differences with Richardson extrapolation
    /// ([`richardson`]); a case whose differences never reach the asymptotic
    /// regime is discarded (finite differences cannot judge it), not passed.
    /// A wrong derivative rule errs by `O(|f'|)`, orders of magnitude above `tol`.
    #[test]
    fn gradient_matches_finite_differences(e in tree(), x in point()) {
        let f = eval(&e, &x);
        prop_assume!(f.is_finite());
        let (_, gd) = grad_dual(&e, &x);
        let (_, gr) = grad_rev(&e, &x);
        for i in 0..NVARS {
            let at = |t: f64| {
                let mut y = x.clone();
                y[i] += t;
                eval(&e, &y)
            };
            let fd = richardson(&at, f);
            prop_assume!(fd.is_some(), "no asymptotic regime");
            let (r, tol) = fd.unwrap();
            prop_assert!((gd[i] - r).abs() <= tol,
                "∂f/∂x{}: dual {} vs FD {} (tol {:e}) tree {:?}", i, gd[i], r, tol, e);
            prop_assert!((gr[i] - r).abs() <= tol,
                "∂f/∂x{}: reverse {} vs FD {} (tol {:e}) tree {:?}", i, gr[i], r, tol, e);
        }
    }
}

/// Richardson-extrapolated central difference of `at` at 0 (`f = at(0)`) and its
/// error bound, `(R, tol)`, or `None` if no step reaches the asymptotic regime.
///
/// With `D(h) = (f(h) − f(−h))/2h`, Taylor gives `D(h) = f' + h²f'''/6 + O(h⁴)`,
/// so `R = (4D(h/2) − D(h))/3 = f' + O(h⁴)`. Error bound `tol = |D(h) − D(h/2)|
/// + 3δ/h`:
/// - truncation: `D(h) − D(h/2) = h²f'''/8 + O(h⁴)` is, *in the asymptotic
///   regime*, far larger than `R`'s `O(h⁴)` error, so it bounds it with a wide
///   margin while adapting to each tree's own `f'''`;
/// - round-off: if each evaluation of `f` is within `δ` of exact, `D(h)` is off by
///   at most `δ/h` and `D(h/2)` by `2δ/h`, so `R` by `(4·2δ/h + δ/h)/3 = 3δ/h`. We
///   take `δ = 2⁻⁴⁰·max(1, |f|)` (≈ 4000 ulps: trees have ≤ 40 operations, each
///   adding ≤ ½ ulp, amplified by the mild condition numbers of these bounded
///   maps).
///
/// The asymptotic regime is checked, not assumed: there successive differences
/// shrink by 4 per halving, `a = D(h) − D(h/2) ≈ 4(D(h/2) − D(h/4)) = 4b`. A tree
/// that oscillates on the scale of `h` (the sine of a large inner value) is not in
/// it at `h = 10⁻³`, and its `|a|` then understates the error (seen in CI:
/// ∂f/∂x1 of −873 against an extrapolation of −1083 with `tol` 65). So `h` starts
/// at 10⁻³ and is halved up to 8 times until `a/b` lies in [3, 5] (4 up to the
/// `O(h²)` relative correction) or both differences are at the round-off level
/// (`|a| ≤ 6δ/h`, `|b| ≤ 12δ/h`, where the `3δ/h` term covers the error).
fn richardson(at: &dyn Fn(f64) -> f64, f: f64) -> Option<(f64, f64)> {
    let d = |h: f64| (at(h) - at(-h)) / (2.0 * h);
    let mut h = 1e-3;
    for _ in 0..=8 {
        let (dh, dh2, dh4) = (d(h), d(h / 2.0), d(h / 4.0));
        let fmax = [at(h), at(-h), at(h / 2.0), at(-h / 2.0)]
            .iter()
            .fold(f.abs(), |m, v| m.max(v.abs()));
        let delta = 2f64.powi(-40) * fmax.max(1.0);
        let (a, b) = (dh - dh2, dh2 - dh4);
        let roundoff = 6.0 * delta / h;
        let asymptotic = (a.abs() <= roundoff && b.abs() <= 2.0 * roundoff)
            || (b != 0.0 && (3.0..=5.0).contains(&(a / b)));
        if asymptotic {
            return Some(((4.0 * dh2 - dh) / 3.0, a.abs() + 3.0 * delta / h));
        }
        h /= 2.0;
    }
    None
}

/// Sanity check that the finite-difference test can fail: a deliberately wrong
/// derivative (`d/dx sin x` taken as `−cos x`) is rejected by the same tolerance.
#[test]
fn finite_difference_check_rejects_a_wrong_rule() {
    fn wrong_sin<T: Real>(x: T) -> T {
        let v = x.value();
        x.chain(v.sin(), -v.cos())
    }
    let x0 = 0.7;
    let g = wrong_sin(Dual::<1>::variable(x0, 0)).eps[0];
    let (r, tol) = richardson(&|t: f64| (x0 + t).sin(), x0.sin()).expect("sin is smooth");
    assert!((g - r).abs() > tol);
    assert!((x0.cos() - r).abs() <= tol);
}

/// The case that made the unchecked Richardson rule fail in CI: `∂f/∂x1` is
/// −873.43 by both modes, the extrapolation at `h = 10⁻³` gave −1083 with a
/// bound of 65 (the tree is `exp(sin(·))` of a power that oscillates on the scale
/// of `h`). With the regime checked, the extrapolation agrees.
#[test]
fn finite_differences_reach_the_asymptotic_regime_of_an_oscillating_tree() {
    use common::{B, E, U};
    let bx = |e: E| Box::new(e);
    let base = E::Bin(
        B::Mul,
        bx(E::Sum(vec![
            E::X(0),
            E::Bin(B::Add, bx(E::X(2)), bx(E::X(2))),
        ])),
        bx(E::Bin(
            B::Add,
            bx(E::Powi(bx(E::X(1)), 2)),
            bx(E::Bin(B::Powf, bx(E::C(-0.9074644248717378)), bx(E::X(1)))),
        )),
    );
    let e = E::Un(
        U::Exp,
        bx(E::Bin(
            B::Powf,
            bx(E::Bin(B::Powf, bx(base), bx(E::X(2)))),
            bx(E::Un(U::Sqrt, bx(E::C(0.0)))),
        )),
    );
    let x = [0.027393337304970768, 0.2810264096259706, 1.6201791827035048];
    let (_, gd) = grad_dual(&e, &x);
    let at = |t: f64| eval(&e, &[x[0], x[1] + t, x[2]]);
    let (r, tol) = richardson(&at, at(0.0)).expect("smooth at a smaller step");
    eprintln!("dual {} FD {r} tol {tol:e}", gd[1]);
    assert!((gd[1] - r).abs() <= tol);
}
