//! Forward mode: the dual number [`Dual<N>`] with `N` partial derivatives.
//!
//! A `Dual<N>` is the first-order truncated Taylor expansion
//! `x + Σᵢ εᵢ·eᵢ` with `eᵢ·eⱼ = 0`: `re` is the value, `eps[i]` the derivative
//! with respect to the `i`-th seeded input. One evaluation of a generic function
//! in `Dual<N>` gives the value and `N` directional derivatives at once, with no
//! tape and no allocation; cost grows linearly in `N`, so forward mode suits a
//! handful of parameters (see [`crate::reverse`] for many).
//!
//! Every derivative rule comes from [`Real::chain`] / [`Real::chain2`]
//! (implemented here once): the operators below only state the partials of
//! `+ − × ÷`, e.g. `∂(x·y)/∂x = y`.
//!
//! # `0·∞ = 0`
//! Every product of a partial and a tangent treats an exact zero as absorbing:
//! where a rule's partial is infinite (`√x` at 0, `acos` at ±1) but the incoming
//! tangent is exactly zero (a constant, or a direction that does not move `x`), the
//! outgoing tangent is `0`, not `∞·0 = NaN`; likewise an infinite tangent through
//! a zero partial (`0·√x` at `x = 0`) contributes `0`. A derivative is a sum over
//! paths of products of partials, so with this convention a path containing an
//! exact zero contributes nothing whatever the order of multiplication, and
//! forward and reverse mode (which uses the same convention) agree. It also means
//! a constant `Dual` passes through `sqrt(0)` safely.
//!
//! ```
//! use usray_ad::{Dual, Real};
//! let x = Dual::<2>::variable(3.0, 0);
//! let y = Dual::<2>::variable(4.0, 1);
//! let r = (x * x + y * y).sqrt();
//! assert_eq!(r.re, 5.0);
//! // ∂r/∂x = x/r, ∂r/∂y = y/r
//! assert!((r.eps[0] - 0.6).abs() < 1e-15 && (r.eps[1] - 0.8).abs() < 1e-15);
//! assert_eq!(Dual::<2>::constant(0.0).sqrt().eps, [0.0, 0.0]);
//! ```

use crate::Real;
use core::cmp::Ordering;
use core::iter::Sum;
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// A forward-mode dual number with `N` partial derivatives.
///
/// Comparisons (`==`, `<`, …) look at [`Dual::re`] only, as [`Real`] requires.
///
/// ```
/// use usray_ad::{Dual, Real};
/// fn f<T: Real>(x: T) -> T {
///     x * x.sin()
/// }
/// let d = f(Dual::<1>::variable(2.0, 0));
/// assert_eq!(d.re, 2.0 * 2.0_f64.sin());
/// assert_eq!(d.eps[0], 2.0_f64.sin() + 2.0 * 2.0_f64.cos());
/// ```
#[derive(Clone, Copy, Debug)]
pub struct Dual<const N: usize> {
    /// The value.
    pub re: f64,
    /// The partial derivatives with respect to the `N` seeded inputs.
    pub eps: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// A dual from its value and partials.
    ///
    /// ```
    /// use usray_ad::Dual;
    /// let d = Dual::new(1.0, [0.5, 2.0]);
    /// assert_eq!(d.eps[1], 2.0);
    /// ```
    #[inline]
    pub const fn new(re: f64, eps: [f64; N]) -> Self {
        Self { re, eps }
    }

    /// A constant: value `re`, all partials zero.
    ///
    /// ```
    /// use usray_ad::Dual;
    /// assert_eq!(Dual::<3>::constant(2.0).eps, [0.0; 3]);
    /// ```
    #[inline]
    pub const fn constant(re: f64) -> Self {
        Self { re, eps: [0.0; N] }
    }

    /// The `index`-th input variable: value `re`, `∂/∂x_index = 1`, other partials 0.
    ///
    /// # Panics
    /// If `index >= N`.
    ///
    /// ```
    /// use usray_ad::Dual;
    /// assert_eq!(Dual::<3>::variable(2.0, 1).eps, [0.0, 1.0, 0.0]);
    /// ```
    #[inline]
    pub fn variable(re: f64, index: usize) -> Self {
        assert!(
            index < N,
            "Dual::<{N}>::variable: index {index} out of range (N = {N})"
        );
        let mut eps = [0.0; N];
        eps[index] = 1.0;
        Self { re, eps }
    }

    /// A variable moving along direction `dir`: value `re`, partials `dir`
    /// (for a directional derivative / Jacobian-vector product).
    ///
    /// ```
    /// use usray_ad::Dual;
    /// let d = Dual::seeded(2.0, [0.5]);
    /// assert_eq!((d * d).eps[0], 2.0); // 2·x·ẋ
    /// ```
    #[inline]
    pub const fn seeded(re: f64, dir: [f64; N]) -> Self {
        Self { re, eps: dir }
    }
}

impl<const N: usize> Default for Dual<N> {
    /// The constant 0.
    #[inline]
    fn default() -> Self {
        Self::constant(0.0)
    }
}

impl<const N: usize> From<f64> for Dual<N> {
    /// A constant.
    #[inline]
    fn from(x: f64) -> Self {
        Self::constant(x)
    }
}

/// `d·e` for a partial `d` and a tangent `e`, with `0·∞ = 0`: an exactly zero
/// partial or tangent contributes nothing even when the other factor is
/// infinite. The branches are on the scalar `d` only, so the common case is a
/// plain (vectorisable) product.
#[inline(always)]
fn scaled<const N: usize>(d: f64, e: &[f64; N]) -> [f64; N] {
    let mut out = [0.0; N];
    if d != 0.0 && d.is_finite() {
        // Finite non-zero partial: the plain product is already right
        // (0 stays 0, ∞ stays ∞).
        for i in 0..N {
            out[i] = d * e[i];
        }
    } else if d != 0.0 {
        // Infinite (or NaN) partial: zero tangents stay zero.
        for i in 0..N {
            out[i] = if e[i] == 0.0 { 0.0 } else { d * e[i] };
        }
    }
    // d == 0: the edge carries nothing, whatever the tangent.
    out
}

