//! Depth-gain (time-gain) compensation.
//!
//! A scanner's time-gain compensation multiplies the sample at absolute time `t`
//! (CONTRACT §1 clock) by `g(t) = 10^(α·d/20)`, `α` in dB/cm, where
//! `d = 100·c·max(t, 0)/2` is the echo depth in cm (two-way path at sound speed `c`,
//! m/s). Linear and diagonal: the VJP multiplies by the same `g` (Szabo, "Diagnostic
//! Ultrasound Imaging: Inside Out", time-gain compensation).

use usray_ad::Real;

/// Gain factor `10^(α·d/20)` at absolute time `t` (s) for `α` dB/cm at `c` (m/s).
pub fn depth_gain<T: Real>(t: T, db_per_cm: T, c: T) -> T {
    let t = if t.value() > 0.0 { t } else { T::zero() };
    let d_cm = c * t * T::from_f64(50.0);
    (db_per_cm * d_cm * T::from_f64(core::f64::consts::LN_10 / 20.0)).exp()
}

/// The gain of every sample of a record starting at `t0` (s), sampled at `fs` (Hz).
pub fn gain_table(n: usize, t0: f64, fs: f64, db_per_cm: f64, c: f64) -> Vec<f64> {
    (0..n)
        .map(|i| depth_gain(t0 + i as f64 / fs, db_per_cm, c))
        .collect()
}

/// Forward: `y = g ⊙ x`.
pub fn apply_gain(x: &[f64], g: &[f64], y: &mut [f64]) {
    for ((y, x), g) in y.iter_mut().zip(x).zip(g) {
        *y = x * g;
    }
}

/// VJP: `x̄ = g ⊙ ȳ` (the operator is diagonal, hence symmetric).
pub fn apply_gain_vjp(ybar: &[f64], g: &[f64], xbar: &mut [f64]) {
    apply_gain(ybar, g, xbar)
}
