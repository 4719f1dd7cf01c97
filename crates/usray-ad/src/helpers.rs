//! Value-and-gradient, JVP and VJP of functions written once for any [`Real`].
//!
//! Rust closures cannot be generic over `T`, so a function to differentiate is a
//! small type implementing [`ScalarFn`] (`ℝⁿ → ℝ`) or [`VectorFn`] (`ℝⁿ → ℝᵐ`);
//! the same `eval` then runs in `f64`, [`Dual`] and [`Var`].
//!
//! | want | use | cost |
//! |---|---|---|
//! | gradient, few inputs | [`value_and_gradient_forward`] | `⌈n/N⌉` evaluations in `Dual<N>` |
//! | gradient, many inputs | [`value_and_gradient_reverse`] | one recorded evaluation + one sweep |
//! | `J·v` | [`jvp`] | one evaluation in `Dual<1>` |
//! | `wᵀ·J` | [`vjp`] | one recorded evaluation + one sweep |
//!
//! ```
//! use usray_ad::helpers::{value_and_gradient_forward, value_and_gradient_reverse, ScalarFn};
//! use usray_ad::Real;
//!
//! /// f(x) = x₀² · sin x₁ + ln(1 + x₂²)
//! struct F;
//! impl ScalarFn for F {
//!     fn eval<T: Real>(&self, x: &[T]) -> T {
//!         x[0] * x[0] * x[1].sin() + (T::one() + x[2] * x[2]).ln()
//!     }
//! }
//! let x = [1.5, 0.3, 2.0];
//! let (mut gf, mut gr) = ([0.0; 3], [0.0; 3]);
//! let vf = value_and_gradient_forward::<2, _>(&F, &x, &mut gf); // 2 passes of Dual<2>
//! let vr = value_and_gradient_reverse(&F, &x, &mut gr);
//! assert_eq!(vf, F.eval(&x));
//! assert_eq!(vr, vf);
//! let exact = [2.0 * 1.5 * 0.3_f64.sin(), 1.5 * 1.5 * 0.3_f64.cos(), 2.0 * 2.0 / 5.0];
//! for i in 0..3 {
//!     assert!((gf[i] - exact[i]).abs() < 1e-15 && (gr[i] - exact[i]).abs() < 1e-15);
//! }
//! ```

use crate::reverse::{Recording, Var};
use crate::{Dual, Real};

/// A scalar function `ℝⁿ → ℝ` written once for every [`Real`].
///
/// ```
/// use usray_ad::helpers::ScalarFn;
/// use usray_ad::Real;
/// struct Norm;
/// impl ScalarFn for Norm {
///     fn eval<T: Real>(&self, x: &[T]) -> T {
///         x.iter().map(|&v| v * v).sum::<T>().sqrt()
///     }
/// }
/// assert_eq!(Norm.eval(&[3.0_f64, 4.0]), 5.0);
/// ```
pub trait ScalarFn {
    /// Evaluate at `x`.
    fn eval<T: Real>(&self, x: &[T]) -> T;
}

/// A vector function `ℝⁿ → ℝᵐ` written once for every [`Real`]; `out.len()` is
/// `m` (the caller sizes it).
///
/// ```
/// use usray_ad::helpers::VectorFn;
/// use usray_ad::Real;
/// struct Polar;
/// impl VectorFn for Polar {
///     fn eval<T: Real>(&self, x: &[T], out: &mut [T]) {
///         out[0] = x[0] * x[1].cos();
///         out[1] = x[0] * x[1].sin();
///     }
/// }
/// let mut y = [0.0; 2];
/// Polar.eval(&[2.0_f64, 0.0], &mut y);
/// assert_eq!(y, [2.0, 0.0]);
/// ```
pub trait VectorFn {
    /// Evaluate at `x`, writing the `out.len()` outputs.
    fn eval<T: Real>(&self, x: &[T], out: &mut [T]);
}

/// Value of `f` at `x`, and its gradient written (not added) into `grad`, by
/// forward mode: `⌈n/N⌉` evaluations in [`Dual<N>`], each seeding `N` inputs.
///
/// # Panics
/// If `grad.len() != x.len()` or `N == 0`.
///
/// ```
/// use usray_ad::helpers::{value_and_gradient_forward, ScalarFn};
/// use usray_ad::Real;
/// struct Prod;
/// impl ScalarFn for Prod {
///     fn eval<T: Real>(&self, x: &[T]) -> T {
///         x[0] * x[1] * x[2]
///     }
/// }
/// let mut g = [0.0; 3];
/// let v = value_and_gradient_forward::<1, _>(&Prod, &[2.0, 3.0, 4.0], &mut g);
/// assert_eq!((v, g), (24.0, [12.0, 8.0, 6.0]));
/// ```
pub fn value_and_gradient_forward<const N: usize, F: ScalarFn>(
    f: &F,
    x: &[f64],
    grad: &mut [f64],
) -> f64 {
    assert!(N > 0, "value_and_gradient_forward needs N ≥ 1 partials");
    assert_eq!(
        grad.len(),
        x.len(),
        "gradient length must equal input length"
    );
    let mut xs: Vec<Dual<N>> = x.iter().map(|&v| Dual::constant(v)).collect();
    if x.is_empty() {
        return f.eval(&xs).re;
    }
    let mut value = 0.0;
    for start in (0..x.len()).step_by(N) {
        let end = (start + N).min(x.len());
        for (i, d) in xs.iter_mut().enumerate() {
            *d = if (start..end).contains(&i) {
                Dual::variable(x[i], i - start)
            } else {
                Dual::constant(x[i])
            };
        }
        let y = f.eval(&xs);
        value = y.re;
        grad[start..end].copy_from_slice(&y.eps[..end - start]);
    }
    value
}

