//! Random expression trees over the elementary functions of `Real`, shared by the
//! integration tests. Every node maps its arguments into the function's domain
//! and keeps kinks away (e.g. `ln(a² + ½)`, `acos(0.9·sin a)`,
//! `min(sin a, cos b + 3)`), so each tree is smooth everywhere and finite
//! differences are meaningful.
#![allow(dead_code)]

use proptest::prelude::*;
use usray_ad::helpers::{ScalarFn, VectorFn};
use usray_ad::Real;

/// Number of input variables of every tree.
pub const NVARS: usize = 3;

/// A unary node.
#[derive(Clone, Copy, Debug)]
pub enum U {
    Neg,
    Sqrt,
    SafeSqrt,
    Ln,
    Exp,
    Sin,
    Cos,
    Tan,
    Acos,
    Asin,
    SafeAcos,
    SafeAsin,
    AbsNeg,
    AbsPos,
    Recip,
    Clip01,
}

/// A binary node.
#[derive(Clone, Copy, Debug)]
pub enum B {
    Add,
    Sub,
    Mul,
    Div,
    Atan2,
    Powf,
    Min,
    Max,
}

/// An expression tree.
#[derive(Clone, Debug)]
pub enum E {
    X(usize),
    C(f64),
    Un(U, Box<E>),
    Bin(B, Box<E>, Box<E>),
    Powi(Box<E>, i32),
    Scale(Box<E>, f64),
    Sum(Vec<E>),
}

/// Evaluate in any `Real`.
pub fn eval<T: Real>(e: &E, x: &[T]) -> T {
    let half = T::from_f64(0.5);
    match e {
        E::X(i) => x[*i],
        E::C(c) => T::from_f64(*c),
        E::Un(u, a) => {
            let a = eval(a, x);
            match u {
                U::Neg => -a,
                U::Sqrt => (a * a + half).sqrt(),
                U::SafeSqrt => (a * a + half).safe_sqrt(),
                U::Ln => (a * a + half).ln(),
                U::Exp => a.sin().exp(),
                U::Tan => a.sin().scale(0.5).tan(),
                U::Sin => a.sin(),
                U::Cos => a.cos(),
                U::Acos => a.sin().scale(0.9).acos(),
                U::Asin => a.cos().scale(0.9).asin(),
                U::SafeAcos => a.cos().scale(0.9).safe_acos(),
                U::SafeAsin => a.sin().scale(0.9).safe_asin(),
                U::AbsNeg => (a.sin() - T::from_f64(2.0)).abs(),
                U::AbsPos => (a.cos() + T::from_f64(2.0)).abs(),
                U::Recip => (a * a + half).recip(),
                U::Clip01 => (half + a.sin().scale(0.4)).clip01(),
            }
        }
        E::Bin(b, l, r) => {
            let (l, r) = (eval(l, x), eval(r, x));
            match b {
                B::Add => l + r,
                B::Sub => l - r,
                B::Mul => l * r,
                B::Div => l / (r * r + half),
                B::Atan2 => l.atan2(r * r + half),
                B::Powf => (l * l + half).powf(r.sin()),
                B::Min => l.sin().min(r.cos() + T::from_f64(3.0)),
                B::Max => l.sin().max(r.cos() + T::from_f64(3.0)),
            }
        }
        E::Powi(a, n) => (eval(a, x).sin() + T::from_f64(1.5)).powi(*n),
        E::Scale(a, k) => eval(a, x).scale(*k),
        E::Sum(v) => v.iter().map(|e| eval(e, x)).sum(),
    }
}

/// A tree as a scalar function.
pub struct Tree(pub E);

impl ScalarFn for Tree {
    fn eval<T: Real>(&self, x: &[T]) -> T {
        eval(&self.0, x)
    }
}

/// Several trees as a vector function.
pub struct Trees(pub Vec<E>);

impl VectorFn for Trees {
    fn eval<T: Real>(&self, x: &[T], out: &mut [T]) {
        for (o, e) in out.iter_mut().zip(&self.0) {
            *o = eval(e, x);
        }
    }
}

const UNARY: [U; 16] = [
    U::Neg,
    U::Sqrt,
    U::SafeSqrt,
    U::Ln,
    U::Exp,
    U::Sin,
    U::Cos,
    U::Tan,
    U::Acos,
    U::Asin,
    U::SafeAcos,
    U::SafeAsin,
    U::AbsNeg,
    U::AbsPos,
    U::Recip,
    U::Clip01,
];
const BINARY: [B; 8] = [
    B::Add,
    B::Sub,
    B::Mul,
    B::Div,
    B::Atan2,
    B::Powf,
    B::Min,
    B::Max,
];

/// Random trees of depth ≤ 6 (median ≈ 20 nodes, up to a few hundred).
pub fn tree() -> BoxedStrategy<E> {
    tree_of_depth(6)
}

fn tree_of_depth(depth: u32) -> BoxedStrategy<E> {
    let leaf = prop_oneof![
        3 => (0..NVARS).prop_map(E::X),
        1 => (-2.0..2.0f64).prop_map(E::C),
    ];
    if depth == 0 {
        return leaf.boxed();
    }
    let inner = tree_of_depth(depth - 1);
    prop_oneof![
        2 => leaf,
        5 => (prop::sample::select(&UNARY[..]), inner.clone())
            .prop_map(|(u, a)| E::Un(u, Box::new(a))),
        5 => (prop::sample::select(&BINARY[..]), inner.clone(), inner.clone())
            .prop_map(|(b, l, r)| E::Bin(b, Box::new(l), Box::new(r))),
        1 => (inner.clone(), -3..=3i32).prop_map(|(a, n)| E::Powi(Box::new(a), n)),
        1 => (inner.clone(), -2.0..2.0f64).prop_map(|(a, k)| E::Scale(Box::new(a), k)),
        1 => prop::collection::vec(inner, 1..4).prop_map(E::Sum),
    ]
    .boxed()
}

/// A random input point.
pub fn point() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-2.0..2.0f64, NVARS)
}
