//! The transmit/receive pulse and convolution of channel data with it.
//!
//! Paper eq. `axial_sig`: `s(t) = sin(2π f_c t)·exp(−t²/σ)`, `t` in seconds, `f_c` in
//! hertz, `σ` in s². The paper leaves `σ` open ("chosen to match the number of
//! cycles"); **usray's definition**: the Gaussian envelope's full width at half
//! maximum equals `cycles` carrier periods, `FWHM = cycles/f_c`, so
//! `exp(−(FWHM/2)²/σ) = 1/2`, i.e.
//!
//! `σ = (cycles / (2 f_c))² / ln 2`.
//!
//! (A 3-cycle 5 MHz pulse has `σ = 1.30e-13 s²`, envelope FWHM 0.6 µs.) The pulse is
//! odd and centred on `t = 0`: a deposit at time of flight `τ` contributes
//! `a·s(t − τ)`, so its envelope peaks at the geometric time of flight.

use usray_ad::Real;

/// `σ` of paper eq. `axial_sig` in s², from `f_c` (Hz) and the number of cycles
/// (envelope FWHM = `cycles/f_c`): `σ = (cycles/(2 f_c))²/ln 2`.
pub fn pulse_sigma<T: Real>(fc: T, cycles: T) -> T {
    let h = cycles / (fc * T::from_f64(2.0));
    h * h / T::from_f64(core::f64::consts::LN_2)
}

/// The pulse `s(t) = sin(2π f_c t)·exp(−t²/σ)` (paper eq. `axial_sig`, dimensionless,
/// peak ≈ 1), with `σ` from [`pulse_sigma`]. Generic so that a time of flight carrying
/// derivatives places a differentiable deposit.
///
/// ```
/// use usray_signal::pulse::{pulse, pulse_dt};
/// assert_eq!(pulse(0.0_f64, 5e6, 3.0), 0.0);
/// // A quarter period after the centre the carrier peaks; the envelope is still ≈ 0.98.
/// let v = pulse(0.05e-6_f64, 5e6, 3.0);
/// assert!((v - (-(0.05e-6_f64).powi(2) / usray_signal::pulse::pulse_sigma(5e6, 3.0)).exp()).abs() < 1e-12);
/// // The derivative matches a central difference.
/// let (t, h) = (0.13e-6_f64, 1e-12);
/// let fd = (pulse(t + h, 5e6, 3.0) - pulse(t - h, 5e6, 3.0)) / (2.0 * h);
/// assert!((fd - pulse_dt(t, 5e6, 3.0)).abs() < 1e-6 * fd.abs().max(1e6));
/// ```
pub fn pulse<T: Real>(t: T, fc: T, cycles: T) -> T {
    let sigma = pulse_sigma(fc, cycles);
    let w = fc * T::from_f64(2.0 * core::f64::consts::PI);
    (w * t).sin() * (-(t * t) / sigma).exp()
}

/// `ds/dt` in 1/s: `[2π f_c cos(2π f_c t) − (2t/σ) sin(2π f_c t)]·exp(−t²/σ)`.
pub fn pulse_dt<T: Real>(t: T, fc: T, cycles: T) -> T {
    let sigma = pulse_sigma(fc, cycles);
    let w = fc * T::from_f64(2.0 * core::f64::consts::PI);
    let env = (-(t * t) / sigma).exp();
    (w * (w * t).cos() - T::from_f64(2.0) * t / sigma * (w * t).sin()) * env
}

/// `σ_f` in Hz: the standard deviation of the pulse's amplitude spectrum about
/// `f_c`. The envelope `exp(−t²/σ)` is a Gaussian of standard deviation
/// `σ_t = √(σ/2)` in time, whose Fourier transform is a Gaussian of standard
/// deviation `σ_f = 1/(2π σ_t)`, so `σ_f² = 1/(2π² σ)` (3 cycles at 5 MHz:
/// 0.625 MHz).
///
/// ```
/// use usray_signal::pulse::pulse_bandwidth_hz;
/// let sf = pulse_bandwidth_hz(5e6_f64, 3.0);
/// assert!((sf - 0.6246e6).abs() < 1e2);
/// ```
pub fn pulse_bandwidth_hz<T: Real>(fc: T, cycles: T) -> T {
    let pi2 = core::f64::consts::PI * core::f64::consts::PI;
    (pulse_sigma(fc, cycles).scale(2.0 * pi2)).recip().sqrt()
}

/// The pulse with its carrier moved **down** by `s` spectral standard
/// deviations, the envelope unchanged: `sin(2π (f_c − s σ_f) t)·exp(−t²/σ)`
/// ([`pulse_bandwidth_hz`]). This is exactly what a frequency-linear
/// attenuation does to a Gaussian pulse (Kuc, *IEEE Trans. Sonics Ultrason.*
/// 1984: the spectrum `E(f − f_c)·e^{−βf}` is `E` centred on `f_c − βσ_f²`,
/// scaled by `e^{−βf_c + β²σ_f²/2}`). `s = 0` gives [`pulse`] bit for bit.
///
/// ```
/// use usray_signal::pulse::{pulse, shifted_pulse};
/// assert_eq!(shifted_pulse(0.1e-6_f64, 5e6, 3.0, 0.0), pulse(0.1e-6_f64, 5e6, 3.0));
/// ```
pub fn shifted_pulse<T: Real>(t: T, fc: T, cycles: T, s: f64) -> T {
    if s == 0.0 {
        return pulse(t, fc, cycles);
    }
    let sigma = pulse_sigma(fc, cycles);
    let f = fc - pulse_bandwidth_hz(fc, cycles).scale(s);
    (f.scale(2.0 * core::f64::consts::PI) * t).sin() * (-(t * t) / sigma).exp()
}

