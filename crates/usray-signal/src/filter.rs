//! Butterworth IIR filters (low-pass and band-pass) applied forward–backward
//! ("zero-phase", MATLAB/scipy `filtfilt`), with their VJP.
//!
//! Design: analog Butterworth prototype poles `p_k = exp(iπ(2k + N − 1)/(2N))`,
//! `k = 1..N`, scaled to the pre-warped cut-off `Ω = 2 f_s tan(π f_cut / f_s)` and
//! mapped by the bilinear transform `z = (2f_s + s)/(2f_s − s)` (Oppenheim & Schafer,
//! "Discrete-Time Signal Processing", bilinear-transform IIR design; identical to scipy's `butter`). Stored as
//! second-order sections, unit gain at DC (low-pass) or Nyquist (high-pass).
//!
//! Zero-phase application with **zero initial state and no edge padding**:
//! `y = R F R F x` where `F` is the causal cascade (a lower-triangular Toeplitz
//! matrix on a finite record) and `R` reverses time. Since `Fᵀ = R F R`, the operator
//! is symmetric: `(R F R F)ᵀ = Fᵀ (R F R)ᵀ = (R F R)(R R F R R) = R F R F`. Its VJP is
//! therefore the same filter (the backward pass of the adjoint is the forward
//! filter run in reverse order). scipy's `filtfilt` differs only near the record
//! ends (it pads with an odd extension and starts from steady state).

use rustfft::num_complex::Complex64;

use crate::das::Sample;

/// One biquad `b0 + b1 z⁻¹ + b2 z⁻² / (1 + a1 z⁻¹ + a2 z⁻²)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Biquad {
    /// Numerator `b0, b1, b2`.
    pub b: [f64; 3],
    /// Denominator `a1, a2` (`a0 = 1`).
    pub a: [f64; 2],
}

/// A cascade of second-order sections.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Sos {
    /// The sections, applied in order.
    pub sections: Vec<Biquad>,
}

fn butter_sections(order: usize, wn: f64, highpass: bool) -> Vec<Biquad> {
    // fs = 2 normalisation (scipy): warped = 4 tan(π wn / 2), bilinear z = (4 + s)/(4 − s).
    let warped = 4.0 * (core::f64::consts::PI * wn / 2.0).tan();
    let n = order as f64;
    let mut out = Vec::new();
    for k in 1..=order {
        let theta = core::f64::consts::PI * (2.0 * k as f64 + n - 1.0) / (2.0 * n);
        let p = Complex64::from_polar(1.0, theta);
        if p.im > 1e-12 {
            continue; // take each conjugate pair once (the one with im < 0) and real poles
        }
        let s = if highpass { warped / p } else { p * warped };
        let zd = (Complex64::new(4.0, 0.0) + s) / (Complex64::new(4.0, 0.0) - s);
        if p.im.abs() <= 1e-12 {
            let zr = zd.re;
            if highpass {
                let g = (1.0 + zr) / 2.0;
                out.push(Biquad {
                    b: [g, -g, 0.0],
                    a: [-zr, 0.0],
                });
            } else {
                let g = (1.0 - zr) / 2.0;
                out.push(Biquad {
                    b: [g, g, 0.0],
                    a: [-zr, 0.0],
                });
            }
        } else {
            let (a1, a2) = (-2.0 * zd.re, zd.norm_sqr());
            if highpass {
                let g = (1.0 - a1 + a2) / 4.0;
                out.push(Biquad {
                    b: [g, -2.0 * g, g],
                    a: [a1, a2],
                });
            } else {
                let g = (1.0 + a1 + a2) / 4.0;
                out.push(Biquad {
                    b: [g, 2.0 * g, g],
                    a: [a1, a2],
                });
            }
        }
    }
    out
}

impl Sos {
    /// Butterworth low-pass of `order`, cut-off `f_cut` Hz (−3 dB per pass), at `fs` Hz.
    /// Returns `None` unless `0 < f_cut < fs/2`.
    pub fn butter_lowpass(order: usize, f_cut: f64, fs: f64) -> Option<Sos> {
        let wn = 2.0 * f_cut / fs;
        (wn > 0.0 && wn < 1.0 && order > 0).then(|| Sos {
            sections: butter_sections(order, wn, false),
        })
    }
    /// Butterworth band-pass as the cascade high-pass(`f_lo`) · low-pass(`f_hi`), each
    /// of `order`. Returns `None` unless `0 < f_lo < f_hi < fs/2`.
    pub fn butter_bandpass(order: usize, f_lo: f64, f_hi: f64, fs: f64) -> Option<Sos> {
        let (wl, wh) = (2.0 * f_lo / fs, 2.0 * f_hi / fs);
        (wl > 0.0 && wl < wh && wh < 1.0 && order > 0).then(|| {
            let mut s = butter_sections(order, wl, true);
            s.extend(butter_sections(order, wh, false));
            Sos { sections: s }
        })
    }

    /// Causal filtering in place, zero initial state (direct form II transposed).
    /// Runs on real samples or on complex ones (an IQ record: real and imaginary
    /// parts filtered independently, in one pass).
    pub fn filter_in_place<T: Sample>(&self, x: &mut [T]) {
        for s in &self.sections {
            let (mut z1, mut z2) = (T::zero(), T::zero());
            for v in x.iter_mut() {
                let xi = *v;
                let y = xi.scale(s.b[0]) + z1;
                z1 = xi.scale(s.b[1]) - y.scale(s.a[0]) + z2;
                z2 = xi.scale(s.b[2]) - y.scale(s.a[1]);
                *v = y;
            }
        }
    }

    /// Anti-causal filtering in place (the causal filter on the reversed record).
    pub fn filter_reverse_in_place<T: Sample>(&self, x: &mut [T]) {
        x.reverse();
        self.filter_in_place(x);
        x.reverse();
    }

    /// Zero-phase forward–backward filtering in place: `x ← R F R F x`.
    pub fn filtfilt_in_place<T: Sample>(&self, x: &mut [T]) {
        self.filter_in_place(x);
        self.filter_reverse_in_place(x);
    }

    /// VJP of [`Sos::filtfilt_in_place`]: the same operator (it is symmetric, see the
    /// module documentation). Written out as the transpose, `Fᵀ (R F R)ᵀ`, i.e. the
    /// forward pass then the reverse pass again.
    pub fn filtfilt_vjp_in_place<T: Sample>(&self, ybar: &mut [T]) {
        // (RFR)ᵀ = R Fᵀ R = F  then  Fᵀ = R F R.
        self.filter_in_place(ybar);
        self.filter_reverse_in_place(ybar);
    }

    /// Frequency response magnitude at `f` Hz for sampling rate `fs` (one pass).
    pub fn magnitude(&self, f: f64, fs: f64) -> f64 {
        let z = Complex64::from_polar(1.0, -2.0 * core::f64::consts::PI * f / fs);
        let z2 = z * z;
        self.sections
            .iter()
            .map(|s| {
                ((s.b[0] + s.b[1] * z + s.b[2] * z2) / (1.0 + s.a[0] * z + s.a[1] * z2)).norm()
            })
            .product()
    }
}

impl Sos {
    /// Zero-phase filtering of every record (`n_samples` long) of channel-shaped
    /// samples, in place. Its VJP is the same call (the operator is symmetric).
    pub fn filtfilt_records(&self, x: &mut [f64], n_samples: usize) {
        if n_samples > 0 {
            for r in x.chunks_mut(n_samples) {
                self.filtfilt_in_place(r);
            }
        }
    }
}
