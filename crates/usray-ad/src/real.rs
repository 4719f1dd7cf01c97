//! The [`Real`] trait: the one scalar bound generic usray code needs.
//!
//! # How derivative rules are shared
//! An AD type implements only two primitives:
//! - [`Real::chain`]: given `f(x)` and `f'(x)` at `x = self.value()`, build the
//!   result `f(self)` carrying `f'(x)·ẋ` (forward) or recording the edge (reverse);
//! - [`Real::chain2`]: the same for a binary function `f(x, y)` with both partials.
//!
//! Every elementary function (`sqrt`, `exp`, `atan2`, …) is a *provided* method
//! written once in terms of those primitives, so the derivative of `acos` exists in
//! exactly one place and every AD type uses it. `f32` and `f64` override the
//! provided methods with the native calls, so plain floating point pays nothing.

use core::fmt::Debug;
use core::iter::Sum;
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// A real scalar that may carry derivatives.
///
/// Generic code writes `fn f<T: Real>(x: T) -> T` and runs unchanged in `f32`,
/// `f64`, a forward dual or a reverse-mode variable. Literals are made with
/// [`Real::from_f64`] (infallible, no `unwrap`). Comparisons (`<`, `==`, …) compare
/// values only; branching on them is how visibility and sampling decisions are made,
/// and such decisions carry no derivative (see `DESIGN.md`).
///
/// ```
/// use usray_ad::Real;
/// fn snell_sin_t<T: Real>(sin_i: T, c1: T, c2: T) -> T {
///     sin_i * c2 / c1
/// }
/// assert_eq!(snell_sin_t(0.5_f64, 1500.0, 3000.0), 1.0);
/// assert_eq!(snell_sin_t(0.5_f32, 1500.0, 3000.0), 1.0);
/// ```
pub trait Real:
    Copy
    + Debug
    + Send
    + Sync
    + 'static
    + PartialEq
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Sum
{
    /// A constant: value `x`, zero derivative.
    fn from_f64(x: f64) -> Self;

    /// The primal value, as `f64`.
    fn value(self) -> f64;

    /// Apply a unary function whose value at `x = self.value()` is `f` and whose
    /// derivative there is `df`. This is the one primitive unary rule.
    fn chain(self, f: f64, df: f64) -> Self;

    /// Apply a binary function `g(x, y)` with value `f` and partials `dfdx`, `dfdy`
    /// at `(self.value(), other.value())`.
    fn chain2(self, other: Self, f: f64, dfdx: f64, dfdy: f64) -> Self;

    /// The same value with the derivative cut: gradients do not flow through the
    /// result. Used to divide by a sampling probability (`DESIGN.md`).
    ///
    /// ```
    /// use usray_ad::Real;
    /// assert_eq!(2.5_f64.detach(), 2.5);
    /// ```
    #[inline]
    fn detach(self) -> Self {
        Self::from_f64(self.value())
    }

    /// True when the value (and, for AD types, every derivative) is finite.
    #[inline]
    fn is_finite(self) -> bool {
        self.value().is_finite()
    }

    /// `0`.
    #[inline]
    fn zero() -> Self {
        Self::from_f64(0.0)
    }

    /// `1`.
    #[inline]
    fn one() -> Self {
        Self::from_f64(1.0)
    }

    /// `π`.
    #[inline]
    fn pi() -> Self {
        Self::from_f64(core::f64::consts::PI)
    }

    /// `self · k` for a plain constant `k` (no derivative through `k`).
    #[inline]
    fn scale(self, k: f64) -> Self {
        self.chain(self.value() * k, k)
    }

    /// `1 / x`; d/dx = −1/x², computed as `−(1/x)²` so that `x²` cannot
    /// underflow for tiny `|x|` (e.g. `x = 10⁻¹⁶⁰`, where `x²` would be subnormal).
    #[inline]
    fn recip(self) -> Self {
        let r = 1.0 / self.value();
        self.chain(r, -(r * r))
    }

    /// `√x`; d/dx = 1/(2√x) (infinite at 0: see [`Real::safe_sqrt`]).
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.value().sqrt();
        self.chain(s, 0.5 / s)
    }

    /// `√max(x, 0)` whose derivative is finite everywhere: `1/(2√x)` for `x > 0`
    /// and `0` for `x ≤ 0` (the subgradient of the clamped function). Used where a
    /// radicand can round to zero: `cos θ_t = √(1 − sin²θ_t)` at grazing incidence,
    /// the length of a zero vector.
    ///
    /// ```
    /// use usray_ad::{Dual, Real};
    /// let x = Dual::<1>::variable(0.0, 0);
    /// assert_eq!(x.safe_sqrt().value(), 0.0);
    /// assert_eq!(x.safe_sqrt().eps[0], 0.0);
    /// ```
    #[inline]
    fn safe_sqrt(self) -> Self {
        let x = self.value();
        if x > 0.0 {
            let s = x.sqrt();
            self.chain(s, 0.5 / s)
        } else {
            self.chain(0.0, 0.0)
        }
    }

    /// `eˣ`; d/dx = eˣ.
    #[inline]
    fn exp(self) -> Self {
        let e = self.value().exp();
        self.chain(e, e)
    }

    /// `ln x`; d/dx = 1/x.
    #[inline]
    fn ln(self) -> Self {
        let x = self.value();
        self.chain(x.ln(), 1.0 / x)
    }

    /// `xⁿ` for an integer `n`; d/dx = n·xⁿ⁻¹.
    #[inline]
    fn powi(self, n: i32) -> Self {
        let x = self.value();
        let d = if n == 0 {
            0.0
        } else {
            f64::from(n) * x.powi(n - 1)
        };
        self.chain(x.powi(n), d)
    }

    /// `xʸ`; ∂/∂x = y·xʸ⁻¹, ∂/∂y = xʸ·ln x (taken as 0 where `x ≤ 0`, where the
    /// real power is only defined for integer `y`).
    #[inline]
    fn powf(self, y: Self) -> Self {
        let (xv, yv) = (self.value(), y.value());
        let f = xv.powf(yv);
        let dfdx = if yv == 0.0 {
            0.0
        } else {
            yv * xv.powf(yv - 1.0)
        };
        let dfdy = if xv > 0.0 { f * xv.ln() } else { 0.0 };
        self.chain2(y, f, dfdx, dfdy)
    }

    /// `sin x`; d/dx = cos x.
    #[inline]
    fn sin(self) -> Self {
        let x = self.value();
        self.chain(x.sin(), x.cos())
    }

    /// `cos x`; d/dx = −sin x.
    #[inline]
    fn cos(self) -> Self {
        let x = self.value();
        self.chain(x.cos(), -x.sin())
    }

    /// `tan x`; d/dx = 1 + tan²x.
    #[inline]
    fn tan(self) -> Self {
        let t = self.value().tan();
        self.chain(t, 1.0 + t * t)
    }

    /// `atan2(y = self, x)`; ∂/∂y = x/(x²+y²), ∂/∂x = −y/(x²+y²) (0 at the origin).
    ///
    /// The partials are evaluated after scaling by `s = max(|x|, |y|)`
    /// (`∂/∂y = (x/s)/((x/s)² + (y/s)²)/s`), so `x² + y²` cannot underflow for tiny
    /// arguments (`10⁻³⁰⁰`) or overflow for huge ones (`10²⁰⁰`).
    ///
    /// ```
    /// use usray_ad::{Dual, Real};
    /// let y = Dual::<2>::variable(1e-300, 0);
    /// let x = Dual::<2>::variable(1e-300, 1);
    /// let a = y.atan2(x);
    /// assert!((a.eps[0] - 5e299).abs() < 1e285 && (a.eps[1] + 5e299).abs() < 1e285);
    /// ```
    #[inline]
    fn atan2(self, x: Self) -> Self {
        let (yv, xv) = (self.value(), x.value());
        let s = xv.abs().max(yv.abs());
        let (dy, dx) = if s > 0.0 && s.is_finite() {
            let (xs, ys) = (xv / s, yv / s);
            let r2 = xs * xs + ys * ys;
            (xs / r2 / s, -ys / r2 / s)
        } else {
            (0.0, 0.0)
        };
        self.chain2(x, yv.atan2(xv), dy, dx)
    }

    /// `acos x`; d/dx = −1/√(1−x²) (infinite at ±1: see [`Real::safe_acos`]).
    #[inline]
    fn acos(self) -> Self {
        let x = self.value();
        self.chain(x.acos(), -1.0 / (1.0 - x * x).sqrt())
    }

    /// `acos(clamp(x, −1, 1))` with a finite derivative: `−1/√(1−x²)` for
    /// `|x| < 1`, `0` at and beyond ±1 (the subgradient of the clamped function).
    /// Rounding can push a cosine computed from unit vectors just past ±1.
    ///
    /// ```
    /// use usray_ad::{Dual, Real};
    /// let x = Dual::<1>::variable(1.0, 0);
    /// assert_eq!(x.safe_acos().value(), 0.0);
    /// assert!(x.safe_acos().eps[0].is_finite());
    /// ```
    #[inline]
    fn safe_acos(self) -> Self {
        let x = self.value();
        let r = 1.0 - x * x;
        if r > 0.0 {
            self.chain(x.acos(), -1.0 / r.sqrt())
        } else {
            self.chain(x.clamp(-1.0, 1.0).acos(), 0.0)
        }
    }

    /// `asin x`; d/dx = 1/√(1−x²) (infinite at ±1: see [`Real::safe_asin`]).
    #[inline]
    fn asin(self) -> Self {
        let x = self.value();
        self.chain(x.asin(), 1.0 / (1.0 - x * x).sqrt())
    }

    /// `asin(clamp(x, −1, 1))`: derivative `1/√(1−x²)` for `|x| < 1`, `0` at and
    /// beyond ±1.
    #[inline]
    fn safe_asin(self) -> Self {
        let x = self.value();
        let r = 1.0 - x * x;
        if r > 0.0 {
            self.chain(x.asin(), 1.0 / r.sqrt())
        } else {
            self.chain(x.clamp(-1.0, 1.0).asin(), 0.0)
        }
    }

    /// `|x|`; d/dx = sign x (0 at 0).
    #[inline]
    fn abs(self) -> Self {
        let x = self.value();
        let s = if x > 0.0 {
            1.0
        } else if x < 0.0 {
            -1.0
        } else {
            0.0
        };
        self.chain(x.abs(), s)
    }

    /// The smaller of the two; the derivative follows the chosen argument
    /// (`self` on ties).
    #[inline]
    fn min(self, other: Self) -> Self {
        Self::select(self.value() <= other.value(), self, other)
    }

    /// The larger of the two; the derivative follows the chosen argument
    /// (`self` on ties).
    #[inline]
    fn max(self, other: Self) -> Self {
        Self::select(self.value() >= other.value(), self, other)
    }

    /// `min(max(x, lo), hi)`; the derivative follows whichever value is returned.
    #[inline]
    fn clamp(self, lo: Self, hi: Self) -> Self {
        self.max(lo).min(hi)
    }

    /// `if cond { a } else { b }`: branch selection. The condition carries no
    /// derivative; the chosen branch keeps its own.
    #[inline]
    fn select(cond: bool, a: Self, b: Self) -> Self {
        if cond {
            a
        } else {
            b
        }
    }

    /// The paper's parameter map, eq. (clip01): `clip(x, 0, 1)` with derivative 1
    /// for `0 < x < 1` and **0 for `x ≤ 0` or `x ≥ 1`** (eq. clip_grad), so a
    /// parameter saturated at a bound receives no gradient.
    ///
    /// ```
    /// use usray_ad::{Dual, Real};
    /// assert_eq!(Dual::<1>::variable(0.3, 0).clip01().eps[0], 1.0);
    /// assert_eq!(Dual::<1>::variable(1.0, 0).clip01().eps[0], 0.0);
    /// assert_eq!(Dual::<1>::variable(-2.0, 0).clip01().value(), 0.0);
    /// ```
    #[inline]
    fn clip01(self) -> Self {
        let x = self.value();
        if x > 0.0 && x < 1.0 {
            self
        } else {
            Self::from_f64(x.clamp(0.0, 1.0))
        }
    }
}

