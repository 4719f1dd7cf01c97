//! [`Recording`]: exclusive use of this thread's tape from start to drop:
//! inputs, a frozen shared prefix, and gradients by one reverse sweep.

use super::sweep::sweep;
use super::tape::{fresh_id, live, stale, tape, valid, with_tape, Tape, DUMMY, LIVE};
use super::Var;
use core::marker::PhantomData;

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
