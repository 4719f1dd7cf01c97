//! Reverse mode: a `Copy` variable [`Var`] recorded on a thread-local tape.
//!
//! Each thread (each rayon worker) owns one tape. A [`Recording`] claims it:
//! inputs are created with [`Recording::input`], generic code runs in [`Var`]
//! (every operation between two `Var`s pointing at different nodes appends one
//! node: two parents and their partials; a unary operation, a binary one with a
//! constant argument, or one whose two arguments point at the same node, appends
//! nothing but multiplies the result's *scale*, the partial of its value with
//! respect to the node it points at), and [`Recording::gradient`] sweeps the tape backwards once, *adding*
//! `∂y/∂xᵢ` into a caller-provided slice. Dropping the recording (or
//! [`Recording::restart`]) clears the tape but keeps its memory, so a per-path
//! loop allocates nothing once the tape has grown to the longest path;
//! [`Recording::freeze`] / [`Recording::rewind`] keep a shared prefix (inputs
//! and what was computed from them once) across paths. Nothing
//! is shared between threads, so results do not depend on scheduling.
//!
//! Constants ([`Var::constant`], [`Real::from_f64`], [`Real::detach`]) carry the
//! sentinel index 0 and create no node; operations on constants only are not
//! recorded at all.
//!
//! ```
//! use usray_ad::reverse::{Recording, Var};
//! use usray_ad::Real;
//!
//! fn tof<T: Real>(depth: T, c: T) -> T {
//!     (depth + depth) / c // two-way time of flight
//! }
//! let mut grad = [0.0; 2];
//! let rec = Recording::start();
//! let (d, c) = (rec.input(0.03), rec.input(1540.0));
//! let t = tof(d, c);
//! rec.gradient(t, &mut grad);
//! drop(rec); // tape cleared, memory kept for the next path
//! assert_eq!(t.value(), 0.06 / 1540.0);
//! assert_eq!(grad, [2.0 / 1540.0, -0.06 / (1540.0 * 1540.0)]);
//! ```
//!
//! # Misuse
//! - Starting a second [`Recording`] on a thread while one is live panics
//!   (`nested reverse-mode recordings are not supported`). Nest forward mode
//!   ([`crate::Dual`]) inside reverse mode instead if needed.
//! - Operating on a [`Var`] whose recording has ended, or that belongs to
//!   another thread's recording, panics with a message saying so: every `Var`
//!   carries the id of its recording, checked at every operation. (Ids are a
//!   32-bit global counter; a stale `Var` kept across ~4·10⁹ recordings could in
//!   principle alias, which is why this is documented as best effort.)
//! - Constants never panic: they belong to no recording.
//! - Do not call into rayon (`join`, `par_iter`) while a `Recording` is live:
//!   a worker that steals another task while waiting may start a second
//!   recording on the same thread, which panics as nesting. Per-path code is
//!   serial, so record inside the parallel task, not around it.
//!
//! No `unsafe` is used anywhere.
//!
//! # Memory and cost
//! A node is 24 bytes (two parent indices, two partials); a recording with `n`
//! operations between two non-constant `Var`s uses `24·n` bytes of tape plus
//! `8·n` of adjoints, kept across recordings (unary steps and operations with
//! a constant cost no memory; a `Var` is 24 bytes). Each thread's tape header
//! (≈ 100 bytes) is leaked so that the thread-local needs no destructor (which
//! keeps every operation's tape access inline); the buffers themselves are
//! freed at thread exit. On the tracer-like benchmark kernel (61 nodes, of
//! which 8 inputs) a record + sweep costs ≈ 7.3× the plain `f64` evaluation,
//! for any number of inputs (see `docs/performance.md`).

use crate::Real;
use core::cell::{Cell, RefCell};
use core::cmp::Ordering;
use core::iter::Sum;
use core::marker::PhantomData;
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};
use core::sync::atomic::{AtomicU32, Ordering as AtomicOrdering};

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
    value: f64,
    /// `∂value/∂(node index)`: the product of the partials of the unary steps
    /// (and binary steps with a constant operand) applied since that node was
    /// recorded, which therefore need no node of their own. A zero partial
    /// turns the result into a constant, so this is 0 for a non-constant only
    /// by underflow.
    scale: f64,
    /// Node index on the tape; 0 = constant (node 0 is a dummy sink).
    index: u32,
    /// Id of the recording the node belongs to (ignored for constants).
    rec: u32,
}