/// Implements [`Real`] for a native float with the native calls (no derivative
/// bookkeeping at all).
macro_rules! impl_real_float {
    ($t:ty) => {
        impl Real for $t {
            #[inline(always)]
            fn from_f64(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn value(self) -> f64 {
                f64::from(self)
            }
            #[inline(always)]
            fn chain(self, f: f64, _df: f64) -> Self {
                f as $t
            }
            #[inline(always)]
            fn chain2(self, _other: Self, f: f64, _dfdx: f64, _dfdy: f64) -> Self {
                f as $t
            }
            #[inline(always)]
            fn detach(self) -> Self {
                self
            }
            #[inline(always)]
            fn scale(self, k: f64) -> Self {
                self * (k as $t)
            }
            #[inline(always)]
            fn recip(self) -> Self {
                1.0 / self
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn safe_sqrt(self) -> Self {
                <$t>::sqrt(<$t>::max(self, 0.0))
            }
            #[inline(always)]
            fn exp(self) -> Self {
                <$t>::exp(self)
            }
            #[inline(always)]
            fn ln(self) -> Self {
                <$t>::ln(self)
            }
            #[inline(always)]
            fn powi(self, n: i32) -> Self {
                <$t>::powi(self, n)
            }
            #[inline(always)]
            fn powf(self, y: Self) -> Self {
                <$t>::powf(self, y)
            }
            #[inline(always)]
            fn sin(self) -> Self {
                <$t>::sin(self)
            }
            #[inline(always)]
            fn cos(self) -> Self {
                <$t>::cos(self)
            }
            #[inline(always)]
            fn tan(self) -> Self {
                <$t>::tan(self)
            }
            #[inline(always)]
            fn atan2(self, x: Self) -> Self {
                <$t>::atan2(self, x)
            }
            #[inline(always)]
            fn acos(self) -> Self {
                <$t>::acos(self)
            }
            #[inline(always)]
            fn safe_acos(self) -> Self {
                <$t>::acos(<$t>::clamp(self, -1.0, 1.0))
            }
            #[inline(always)]
            fn asin(self) -> Self {
                <$t>::asin(self)
            }
            #[inline(always)]
            fn safe_asin(self) -> Self {
                <$t>::asin(<$t>::clamp(self, -1.0, 1.0))
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn clip01(self) -> Self {
                <$t>::clamp(self, 0.0, 1.0)
            }
        }
    };
}

impl_real_float!(f64);
impl_real_float!(f32);
