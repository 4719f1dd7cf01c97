//! [`Var`], the reverse-mode scalar: its two [`Real`] primitives and the one
//! place an operation appends a node to the tape ([`record`]).

use super::tape::{check_live, live, stale, tape, valid, Node};
use crate::Real;

/// A reverse-mode variable: a value and the index of its tape node.
///
/// `Copy`, 24 bytes. Comparisons (`==`, `<`, …) look at the value only.
///
/// ```
/// use usray_ad::reverse::Var;
/// use usray_ad::Real;
/// let c = Var::constant(2.0); // usable anywhere, never recorded
/// assert_eq!((c * c).value(), 4.0);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct Var {
    pub(super) value: f64,
    /// `∂value/∂(node index)`: the product of the partials of the unary steps
    /// (and binary steps with a constant operand) applied since that node was
    /// recorded, which therefore need no node of their own. A zero partial
    /// turns the result into a constant, so this is 0 for a non-constant only
    /// by underflow.
    pub(super) scale: f64,
    /// Node index on the tape; 0 = constant (node 0 is a dummy sink).
    pub(super) index: u32,
    /// Id of the recording the node belongs to (ignored for constants).
    pub(super) rec: u32,
}

impl Var {
    /// A constant (no derivative, no tape node); valid in any recording and
    /// outside recordings.
    ///
    /// ```
    /// use usray_ad::reverse::Var;
    /// use usray_ad::Real;
    /// assert_eq!(Var::constant(1.5).value(), 1.5);
    /// ```
    #[inline(always)]
    pub const fn constant(value: f64) -> Self {
        Self {
            value,
            scale: 0.0,
            index: 0,
            rec: 0,
        }
    }

    /// True for a constant (a `Var` that carries no derivative).
    ///
    /// ```
    /// use usray_ad::reverse::{Recording, Var};
    /// use usray_ad::Real;
    /// let rec = Recording::start();
    /// let x = rec.input(1.0);
    /// assert!(!x.is_constant());
    /// assert!(x.detach().is_constant());
    /// ```
    #[inline(always)]
    pub const fn is_constant(self) -> bool {
        self.index == 0
    }
}

impl Real for Var {
    #[inline(always)]
    fn from_f64(x: f64) -> Self {
        Self::constant(x)
    }

    #[inline(always)]
    fn value(self) -> f64 {
        self.value
    }

    /// True when the value is finite. A `Var` does not know its derivatives
    /// before the sweep; check the gradient buffer afterwards.
    #[inline]
    fn is_finite(self) -> bool {
        self.value.is_finite()
    }

    /// `y = f(x)` with partial `df`: records nothing. The result points at the
    /// same node as `x`, its scale multiplied by `df` (the chain rule along a
    /// unary chain). A zero partial gives a constant: the edge carries nothing,
    /// even an infinite adjoint (`0·∞ = 0`, the convention of `Dual`).
    #[inline(always)]
    fn chain(self, f: f64, df: f64) -> Self {
        if self.index == 0 {
            return Self::constant(f);
        }
        check_live(self.rec);
        let scale = self.scale * df;
        if df == 0.0 {
            return Self::constant(f);
        }
        Self {
            value: f,
            scale,
            index: self.index,
            rec: self.rec,
        }
    }

    /// `z = g(x, y)` with partials `dfdx`, `dfdy`: one node when both arguments
    /// carry derivatives of different nodes; with a constant argument, or both
    /// pointing at the same node ([`record`]), this is a unary step and records
    /// nothing.
    #[inline(always)]
    fn chain2(self, other: Self, f: f64, dfdx: f64, dfdy: f64) -> Self {
        match (self.index == 0, other.index == 0) {
            (true, true) => Self::constant(f),
            (false, true) => self.chain(f, dfdx),
            (true, false) => other.chain(f, dfdy),
            (false, false) => record(f, self, dfdx, other, dfdy),
        }
    }
}

/// Append the node `value ← (a, da), (b, db)` to this thread's tape.
///
/// The only place an operation touches the tape. Forced inline, with the tape
/// borrowed directly (no closure): the thread-local access is then a
/// thread-pointer load in every operation. Left to the compiler, this function
/// (or a closure around the tape access) stayed out of line in much of the
/// transport's code, a call per recorded node: the 16-parameter replay of the
/// transport's `gradient_cost` example was 4–10% slower with those placements
/// (`docs/performance.md`).
///
/// Both `a` and `b` carry derivatives (non-zero index); their scales are folded
/// into the partials. When both point at the same node nothing is appended
/// ([`same_node`]; tested here rather than in [`Real::chain2`], which is
/// inlined into every operation and whose size decides what else the compiler
/// inlines).
#[inline(always)]
fn record(value: f64, a: Var, da: f64, b: Var, db: f64) -> Var {
    if a.index == b.index {
        return same_node(value, a, da, b, db);
    }
    let live = live();
    if !valid(a.rec, live) || !valid(b.rec, live) {
        stale(if valid(a.rec, live) { b.rec } else { a.rec }, live.0);
    }
    let (ea, eb) = (a.scale * da, b.scale * db);
    let t = &mut *tape().borrow_mut();
    // A zero partial points at the dummy node: the edge carries nothing,
    // even an infinite adjoint or scale (`0·∞ = 0`, the convention of `Dual`).
    let index = t.push(Node {
        a: if da == 0.0 { 0 } else { a.index },
        b: if db == 0.0 { 0 } else { b.index },
        da: ea,
        db: eb,
    });
    Var {
        value,
        scale: 1.0,
        index,
        rec: live.0,
    }
}

/// `value = g(a, b)` where `a` and `b` point at the same node `n` (`x·x`,
/// `x − 2x`, `v·v` in a dot product, …): a unary function of `n` with
/// `∂value/∂n = a.scale·da + b.scale·db` (the chain rule through both
/// arguments), so no node is recorded. A zero local partial cuts its term, even
/// through an infinite scale (`0·∞ = 0`, as in [`record`]); a zero total makes
/// the result a constant (as in [`Real::chain`]).
#[inline(always)]
fn same_node(value: f64, a: Var, da: f64, b: Var, db: f64) -> Var {
    check_live(a.rec);
    check_live(b.rec);
    let term = |scale: f64, d: f64| if d == 0.0 { 0.0 } else { scale * d };
    let scale = term(a.scale, da) + term(b.scale, db);
    if scale == 0.0 {
        return Var::constant(value);
    }
    Var {
        value,
        scale,
        index: a.index,
        rec: a.rec,
    }
}