/// One tape entry: `adj[a] += adj[self]·da`, `adj[b] += adj[self]·db`.
/// Every node recorded by an operation has two parents (unary steps record
/// none, see [`Var`]'s scale); an edge with a zero partial points at the dummy
/// node 0, and input nodes point both at 0. This keeps the reverse sweep free
/// of branches on arity.
#[derive(Clone, Copy, Debug)]
struct Node {
    a: u32,
    b: u32,
    da: f64,
    db: f64,
}

const DUMMY: Node = Node {
    a: 0,
    b: 0,
    da: 0.0,
    db: 0.0,
};

/// The per-thread tape (the ids of the live recording are in [`LIVE`]).
struct Tape {
    nodes: Vec<Node>,
    inputs: Vec<u32>,
    adj: Vec<f64>,
    /// Lengths of `nodes` and `inputs` at [`Recording::freeze`] (what
    /// [`Recording::rewind`] keeps); 0 when not frozen.
    frozen: (usize, usize),
}

thread_local! {
    /// This thread's tape. The tape itself is leaked (`Box::leak`) so that this
    /// thread-local holds only a `Copy` reference and needs no destructor: access
    /// is then a plain thread-pointer load the compiler inlines into every
    /// operation (a thread-local with a destructor went through an out-of-line
    /// `LocalKey::with` per operation, ~3× slower). The buffers are freed at
    /// thread exit by [`TapeRelease`]; only the empty header (≈ 100 bytes) stays
    /// leaked per thread that ever used reverse mode.
    static TAPE: Cell<Option<&'static RefCell<Tape>>> = const { Cell::new(None) };
    /// Frees this thread's tape buffers when the thread exits.
    static RELEASE: TapeRelease = const { TapeRelease };
    /// Ids of the recording live on this thread: `(current, frozen)`, both 0
    /// if none. `Var`s recorded now carry the current id; those made before
    /// [`Recording::freeze`] carry the frozen id (0 when not frozen, which no
    /// non-constant `Var` carries). Kept outside the tape so that checking a
    /// `Var` is one thread-local load, with no borrow.
    static LIVE: Cell<(u32, u32)> = const { Cell::new((0, 0)) };
}

/// Ids of the recording live on this thread, `(current, frozen)` (see [`LIVE`]).
#[inline(always)]
fn live() -> (u32, u32) {
    LIVE.with(Cell::get)
}

/// True when a non-constant `Var` of recording id `rec` may be used now.
#[inline(always)]
fn valid(rec: u32, (current, frozen): (u32, u32)) -> bool {
    // Both compares, no short circuit: whether a `Var` is the path's or the
    // frozen scene's varies from one operation to the next, so a branch
    // between the two would be mispredicted often.
    rec == current || rec == frozen
}

/// Panics unless `rec` (of a non-constant `Var`) belongs to the recording live
/// on this thread.
#[inline(always)]
fn check_live(rec: u32) {
    let live = live();
    if !valid(rec, live) {
        stale(rec, live.0);
    }
}

/// Thread-exit guard: empties the leaked tape's buffers.
struct TapeRelease;

impl Drop for TapeRelease {
    fn drop(&mut self) {
        if let Ok(Some(t)) = TAPE.try_with(Cell::get) {
            if let Ok(mut t) = t.try_borrow_mut() {
                if LIVE
                    .try_with(Cell::get)
                    .is_ok_and(|(current, _)| current == 0)
                {
                    t.nodes = Vec::new();
                    t.inputs = Vec::new();
                    t.adj = Vec::new();
                }
            }
        }
    }
}

/// This thread's tape (created on first use).
#[inline(always)]
fn tape() -> &'static RefCell<Tape> {
    match TAPE.with(Cell::get) {
        Some(t) => t,
        None => new_tape(),
    }
}

#[cold]
#[inline(never)]
fn new_tape() -> &'static RefCell<Tape> {
    let t: &'static RefCell<Tape> = Box::leak(Box::new(RefCell::new(Tape {
        nodes: Vec::new(),
        inputs: Vec::new(),
        adj: Vec::new(),
        frozen: (0, 0),
    })));
    TAPE.with(|c| c.set(Some(t)));
    // Touch the guard so its destructor is registered for this thread.
    let _ = RELEASE.try_with(|_| ());
    t
}

