//! Comparisons, conversions and arithmetic operators of [`Var`]: each
//! operator is [`Real::chain`] or [`Real::chain2`] with its partials.

use super::Var;
use crate::Real;
use core::cmp::Ordering;
use core::iter::Sum;
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

impl PartialEq for Var {
    /// Compares values only.
    #[inline]
    fn eq(&self, other: &Self) -> bool {
        self.value == other.value
    }
}

impl PartialOrd for Var {
    /// Compares values only.
    #[inline]
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        self.value.partial_cmp(&other.value)
    }
}

impl Default for Var {
    /// The constant 0.
    #[inline]
    fn default() -> Self {
        Self::constant(0.0)
    }
}

impl From<f64> for Var {
    /// A constant.
    #[inline]
    fn from(x: f64) -> Self {
        Self::constant(x)
    }
}

impl Add for Var {
    type Output = Self;
    /// ∂(x+y)/∂x = 1, ∂(x+y)/∂y = 1.
    #[inline(always)]
    fn add(self, rhs: Self) -> Self {
        self.chain2(rhs, self.value + rhs.value, 1.0, 1.0)
    }
}

impl Sub for Var {
    type Output = Self;
    /// ∂(x−y)/∂x = 1, ∂(x−y)/∂y = −1.
    #[inline(always)]
    fn sub(self, rhs: Self) -> Self {
        self.chain2(rhs, self.value - rhs.value, 1.0, -1.0)
    }
}

impl Mul for Var {
    type Output = Self;
    /// ∂(x·y)/∂x = y, ∂(x·y)/∂y = x.
    #[inline(always)]
    fn mul(self, rhs: Self) -> Self {
        self.chain2(rhs, self.value * rhs.value, rhs.value, self.value)
    }
}

impl Div for Var {
    type Output = Self;
    /// ∂(x/y)/∂x = 1/y, ∂(x/y)/∂y = −(x/y)/y.
    #[inline(always)]
    fn div(self, rhs: Self) -> Self {
        // The value is the true quotient (not `x·(1/y)`), so every number type
        // computes bit-identical values and a replay takes the same branches as
        // the `f64` render.
        let q = self.value / rhs.value;
        let inv = 1.0 / rhs.value;
        self.chain2(rhs, q, inv, -q * inv)
    }
}

impl Neg for Var {
    type Output = Self;
    /// d(−x)/dx = −1.
    #[inline(always)]
    fn neg(self) -> Self {
        self.chain(-self.value, -1.0)
    }
}

/// `Var ∘ f64` and `f64 ∘ Var` by promoting the `f64` to a constant.
macro_rules! mixed_ops {
    ($($tr:ident $m:ident $atr:ident $am:ident),*) => {$(
        impl $tr<f64> for Var {
            type Output = Self;
            #[inline(always)]
            fn $m(self, rhs: f64) -> Self {
                $tr::$m(self, Self::constant(rhs))
            }
        }
        impl $tr<Var> for f64 {
            type Output = Var;
            #[inline(always)]
            fn $m(self, rhs: Var) -> Var {
                $tr::$m(Var::constant(self), rhs)
            }
        }
        impl $atr for Var {
            #[inline(always)]
            fn $am(&mut self, rhs: Self) {
                *self = $tr::$m(*self, rhs);
            }
        }
        impl $atr<f64> for Var {
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

impl Sum for Var {
    #[inline]
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::constant(-0.0), |a, b| a + b)
    }
}

impl<'a> Sum<&'a Var> for Var {
    #[inline]
    fn sum<I: Iterator<Item = &'a Self>>(iter: I) -> Self {
        iter.fold(Self::constant(-0.0), |a, b| a + *b)
    }
}
