//! # usray: differentiable ultrasound simulation by Monte Carlo ray tracing
//!
//! This crate gathers the workspace's crates under one name, for users who want
//! everything; each is also published on its own:
//!
//! | module | crate | what it holds |
//! |---|---|---|
//! | [`ad`] | `usray-ad` | the `Real` scalar trait, forward duals, reverse-mode tapes |
//! | [`geometry`] | `usray-geometry` | vectors, rays, analytic shapes, meshes, hits |
//! | [`transport`] | `usray-transport` | scenes, probes, the Monte Carlo tracer, channel data |
//! | [`signal`] | `usray-signal` | image formation (DAS, IQ, envelope, log) with adjoints, I/O |
//! | [`optim`] | `usray-optim` | parameter maps, losses, Adam, fits, diagnosis |
//!
//! The workspace-level tests in `tests/` exercise the whole pipeline through it.
//!
//! ```
//! use usray::ad::Real;
//! fn two_way_time<T: Real>(depth_m: T, c_m_s: T) -> T {
//!     depth_m.scale(2.0) / c_m_s
//! }
//! assert_eq!(two_way_time(0.0154_f64, 1540.0), 2.0e-5);
//! ```

pub use usray_ad as ad;
pub use usray_geometry as geometry;
pub use usray_optim as optim;
pub use usray_signal as signal;
pub use usray_transport as transport;