/// Run `f` on this thread's tape.
#[inline(always)]
fn with_tape<R>(f: impl FnOnce(&RefCell<Tape>) -> R) -> R {
    f(tape())
}

/// Source of recording ids, unique across threads (0 is reserved for "none").
/// Threads take blocks of [`ID_BLOCK`] ids, so starting a recording touches the
/// shared counter only once per 4096 recordings (no cache-line ping-pong
/// between rayon workers starting a recording per path).
static NEXT_REC: AtomicU32 = AtomicU32::new(1);
const ID_BLOCK: u32 = 1 << 12;

thread_local! {
    /// This thread's current block of ids: `(next, end)`.
    static IDS: Cell<(u32, u32)> = const { Cell::new((0, 0)) };
}

fn fresh_id() -> u32 {
    IDS.with(|c| {
        let (mut next, mut end) = c.get();
        loop {
            if next == end {
                next = NEXT_REC.fetch_add(ID_BLOCK, AtomicOrdering::Relaxed);
                end = next.wrapping_add(ID_BLOCK);
            }
            let id = next;
            next = next.wrapping_add(1);
            if id != 0 {
                c.set((next, end));
                return id;
            }
        }
    })
}

#[cold]
#[inline(never)]
fn stale(var_rec: u32, tape_rec: u32) -> ! {
    if tape_rec == 0 {
        panic!(
            "usray_ad::reverse: a Var was used after its Recording ended (no recording is \
             live on this thread); Vars are only valid inside the Recording that made them"
        );
    }
    panic!(
        "usray_ad::reverse: a Var from recording #{var_rec} was used in recording \
         #{tape_rec}: it outlived its Recording or belongs to another thread's tape"
    );
}

impl Tape {
    #[inline(always)]
    fn push(&mut self, node: Node) -> u32 {
        let i = self.nodes.len();
        debug_assert!(i < u32::MAX as usize, "reverse tape overflow");
        self.nodes.push(node);
        i as u32
    }

    /// Reset for a new recording `id`, keeping capacity.
    fn begin(&mut self, id: u32) {
        LIVE.with(|c| c.set((id, 0)));
        self.nodes.clear();
        self.inputs.clear();
        self.frozen = (0, 0);
        self.nodes.push(DUMMY);
    }
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

/// Exclusive use of this thread's tape, from [`Recording::start`] to drop.
///
/// Not `Send`: the tape belongs to the thread. Inputs are numbered in creation
/// order; gradients are returned in that order.
///
/// Per-path use (what the transport does), allocation-free in steady state:
/// ```
/// use usray_ad::reverse::Recording;
/// use usray_ad::Real;
/// let theta = [1.0, 2.0];
/// let mut grad = vec![0.0; 2];
/// let mut rec = Recording::start();
/// for path in 0..3 {
///     rec.restart(); // new path: tape emptied, memory kept
///     let p = rec.inputs_array::<2>(&theta);
///     let deposit = p[0] * p[1] * f64::from(path); // path-dependent
///     rec.gradient(deposit, &mut grad); // accumulates over paths
/// }
/// assert_eq!(grad, [2.0 * 3.0, 1.0 * 3.0]); // Σ_path path · (θ₁, θ₀)
/// ```
pub struct Recording {
    /// Id carried by the `Var`s recorded now.
    id: u32,
    /// Id of the `Var`s made before [`Recording::freeze`] (0: not frozen).
    frozen: u32,
    _not_send: PhantomData<*const ()>,
}

impl Recording {
    /// Claim this thread's tape and start recording.
    ///
    /// # Panics
    /// If a recording is already live on this thread (nesting is not supported).
    ///
    /// ```
    /// use usray_ad::reverse::Recording;
    /// let rec = Recording::start();
    /// let x = rec.input(2.0);
    /// drop(rec);
    /// ```
    pub fn start() -> Self {
        let id = fresh_id();
        with_tape(|t| {
            let t = &mut *t.borrow_mut();
            assert!(
                live().0 == 0,
                "usray_ad::reverse: nested reverse-mode recordings are not supported \
                 (a Recording is already live on this thread)"
            );
            t.begin(id);
        });
        Self {
            id,
            frozen: 0,
            _not_send: PhantomData,
        }
    }

