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
//! Constants ([`Var::constant`], [`Real::from_f64`](crate::Real::from_f64),
//! [`Real::detach`](crate::Real::detach)) carry the sentinel index 0 and
//! create no node; operations on constants only are not recorded at all.
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

mod ops;
mod recording;
mod sweep;
mod tape;
mod var;

pub use recording::{gradient, Recording};
pub use tape::tape_capacity;
pub use var::Var;