/// Value of `f` at `x`, and its gradient written (not added) into `grad`, by
/// reverse mode: one evaluation recorded on this thread's tape, one sweep.
///
/// # Panics
/// If `grad.len() != x.len()`, or a [`Recording`] is already live on this thread.
///
/// ```
/// use usray_ad::helpers::{value_and_gradient_reverse, ScalarFn};
/// use usray_ad::Real;
/// struct Sq;
/// impl ScalarFn for Sq {
///     fn eval<T: Real>(&self, x: &[T]) -> T {
///         x.iter().map(|&v| v * v).sum()
///     }
/// }
/// let mut g = [0.0; 2];
/// assert_eq!(value_and_gradient_reverse(&Sq, &[1.0, -2.0], &mut g), 5.0);
/// assert_eq!(g, [2.0, -4.0]);
/// ```
pub fn value_and_gradient_reverse<F: ScalarFn>(f: &F, x: &[f64], grad: &mut [f64]) -> f64 {
    assert_eq!(
        grad.len(),
        x.len(),
        "gradient length must equal input length"
    );
    let rec = Recording::start();
    let mut xs = vec![Var::constant(0.0); x.len()];
    rec.inputs_into(x, &mut xs);
    let y = f.eval(&xs);
    grad.fill(0.0);
    rec.gradient(y, grad);
    y.value()
}

/// Jacobian-vector product by forward mode (one evaluation in `Dual<1>`):
/// writes `y = f(x)` and `jv = J(x)·v`.
///
/// # Panics
/// If `v.len() != x.len()` or `jv.len() != y.len()`.
///
/// ```
/// use usray_ad::helpers::{jvp, VectorFn};
/// use usray_ad::Real;
/// struct Lin;
/// impl VectorFn for Lin {
///     fn eval<T: Real>(&self, x: &[T], out: &mut [T]) {
///         out[0] = x[0] + x[1];
///         out[1] = x[0] * x[1];
///     }
/// }
/// let (mut y, mut jv) = ([0.0; 2], [0.0; 2]);
/// jvp(&Lin, &[2.0, 3.0], &[1.0, 0.0], &mut y, &mut jv);
/// assert_eq!((y, jv), ([5.0, 6.0], [1.0, 3.0]));
/// ```
pub fn jvp<F: VectorFn>(f: &F, x: &[f64], v: &[f64], y: &mut [f64], jv: &mut [f64]) {
    assert_eq!(
        v.len(),
        x.len(),
        "jvp: direction length must equal input length"
    );
    assert_eq!(jv.len(), y.len(), "jvp: jv length must equal output length");
    let xs: Vec<Dual<1>> = x
        .iter()
        .zip(v)
        .map(|(&xi, &vi)| Dual::seeded(xi, [vi]))
        .collect();
    let mut out = vec![Dual::<1>::constant(0.0); y.len()];
    f.eval(&xs, &mut out);
    for ((yi, ji), o) in y.iter_mut().zip(jv.iter_mut()).zip(&out) {
        *yi = o.re;
        *ji = o.eps[0];
    }
}

/// Vector-Jacobian product by reverse mode (one recorded evaluation, one sweep):
/// writes `y = f(x)` and `wj = wᵀ·J(x)`.
///
/// # Panics
/// If `w.len() != y.len()` or `wj.len() != x.len()`, or a [`Recording`] is
/// already live on this thread.
///
/// ```
/// use usray_ad::helpers::{vjp, VectorFn};
/// use usray_ad::Real;
/// struct Lin;
/// impl VectorFn for Lin {
///     fn eval<T: Real>(&self, x: &[T], out: &mut [T]) {
///         out[0] = x[0] + x[1];
///         out[1] = x[0] * x[1];
///     }
/// }
/// let (mut y, mut wj) = ([0.0; 2], [0.0; 2]);
/// vjp(&Lin, &[2.0, 3.0], &[0.0, 1.0], &mut y, &mut wj);
/// assert_eq!((y, wj), ([5.0, 6.0], [3.0, 2.0]));
/// ```
pub fn vjp<F: VectorFn>(f: &F, x: &[f64], w: &[f64], y: &mut [f64], wj: &mut [f64]) {
    assert_eq!(
        w.len(),
        y.len(),
        "vjp: weight length must equal output length"
    );
    assert_eq!(wj.len(), x.len(), "vjp: wj length must equal input length");
    let rec = Recording::start();
    let mut xs = vec![Var::constant(0.0); x.len()];
    rec.inputs_into(x, &mut xs);
    let mut out = vec![Var::constant(0.0); y.len()];
    f.eval(&xs, &mut out);
    for (yi, o) in y.iter_mut().zip(&out) {
        *yi = o.value();
    }
    wj.fill(0.0);
    rec.vjp(&out, w, wj);
}