    /// Clear the tape and continue as a fresh recording (a new id: `Var`s made
    /// before the restart become invalid). Memory is kept. Equivalent to dropping
    /// and restarting, without giving the tape up.
    pub fn restart(&mut self) {
        let id = fresh_id();
        with_tape(|t| t.borrow_mut().begin(id));
        self.id = id;
        self.frozen = 0;
    }

    /// Keep what has been recorded so far (inputs, and the `Var`s computed from
    /// them) for reuse after each [`Recording::rewind`]: e.g. a scene lifted once
    /// onto the tape and shared by many paths, each recorded, differentiated and
    /// rewound in turn. `Var`s made before the freeze stay valid; those made
    /// after it become invalid at the next rewind (a fresh id, checked as usual).
    /// Memory is kept.
    ///
    /// # Panics
    /// If the recording is already frozen (undo it with [`Recording::restart`]).
    ///
    /// ```
    /// use usray_ad::reverse::Recording;
    /// use usray_ad::Real;
    /// let mut rec = Recording::start();
    /// let [a, b] = rec.inputs_array::<2>(&[3.0, 4.0]);
    /// let shared = a * b; // e.g. the lifted scene: recorded once
    /// rec.freeze();
    /// let mut grad = [0.0; 2];
    /// for k in 1..=2 {
    ///     rec.rewind(); // drops the previous path's nodes, keeps `a`, `b`, `shared`
    ///     let y = shared * f64::from(k) + a; // a path using them
    ///     rec.gradient(y, &mut grad);
    /// }
    /// assert_eq!(grad, [4.0 * 3.0 + 2.0, 3.0 * 3.0]);
    /// ```
    pub fn freeze(&mut self) {
        assert!(
            self.frozen == 0,
            "usray_ad::reverse: Recording::freeze called twice (restart first)"
        );
        let id = fresh_id();
        with_tape(|t| {
            let t = &mut *t.borrow_mut();
            t.frozen = (t.nodes.len(), t.inputs.len());
            LIVE.with(|c| c.set((id, self.id)));
        });
        self.frozen = self.id;
        self.id = id;
    }

    /// Return the tape to the [`Recording::freeze`] point: everything recorded
    /// after it is dropped (memory kept), and `Var`s made after it become
    /// invalid (a fresh id); those made before stay valid.
    ///
    /// # Panics
    /// If the recording is not frozen.
    pub fn rewind(&mut self) {
        assert!(
            self.frozen != 0,
            "usray_ad::reverse: Recording::rewind without Recording::freeze"
        );
        let id = fresh_id();
        with_tape(|t| {
            let t = &mut *t.borrow_mut();
            let (nodes, inputs) = t.frozen;
            t.nodes.truncate(nodes);
            t.inputs.truncate(inputs);
            LIVE.with(|c| c.set((id, self.frozen)));
        });
        self.id = id;
    }

    /// A new input variable with value `x`; inputs are numbered in creation order.
    #[inline]
    pub fn input(&self, x: f64) -> Var {
        with_tape(|t| {
            let t = &mut *t.borrow_mut();
            let i = t.push(DUMMY);
            t.inputs.push(i);
            Var {
                value: x,
                scale: 1.0,
                index: i,
                rec: self.id,
            }
        })
    }

    /// One input per element of `xs`, written into `out` (no allocation).
    ///
    /// # Panics
    /// If `out.len() != xs.len()`.
    pub fn inputs_into(&self, xs: &[f64], out: &mut [Var]) {
        assert_eq!(xs.len(), out.len(), "inputs_into: length mismatch");
        with_tape(|t| {
            let t = &mut *t.borrow_mut();
            // In bulk: one capacity check per buffer, not one per input.
            let first = t.nodes.len();
            let end = first + xs.len();
            assert!(end < u32::MAX as usize, "reverse tape overflow");
            t.nodes.resize(end, DUMMY);
            t.inputs.extend(first as u32..end as u32);
            for ((o, &x), i) in out.iter_mut().zip(xs).zip(first as u32..) {
                *o = Var {
                    value: x,
                    scale: 1.0,
                    index: i,
                    rec: self.id,
                };
            }
        });
    }

