//! Post-processing of a beamformed complex image: envelope `|IQ|`, log compression
//! `20·log10`, normalisation to the maximum, dynamic-range clipping to `[0, 1]`
//! (Szabo, "Diagnostic Ultrasound Imaging: Inside Out", B-mode display chain), with VJPs.
//!
//! With envelope `E_p = |u_p|`, maximum `M = max_q E_q` attained at `q*`, dynamic
//! range `D` dB:
//!
//! `dB_p = 20·log10(E_p / M)`, `I_p = clamp((dB_p + D)/D, 0, 1)`.
//!
//! **Gradient of the maximum: exact.** `M = E_{q*}` is differentiated as the value at
//! its arg-max (the max is differentiable wherever the arg-max is unique, i.e. almost
//! everywhere), so `∂dB_p/∂E_q = (20/ln 10)(δ_pq/E_p − δ_{q q*}/M)`. The clip passes
//! gradient where `0 < (dB + D)/D < 1` strictly and blocks it outside (the
//! one-sided derivative at the boundary is taken as 0). The envelope's derivative
//! is `∂|u|/∂u = u/|u|` (0 where `u = 0`).
//!
//! **A fixed reference.** Data in a calibrated unit can be compressed against a
//! given envelope `M₀` instead of their own maximum ([`log_compress_against`]):
//! `dB_p = 20·log10(E_p / M₀)`, whose gradient has no maximum term,
//! `∂dB_p/∂E_q = (20/ln 10) δ_pq/E_p`. Two images compressed against the same
//! `M₀` keep their absolute levels: an echo twice as strong is 6 dB brighter,
//! where normalising each to its own maximum would show both at 0 dB.

use rustfft::num_complex::Complex64;

const K: f64 = 20.0 / core::f64::consts::LN_10;

/// `E = |u|` element-wise.
pub fn envelope(u: &[Complex64], env: &mut [f64]) {
    for (e, v) in env.iter_mut().zip(u) {
        *e = v.norm();
    }
}

/// VJP of [`envelope`]: `ū = Ē·u/|u|`.
pub fn envelope_vjp(u: &[Complex64], env_bar: &[f64], u_bar: &mut [Complex64]) {
    for ((ub, v), &g) in u_bar.iter_mut().zip(u).zip(env_bar) {
        let n = v.norm();
        *ub = if n > 0.0 {
            *v * (g / n)
        } else {
            Complex64::new(0.0, 0.0)
        };
    }
}

/// Index of the maximum (first one on ties; fixed order).
pub fn argmax(v: &[f64]) -> usize {
    let mut best = 0;
    for (i, &x) in v.iter().enumerate() {
        if x > v[best] {
            best = i;
        }
    }
    best
}

/// `dB_p = 20 log10(E_p / max E)`; returns the arg-max. Zero envelope gives `−∞`.
pub fn log_compress(env: &[f64], db: &mut [f64]) -> usize {
    let q = argmax(env);
    let m = env[q];
    for (d, &e) in db.iter_mut().zip(env) {
        *d = if m > 0.0 {
            20.0 * (e / m).log10()
        } else {
            f64::NEG_INFINITY
        };
    }
    q
}

/// VJP of [`log_compress`] with the exact gradient of the maximum (module docs).
pub fn log_compress_vjp(env: &[f64], argmax: usize, db_bar: &[f64], env_bar: &mut [f64]) {
    let total = log_compress_against_vjp(env, db_bar, env_bar);
    let m = env[argmax];
    if m > 0.0 {
        env_bar[argmax] -= K * total / m;
    }
}

/// `dB_p = 20 log10(E_p / reference)` against a fixed `reference > 0` (module
/// docs, "A fixed reference"). Zero envelope gives `−∞`.
pub fn log_compress_against(env: &[f64], reference: f64, db: &mut [f64]) {
    for (d, &e) in db.iter_mut().zip(env) {
        *d = 20.0 * (e / reference).log10();
    }
}

/// VJP of [`log_compress_against`] (the reference is a constant); returns
/// `Σ_p dB̄_p`, the part [`log_compress_vjp`] adds the maximum's term with.
pub fn log_compress_against_vjp(env: &[f64], db_bar: &[f64], env_bar: &mut [f64]) -> f64 {
    let mut total = 0.0;
    for ((eb, &e), &g) in env_bar.iter_mut().zip(env).zip(db_bar) {
        *eb = if e > 0.0 && g != 0.0 { K * g / e } else { 0.0 };
        total += g;
    }
    total
}

/// `I = clamp((dB + D)/D, 0, 1)` (grey level in `[0, 1]`; `−∞` → 0).
pub fn clip_dynamic_range(db: &[f64], d: f64, img: &mut [f64]) {
    for (i, &x) in img.iter_mut().zip(db) {
        let v = (x + d) / d;
        *i = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    }
}

/// VJP of [`clip_dynamic_range`]: `dB̄ = Ī/D` where `0 < I < 1`, else 0.
pub fn clip_dynamic_range_vjp(db: &[f64], d: f64, img_bar: &[f64], db_bar: &mut [f64]) {
    for ((b, &x), &g) in db_bar.iter_mut().zip(db).zip(img_bar) {
        let v = (x + d) / d;
        *b = if v > 0.0 && v < 1.0 { g / d } else { 0.0 };
    }
}