/// `∂/∂s` of [`shifted_pulse`]: `−2π σ_f t·cos(2π (f_c − s σ_f) t)·exp(−t²/σ)`.
///
/// ```
/// use usray_signal::pulse::{shifted_pulse, shifted_pulse_ds};
/// let (t, s, h) = (0.13e-6_f64, 0.4, 1e-6);
/// let fd = (shifted_pulse(t, 5e6, 3.0, s + h) - shifted_pulse(t, 5e6, 3.0, s - h)) / (2.0 * h);
/// assert!((fd - shifted_pulse_ds(t, 5e6, 3.0, s)).abs() < 1e-8);
/// ```
pub fn shifted_pulse_ds<T: Real>(t: T, fc: T, cycles: T, s: f64) -> T {
    let sigma = pulse_sigma(fc, cycles);
    let sf = pulse_bandwidth_hz(fc, cycles);
    let w = (fc - sf.scale(s)).scale(2.0 * core::f64::consts::PI);
    -(sf.scale(2.0 * core::f64::consts::PI) * t * (w * t).cos() * (-(t * t) / sigma).exp())
}

/// Half-width (s) beyond which the pulse envelope is below 1e-7 of its peak:
/// `4√σ` (`exp(−16) = 1.1e-7`).
pub fn pulse_support_s(fc: f64, cycles: f64) -> f64 {
    4.0 * pulse_sigma(fc, cycles).sqrt()
}

/// The pulse sampled at `fs`: taps `s(k/fs)` for `k = −K..=K` (K from
/// [`pulse_support_s`]); tap `K` is `t = 0`.
pub fn pulse_taps(fs: f64, fc: f64, cycles: f64) -> Vec<f64> {
    let k = (pulse_support_s(fc, cycles) * fs).ceil() as i64;
    (-k..=k).map(|i| pulse(i as f64 / fs, fc, cycles)).collect()
}

/// Convolution of one record with centred taps (odd length `2K+1`):
/// `y[n] = Σ_k taps[k]·x[n − (k − K)]`, zero outside the record (linear, paper
/// eq. `axial_sig` applied to a sampled impulse train).
pub fn convolve(x: &[f64], taps: &[f64], y: &mut [f64]) {
    let k0 = (taps.len() / 2) as isize;
    let n = x.len() as isize;
    for (i, yi) in y.iter_mut().enumerate() {
        let mut acc = 0.0;
        for (k, &t) in taps.iter().enumerate() {
            let j = i as isize - (k as isize - k0);
            if j >= 0 && j < n {
                acc += t * x[j as usize];
            }
        }
        *yi = acc;
    }
}

/// VJP of [`convolve`] (its transpose: correlation with the same taps):
/// `x̄[j] = Σ_k taps[k]·ȳ[j + (k − K)]`, each sum taken over the terms inside
/// the record in increasing `k`.
pub fn convolve_vjp(ybar: &[f64], taps: &[f64], xbar: &mut [f64]) {
    let k0 = taps.len() / 2;
    let n = ybar.len();
    // One output near the ends of the record: terms outside it are skipped.
    let edge = |j: usize| -> f64 {
        let mut acc = 0.0;
        for (k, &t) in taps.iter().enumerate() {
            let i = j as isize + (k as isize - k0 as isize);
            if i >= 0 && (i as usize) < n {
                acc += t * ybar[i as usize];
            }
        }
        acc
    };
    // Outputs `lo..hi` read only samples inside the record (`j − K ≥ 0` and
    // `j − K + taps.len() − 1 < n`). They are summed `LANES` at a time:
    // independent sums, each in the same order as alone (so the same bits),
    // which the processor overlaps instead of waiting on one chain of additions.
    const LANES: usize = 8;
    let lo = k0.min(xbar.len());
    let hi = (n + k0 + 1)
        .saturating_sub(taps.len())
        .clamp(lo, xbar.len());
    for j in 0..lo {
        xbar[j] = edge(j);
    }
    let mut j = lo;
    while j + LANES <= hi {
        let mut acc = [0.0; LANES];
        let first = j - k0;
        for (k, &t) in taps.iter().enumerate() {
            for (a, &y) in acc.iter_mut().zip(&ybar[first + k..first + k + LANES]) {
                *a += t * y;
            }
        }
        xbar[j..j + LANES].copy_from_slice(&acc);
        j += LANES;
    }
    for (jj, x) in xbar.iter_mut().enumerate().skip(j) {
        *x = edge(jj);
    }
}

/// Convolve every record of channel-shaped samples (`[.., n_samples]` records of
/// length `n_samples`) with the pulse sampled at `fs`: `out = s ⋆ x` per record.
/// The forward of paper eq. `axial_sig` applied to impulse-like deposits.
pub fn convolve_records(x: &[f64], n_samples: usize, fs: f64, fc: f64, cycles: f64) -> Vec<f64> {
    let taps = pulse_taps(fs, fc, cycles);
    let mut out = vec![0.0; x.len()];
    if n_samples > 0 {
        for (xr, yr) in x.chunks(n_samples).zip(out.chunks_mut(n_samples)) {
            convolve(xr, &taps, yr);
        }
    }
    out
}

/// VJP of [`convolve_records`]: correlation of every record with the same taps.
pub fn convolve_records_vjp(
    ybar: &[f64],
    n_samples: usize,
    fs: f64,
    fc: f64,
    cycles: f64,
) -> Vec<f64> {
    let taps = pulse_taps(fs, fc, cycles);
    let mut out = vec![0.0; ybar.len()];
    if n_samples > 0 {
        for (yr, xr) in ybar.chunks(n_samples).zip(out.chunks_mut(n_samples)) {
            convolve_vjp(yr, &taps, xr);
        }
    }
    out
}