    /// `N` inputs as an array (no allocation).
    ///
    /// # Panics
    /// If `xs.len() != N`.
    ///
    /// ```
    /// use usray_ad::reverse::Recording;
    /// use usray_ad::Real;
    /// let rec = Recording::start();
    /// let [a, b] = rec.inputs_array::<2>(&[1.0, 2.0]);
    /// assert_eq!((a + b).value(), 3.0);
    /// ```
    pub fn inputs_array<const N: usize>(&self, xs: &[f64]) -> [Var; N] {
        assert_eq!(xs.len(), N, "inputs_array: length mismatch");
        let mut out = [Var::constant(0.0); N];
        self.inputs_into(xs, &mut out);
        out
    }

    /// Number of inputs created so far in this recording.
    pub fn num_inputs(&self) -> usize {
        with_tape(|t| t.borrow().inputs.len())
    }

    /// Number of tape nodes recorded so far (including one dummy node and the
    /// inputs): a measure of the recording's size.
    pub fn len(&self) -> usize {
        with_tape(|t| t.borrow().nodes.len())
    }

    /// True when nothing but the dummy node is on the tape.
    pub fn is_empty(&self) -> bool {
        self.len() <= 1
    }

    /// Add `∂y/∂xᵢ` to `grad[i]` for every input `xᵢ` (in creation order).
    /// The tape is left intact, so several outputs may be differentiated in turn.
    ///
    /// # Panics
    /// If `grad.len()` differs from the number of inputs, or `y` belongs to
    /// another recording.
    pub fn gradient(&self, y: Var, grad: &mut [f64]) {
        self.vjp(&[y], &[1.0], grad);
    }

