//! Automatic differentiation for usray.
//!
//! usray differentiates a Monte Carlo ultrasound ray tracer: channel data depend on
//! scene parameters (radii, sound speeds, impedances, …) through ray–surface
//! distances, Snell refraction, Fresnel amplitudes and times of flight. This crate
//! provides the one scalar trait, [`Real`], in which all that code is written
//! **once** (`fn f<T: Real>(…)`), and the number types it runs in:
//!
//! | type | what you get | use it for |
//! |---|---|---|
//! | `f64`, `f32` | the value, at native speed | rendering |
//! | [`Dual<N>`] | value + `N` partials (forward mode) | a few parameters, tests |
//! | [`reverse::Var`] | value; gradient by a per-thread tape (reverse mode) | many parameters, per-path replay |
//!
//! Every elementary function's derivative rule is written once, in [`Real`], on top
//! of two primitives (`chain`, `chain2`) that each number type implements.
//!
//! # 1. A generic function
//! ```
//! use usray_ad::Real;
//!
//! /// Acoustic pressure reflection coefficient at normal incidence,
//! /// R = (Z₂ − Z₁)/(Z₂ + Z₁) (Z in MRayl, R dimensionless).
//! fn reflection<T: Real>(z1: T, z2: T) -> T {
//!     (z2 - z1) / (z2 + z1)
//! }
//! assert_eq!(reflection(1.5_f64, 4.5), 0.5);
//! ```
//!
//! # 2. Its derivative by forward mode ([`Dual`])
//! Seed each input with [`Dual::variable`]`(value, index)`; read `re` and `eps`.
//! ```
//! # use usray_ad::Real;
//! # fn reflection<T: Real>(z1: T, z2: T) -> T { (z2 - z1) / (z2 + z1) }
//! use usray_ad::Dual;
//! let r = reflection(Dual::<2>::variable(1.5, 0), Dual::<2>::variable(4.5, 1));
//! assert_eq!(r.re, 0.5);
//! // ∂R/∂Z₁ = −2Z₂/(Z₁+Z₂)², ∂R/∂Z₂ = 2Z₁/(Z₁+Z₂)²  (per MRayl)
//! assert!((r.eps[0] - (-9.0 / 36.0)).abs() < 1e-15);
//! assert!((r.eps[1] - 3.0 / 36.0).abs() < 1e-15);
//! ```
//!
//! # 3. The same gradient by reverse mode ([`reverse`])
//! A [`reverse::Recording`] claims this thread's tape; inputs are [`reverse::Var`]s;
//! [`reverse::Recording::gradient`] *adds* the gradient into your buffer. Dropping the
//! recording clears the tape but keeps its memory (no allocation per path).
//! ```
//! # use usray_ad::Real;
//! # fn reflection<T: Real>(z1: T, z2: T) -> T { (z2 - z1) / (z2 + z1) }
//! use usray_ad::reverse::Recording;
//! let mut grad = [0.0; 2];
//! {
//!     let rec = Recording::start();
//!     let [z1, z2] = rec.inputs_array::<2>(&[1.5, 4.5]);
//!     let r = reflection(z1, z2);
//!     assert_eq!(r.value(), 0.5);
//!     rec.gradient(r, &mut grad);
//! }
//! assert!((grad[0] - (-9.0 / 36.0)).abs() < 1e-15);
//! assert!((grad[1] - 3.0 / 36.0).abs() < 1e-15);
//! ```
//!
//! # 4. Helpers for whole functions ([`helpers`])
//! Closures cannot be generic, so write a tiny type implementing
//! [`helpers::ScalarFn`] (or [`helpers::VectorFn`]) and ask for value and gradient
//! by either mode, or for a JVP / VJP.
//! ```
//! use usray_ad::helpers::{self, ScalarFn, VectorFn};
//! use usray_ad::Real;
//!
//! struct Reflection;
//! impl ScalarFn for Reflection {
//!     fn eval<T: Real>(&self, z: &[T]) -> T {
//!         (z[1] - z[0]) / (z[1] + z[0])
//!     }
//! }
//! let mut g = [0.0; 2];
//! let v = helpers::value_and_gradient_reverse(&Reflection, &[1.5, 4.5], &mut g);
//! let mut g1 = [0.0; 2];
//! let v1 = helpers::value_and_gradient_forward::<1, _>(&Reflection, &[1.5, 4.5], &mut g1);
//! assert_eq!(v, v1);
//! assert!((g[0] - g1[0]).abs() < 1e-16 && (g[1] - g1[1]).abs() < 1e-16);
//!
//! // (reflection, transmission) as a vector function; JVP and VJP agree:
//! // ⟨J v, w⟩ = ⟨v, Jᵀ w⟩.
//! struct RT;
//! impl VectorFn for RT {
//!     fn eval<T: Real>(&self, z: &[T], out: &mut [T]) {
//!         out[0] = (z[1] - z[0]) / (z[1] + z[0]);
//!         out[1] = z[1].scale(2.0) / (z[1] + z[0]);
//!     }
//! }
//! let (x, v, w) = ([1.5, 4.5], [0.3, -1.0], [2.0, 0.5]);
//! let (mut y, mut jv, mut wj) = ([0.0; 2], [0.0; 2], [0.0; 2]);
//! helpers::jvp(&RT, &x, &v, &mut y, &mut jv);
//! helpers::vjp(&RT, &x, &w, &mut y, &mut wj);
//! let lhs = jv[0] * w[0] + jv[1] * w[1];
//! let rhs = v[0] * wj[0] + v[1] * wj[1];
//! assert!((lhs - rhs).abs() < 1e-15);
//! ```
//!
//! # 5. `clip01`: the paper's parameter map
//! Optimised parameters live in `[0, 1]` and are clipped; a parameter at a bound
//! gets **zero** gradient (the paper's clip-gradient rule), inside it passes through.
//! ```
//! use usray_ad::{Dual, Real};
//! assert_eq!(Dual::<1>::variable(0.4, 0).clip01().eps[0], 1.0);
//! assert_eq!(Dual::<1>::variable(1.3, 0).clip01().re, 1.0);
//! assert_eq!(Dual::<1>::variable(1.3, 0).clip01().eps[0], 0.0);
//! assert_eq!(Dual::<1>::variable(0.0, 0).clip01().eps[0], 0.0);
//! ```
//!
//! # 6. `detach`: keep the value, cut the gradient
//! A sampling decision divides by its probability *detached*, so the estimator's
//! value is unbiased and the gradient flows only through the weight's numerator.
//! ```
//! use usray_ad::{Dual, Real};
//! let r = Dual::<1>::variable(0.25, 0); // e.g. a Fresnel reflectance
//! let weight = r / r.detach(); // sampled reflection: value 1, d/dr = 1/r
//! assert_eq!(weight.re, 1.0);
//! assert_eq!(weight.eps[0], 4.0);
//! ```
//!
//! # 7. Safe functions at awkward points
//! `sqrt` at 0 and `acos` at ±1 have infinite derivatives; the `safe_` variants
//! clamp the argument and use the subgradient 0 there, so a grazing ray or a
//! zero-length vector does not poison a gradient with `∞` or `NaN`.
//! ```
//! use usray_ad::{Dual, Real};
//! let x = Dual::<1>::variable(0.0, 0);
//! assert!(!x.sqrt().is_finite());
//! assert_eq!(x.safe_sqrt().eps[0], 0.0);
//! ```
//!
//! # Per-path gradients (how `usray-transport` should use reverse mode)
//! Channel data are a sum of path deposits, so `∂L/∂θ = Σ_k ā_k ∂a_k/∂θ +
//! τ̄_k ∂τ_k/∂θ` (`DESIGN.md`). Replay each path in [`reverse::Var`] and hand its
//! deposits with their weights to [`reverse::Recording::vjp`], which *adds* into a
//! per-worker gradient buffer; [`reverse::Recording::restart`] empties the tape for
//! the next path without freeing memory (no allocation once warm).
//! ```
//! use usray_ad::reverse::{Recording, Var};
//! use usray_ad::Real;
//!
//! /// A toy "path": amplitude and time of flight from (depth, sound speed).
//! fn path<T: Real>(theta: &[T], k: usize) -> (T, T) {
//!     let depth = theta[0].scale(1.0 + k as f64);
//!     let amp = (-depth).exp();
//!     let tof = (depth + depth) / theta[1];
//!     (amp, tof)
//! }
//! let theta = [0.02, 1540.0];
//! let mut grad = vec![0.0; 2]; // per worker, reduced in a fixed order
//! let (mut ys, mut ws) = (Vec::new(), Vec::new()); // reused buffers
//! let mut rec = Recording::start();
//! for k in 0..4 {
//!     rec.restart();
//!     let p: [Var; 2] = rec.inputs_array(&theta);
//!     let (a, tau) = path(&p, k);
//!     let (a_bar, tau_bar) = (0.5, -2.0); // from the image-formation VJPs
//!     ys.clear();
//!     ws.clear();
//!     ys.extend([a, tau]);
//!     ws.extend([a_bar, tau_bar]);
//!     rec.vjp(&ys, &ws, &mut grad);
//! }
//! drop(rec);
//! // Check against forward mode.
//! let mut fwd = [0.0; 2];
//! for k in 0..4 {
//!     let p = [usray_ad::Dual::<2>::variable(theta[0], 0), usray_ad::Dual::variable(theta[1], 1)];
//!     let (a, tau) = path(&p, k);
//!     for i in 0..2 {
//!         fwd[i] += 0.5 * a.eps[i] - 2.0 * tau.eps[i];
//!     }
//! }
//! assert!((grad[0] - fwd[0]).abs() < 1e-12 && (grad[1] - fwd[1]).abs() < 1e-15);
//! ```
//!
//! # Conventions
//! - Values are bit-identical in `f64`, [`Dual`] and [`reverse::Var`] (the same
//!   floating-point operations in the same order), so a replay in an AD type takes
//!   exactly the branches the `f64` render took.
//! - Comparisons look at values only; branch decisions carry no derivative.
//! - `0·∞ = 0` in every chain-rule product, in both modes (see [`Dual`]), so a
//!   constant through `sqrt(0)` or a zero-weighted singular branch gives no `NaN`.
//! - Non-`safe_` functions at their singular points return the true one-sided
//!   derivative (`±∞`); the `safe_` variants return the subgradient 0.
//!
//! # Threads
//! Reverse mode keeps one tape per thread; each rayon worker records, sweeps and
//! clears its own, so many paths are differentiated in parallel with nothing
//! shared and results independent of scheduling. Forward mode needs no state.
//!
//! # Cost
//! On a tracer-like kernel (ray–sphere hit, Snell refraction, Fresnel amplitude,
//! time of flight) see `docs/performance.md`, section *usray-ad*.

mod dual;
pub mod helpers;
mod real;
pub mod reverse;

pub use dual::Dual;
pub use real::Real;
pub use reverse::{Recording, Var};
