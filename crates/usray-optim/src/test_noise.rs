//! Gaussian noise for the crate's statistical tests.

use usray_transport::rng::mix64;

/// A standard normal deviate by Box–Muller from a counter-keyed hash: the
/// same `key` gives the same deviate, distinct keys independent ones.
pub(crate) fn normal(key: u64) -> f64 {
    let u = |k: u64| ((mix64(k) >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let (u1, u2) = (u(2 * key), u(2 * key + 1));
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