    /// Vector-Jacobian product: add `Σⱼ wⱼ·∂yⱼ/∂xᵢ` to `grad[i]`, in one sweep.
    /// This is how a path with several deposits (`ā_k·a_k + τ̄_k·τ_k`) is
    /// differentiated at once.
    ///
    /// # Panics
    /// If `ys.len() != ws.len()`, `grad.len()` differs from the number of inputs,
    /// or a `y` belongs to another recording.
    ///
    /// ```
    /// use usray_ad::reverse::Recording;
    /// use usray_ad::Real;
    /// let rec = Recording::start();
    /// let [x, y] = rec.inputs_array::<2>(&[3.0, 5.0]);
    /// let mut g = [0.0; 2];
    /// rec.vjp(&[x * y, x + y], &[1.0, 10.0], &mut g);
    /// assert_eq!(g, [5.0 + 10.0, 3.0 + 10.0]);
    /// ```
    pub fn vjp(&self, ys: &[Var], ws: &[f64], grad: &mut [f64]) {
        assert_eq!(
            ys.len(),
            ws.len(),
            "vjp: {} outputs but {} weights",
            ys.len(),
            ws.len()
        );
        with_tape(|t| {
            let t = &mut *t.borrow_mut();
            let live = live();
            debug_assert_eq!(live.0, self.id);
            assert_eq!(
                grad.len(),
                t.inputs.len(),
                "gradient: grad has length {} but the recording has {} inputs",
                grad.len(),
                t.inputs.len()
            );
            let Tape {
                nodes, inputs, adj, ..
            } = t;
            let mut top = 0usize;
            for y in ys {
                if y.index != 0 {
                    if !valid(y.rec, live) {
                        stale(y.rec, live.0);
                    }
                    top = top.max(y.index as usize);
                }
            }
            // Only nodes up to the latest output can reach it. The adjoint buffer
            // keeps a power-of-two length (see `sweep`); only `0..=top` is used.
            let size = (top + 1).next_power_of_two();
            if adj.len() < size {
                adj.resize(size, 0.0);
            }
            adj[..=top].fill(0.0);
            for (y, &w) in ys.iter().zip(ws) {
                // A zero weight contributes nothing, even through an infinite
                // scale (`0·∞ = 0`).
                if w != 0.0 {
                    adj[y.index as usize] += w * y.scale;
                }
            }
            // Nodes 1..=lo are inputs (usually all of them, created first):
            // they have no parents, so the sweep stops above them.
            let lo = inputs
                .iter()
                .zip(1u32..)
                .take_while(|&(&i, k)| i == k)
                .count();
            sweep(nodes, &mut adj[..size], top, lo);
            // An input created after every output cannot influence them.
            for (g, &i) in grad.iter_mut().zip(inputs.iter()) {
                let i = i as usize;
                if i <= top {
                    *g += adj[i];
                }
            }
        });
    }
}

/// The reverse sweep: nodes `top, top−1, …, lo + 1`, each pushing its adjoint
/// to its parents (nodes `1..=lo` must be inputs: they have none, and pushing
/// their zero partials to the dummy node would chain every step through the
/// same memory slot). A zero adjoint is not propagated (so an infinite partial on a
/// branch that does not reach the output gives 0, not `0·∞ = NaN`), and zero
/// partials were redirected to the dummy node when recorded: `0·∞ = 0`, the
/// convention of [`crate::Dual`], so both modes agree at singular points.
#[inline]
fn sweep(nodes: &[Node], adj: &mut [f64], top: usize, lo: usize) {
    // `adj.len()` is a power of two above `top`: indexing with `& mask` is then
    // provably in bounds, so the loop carries no bounds checks (and no `unsafe`).
    // Every parent index is below its child, so the mask never changes an index.
    let size = adj.len();
    assert!(size.is_power_of_two() && top < size);
    let mask = size - 1;
    let nodes = &nodes[..=top];
    // A `while` loop: `(1..=top).rev()` (an inclusive range) compiles to a
    // noticeably slower loop.
    //
    // Many nodes feed the node recorded just before them; going through memory
    // for that edge puts a store-to-load forward on the critical path of the
    // next step. That contribution is carried in a register instead (`carry`).
    // (Branching around `adj[i] + carry` when only the carry reached node i,
    // to shorten the chain further, measured no faster.)
    let mut i = top;
    let mut carry = 0.0;
    while i > lo {
        let g = adj[i & mask] + carry;
        adj[i & mask] = g;
        carry = if g != 0.0 {
            propagate(nodes[i], i, g, adj, mask)
        } else {
            0.0
        };
        i -= 1;
    }
    // What the last node processed passed on to node `lo` (an input).
    if carry != 0.0 {
        adj[lo & mask] += carry;
    }
}

/// Push the adjoint `g` of node `i` to its parents; returns the part destined
/// for node `i − 1` (kept in a register by the caller, see [`sweep`]).
#[inline(always)]
fn propagate(n: Node, i: usize, g: f64, adj: &mut [f64], mask: usize) -> f64 {
    let (ca, cb) = (g * n.da, g * n.db);
    let prev = (i - 1) as u32;
    let (a_next, b_next) = (n.a == prev, n.b == prev);
    if !a_next {
        adj[n.a as usize & mask] += ca;
    }
    if !b_next {
        adj[n.b as usize & mask] += cb;
    }
    // No `ca + 0.0` on the common path: that add would sit on the critical
    // path (carry → add → multiply → carry) of every step.
    match (a_next, b_next) {
        (true, true) => ca + cb,
        (true, false) => ca,
        (false, true) => cb,
        (false, false) => 0.0,
    }
}

impl Drop for Recording {
    fn drop(&mut self) {
        if let Ok(mut t) = tape().try_borrow_mut() {
            if live().0 == self.id {
                LIVE.with(|c| c.set((0, 0)));
                t.nodes.clear();
                t.inputs.clear();
            }
        }
    }
}

/// Capacity (in nodes) of this thread's tape: stays constant once a per-path
/// loop has reached its longest path, which is how the tests check that the
/// steady state does not allocate.
///
/// ```
/// use usray_ad::reverse;
/// let _ = reverse::tape_capacity();
/// ```
pub fn tape_capacity() -> usize {
    with_tape(|t| {
        let t = t.borrow();
        t.nodes.capacity() + t.adj.capacity() + t.inputs.capacity()
    })
}

/// Value and gradient of `f` at `x`, recorded on this thread's tape.
/// Convenience for tests and small problems (allocates the result); use
/// [`Recording`] in hot loops, or [`crate::helpers`] for generic functions.
///
/// ```
/// use usray_ad::reverse;
/// use usray_ad::Real;
/// let (v, g) = reverse::gradient(|x| x[0] * x[1].sin(), &[2.0, 0.0]);
/// assert_eq!(v, 0.0);
/// assert_eq!(g, vec![0.0, 2.0]);
/// ```
pub fn gradient<F: FnOnce(&[Var]) -> Var>(f: F, x: &[f64]) -> (f64, Vec<f64>) {
    let rec = Recording::start();
    let vars: Vec<Var> = x.iter().map(|&xi| rec.input(xi)).collect();
    let y = f(&vars);
    let mut g = vec![0.0; x.len()];
    rec.gradient(y, &mut g);
    (y.value, g)
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
