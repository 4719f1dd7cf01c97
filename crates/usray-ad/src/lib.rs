//! Automatic differentiation for usray (work in progress: see issue 2).
mod real;
pub use real::Real;