impl<const N: usize> Real for Dual<N> {
    #[inline(always)]
    fn from_f64(x: f64) -> Self {
        Self::constant(x)
    }

    #[inline(always)]
    fn value(self) -> f64 {
        self.re
    }

    /// Forward chain rule: `ε_out = f'(x)·ε` (with `0·∞ = 0`, see the module docs).
    #[inline(always)]
    fn chain(self, f: f64, df: f64) -> Self {
        Self {
            re: f,
            eps: scaled(df, &self.eps),
        }
    }

    /// Forward chain rule for `g(x, y)`: `ε_out = ∂g/∂x·ε_x + ∂g/∂y·ε_y`.
    #[inline(always)]
    fn chain2(self, other: Self, f: f64, dfdx: f64, dfdy: f64) -> Self {
        let mut eps = scaled(dfdx, &self.eps);
        let b = scaled(dfdy, &other.eps);
        for i in 0..N {
            eps[i] += b[i];
        }
        Self { re: f, eps }
    }

    /// The value and every partial are finite.
    ///
    /// ```
    /// use usray_ad::{Dual, Real};
    /// assert!(!Dual::<1>::variable(0.0, 0).sqrt().is_finite()); // ∂√x/∂x = ∞ at 0
    /// assert!(Dual::<1>::variable(0.0, 0).safe_sqrt().is_finite());
    /// ```
    #[inline]
    fn is_finite(self) -> bool {
        self.re.is_finite() && self.eps.iter().all(|e| e.is_finite())
    }

    #[inline(always)]
    fn scale(self, k: f64) -> Self {
        Self {
            re: self.re * k,
            eps: scaled(k, &self.eps),
        }
    }
}

impl<const N: usize> PartialEq for Dual<N> {
    /// Compares values only.
    #[inline]
    fn eq(&self, other: &Self) -> bool {
        self.re == other.re
    }
}

impl<const N: usize> PartialOrd for Dual<N> {
    /// Compares values only.
    #[inline]
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        self.re.partial_cmp(&other.re)
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    /// ∂(x+y)/∂x = 1, ∂(x+y)/∂y = 1.
    #[inline(always)]
    fn add(self, rhs: Self) -> Self {
        self.chain2(rhs, self.re + rhs.re, 1.0, 1.0)
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    /// ∂(x−y)/∂x = 1, ∂(x−y)/∂y = −1.
    #[inline(always)]
    fn sub(self, rhs: Self) -> Self {
        self.chain2(rhs, self.re - rhs.re, 1.0, -1.0)
    }
}

impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    /// ∂(x·y)/∂x = y, ∂(x·y)/∂y = x.
    #[inline(always)]
    fn mul(self, rhs: Self) -> Self {
        self.chain2(rhs, self.re * rhs.re, rhs.re, self.re)
    }
}

impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    /// ∂(x/y)/∂x = 1/y, ∂(x/y)/∂y = −x/y² = −(x/y)/y.
    #[inline(always)]
    fn div(self, rhs: Self) -> Self {
        // The value is the true quotient (not `x·(1/y)`), so every number type
        // computes bit-identical values and a replay takes the same branches as
        // the `f64` render.
        let q = self.re / rhs.re;
        let inv = 1.0 / rhs.re;
        self.chain2(rhs, q, inv, -q * inv)
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    /// d(−x)/dx = −1.
    #[inline(always)]
    fn neg(self) -> Self {
        self.chain(-self.re, -1.0)
    }
}

/// `Dual ∘ f64` and `f64 ∘ Dual` by promoting the `f64` to a constant (the
/// zero partials fold away after inlining).
macro_rules! mixed_ops {
    ($($tr:ident $m:ident $atr:ident $am:ident),*) => {$(
        impl<const N: usize> $tr<f64> for Dual<N> {
            type Output = Self;
            #[inline(always)]
            fn $m(self, rhs: f64) -> Self {
                $tr::$m(self, Self::constant(rhs))
            }
        }
        impl<const N: usize> $tr<Dual<N>> for f64 {
            type Output = Dual<N>;
            #[inline(always)]
            fn $m(self, rhs: Dual<N>) -> Dual<N> {
                $tr::$m(Dual::constant(self), rhs)
            }
        }
        impl<const N: usize> $atr for Dual<N> {
            #[inline(always)]
            fn $am(&mut self, rhs: Self) {
                *self = $tr::$m(*self, rhs);
            }
        }
        impl<const N: usize> $atr<f64> for Dual<N> {
            #[inline(always)]
            fn $am(&mut self, rhs: f64) {
                *self = $tr::$m(*self, Self::constant(rhs));
            }
        }
    )*};
}
mixed_ops!(
    Add add AddAssign add_assign,
    Sub sub SubAssign sub_assign,
    Mul mul MulAssign mul_assign,
    Div div DivAssign div_assign
);

impl<const N: usize> Sum for Dual<N> {
    #[inline]
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::constant(-0.0), |a, b| a + b)
    }
}

impl<'a, const N: usize> Sum<&'a Dual<N>> for Dual<N> {
    #[inline]
    fn sum<I: Iterator<Item = &'a Self>>(iter: I) -> Self {
        iter.fold(Self::constant(-0.0), |a, b| a + *b)
    }
}
