//! Automatic differentiation for usray (work in progress: see issue 2).
mod dual;
mod real;
pub use dual::Dual;
pub use real::Real;
