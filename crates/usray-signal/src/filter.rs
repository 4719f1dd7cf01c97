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

use core::ops::{Add, Sub};

use rustfft::num_complex::Complex64;
use usray_ad::Real;

use crate::das::Sample;

/// One biquad `b0 + b1 z⁻¹ + b2 z⁻² / (1 + a1 z⁻¹ + a2 z⁻²)`, coefficients in
/// `T` (`f64` to filter; a dual number to differentiate the design,
/// [`butter_lowpass_sections`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Biquad<T = f64> {
    /// Numerator `b0, b1, b2`.
    pub b: [T; 3],
    /// Denominator `a1, a2` (`a0 = 1`).
    pub a: [T; 2],
}

/// A cascade of second-order sections.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Sos {
    /// The sections, applied in order.
    pub sections: Vec<Biquad>,
}

/// The Butterworth sections at normalised cut-off `wn` (1 = Nyquist) in any
/// `T: Real`. The complex arithmetic of the bilinear transform is written
/// out in num-complex's order of operations (`Complex64` `Mul<f64>`,
/// `f64 / Complex64`, `Div`, `norm_sqr`), so that the `f64` design is the
/// one `Complex64` gave, bit for bit; the poles of the prototype do not
/// depend on `wn` and stay `Complex64`.
fn butter_sections<T: Real>(order: usize, wn: T, highpass: bool) -> Vec<Biquad<T>> {
    // fs = 2 normalisation (scipy): warped = 4 tan(π wn / 2), bilinear z = (4 + s)/(4 − s).
    let warped = (wn.scale(core::f64::consts::PI) / T::from_f64(2.0))
        .tan()
        .scale(4.0);
    let (zero, one, two, four) = (T::zero(), T::one(), T::from_f64(2.0), T::from_f64(4.0));
    let n = order as f64;
    let mut out = Vec::new();
    for k in 1..=order {
        let theta = core::f64::consts::PI * (2.0 * k as f64 + n - 1.0) / (2.0 * n);
        let p = Complex64::from_polar(1.0, theta);
        if p.im > 1e-12 {
            continue; // take each conjugate pair once (the one with im < 0) and real poles
        }
        // The analog pole at the warped cut-off: `warped / p` or `p · warped`.
        let s = if highpass {
            let ns = T::from_f64(p.norm_sqr());
            (warped.scale(p.re) / ns, zero - warped.scale(p.im) / ns)
        } else {
            (warped.scale(p.re), warped.scale(p.im))
        };
        // zd = (4 + s) / (4 − s).
        let (a, b) = (four + s.0, zero + s.1);
        let (c, d) = (four - s.0, zero - s.1);
        let ns = c * c + d * d;
        let zd = ((a * c + b * d) / ns, (b * c - a * d) / ns);
        if p.im.abs() <= 1e-12 {
            let zr = zd.0;
            if highpass {
                let g = (one + zr) / two;
                out.push(Biquad {
                    b: [g, -g, zero],
                    a: [-zr, zero],
                });
            } else {
                let g = (one - zr) / two;
                out.push(Biquad {
                    b: [g, g, zero],
                    a: [-zr, zero],
                });
            }
        } else {
            let (a1, a2) = (zd.0.scale(-2.0), zd.0 * zd.0 + zd.1 * zd.1);
            if highpass {
                let g = (one - a1 + a2) / four;
                out.push(Biquad {
                    b: [g, g.scale(-2.0), g],
                    a: [a1, a2],
                });
            } else {
                let g = (one + a1 + a2) / four;
                out.push(Biquad {
                    b: [g, g.scale(2.0), g],
                    a: [a1, a2],
                });
            }
        }
    }
    out
}

/// The sections of [`Sos::butter_lowpass`] with the cut-off `f_cut` (Hz) in
/// any `T: Real`: in a dual number, the derivative of every coefficient in
/// the cut-off. `None` unless `0 < f_cut < fs/2`.
///
/// ```
/// use usray_ad::Dual;
/// use usray_signal::filter::{butter_lowpass_sections, Sos};
/// let plain = Sos::butter_lowpass(5, 2e6, 20e6).unwrap();
/// let dual = butter_lowpass_sections(5, Dual::<1>::variable(2e6, 0), 20e6).unwrap();
/// assert_eq!(plain.sections[0].b[0], dual[0].b[0].re);
/// ```
pub fn butter_lowpass_sections<T: Real>(order: usize, f_cut: T, fs: f64) -> Option<Vec<Biquad<T>>> {
    let wn = f_cut.scale(2.0) / T::from_f64(fs);
    let w = wn.value();
    (w > 0.0 && w < 1.0 && order > 0).then(|| butter_sections(order, wn, false))
}

/// One section over `x` in place, causal, zero initial state (direct form II
/// transposed), with `mul(sample, coefficient)`: the one recursion behind
/// the filter on channel samples ([`Sos::filter_in_place`]) and on `T: Real`
/// ([`filtfilt_real`]).
#[inline(always)]
fn run_section<S, C: Copy>(s: &Biquad<C>, zero: S, x: &mut [S], mul: impl Fn(S, C) -> S)
where
    S: Copy + Add<Output = S> + Sub<Output = S>,
{
    let (mut z1, mut z2) = (zero, zero);
    for v in x.iter_mut() {
        let xi = *v;
        let y = mul(xi, s.b[0]) + z1;
        z1 = mul(xi, s.b[1]) - mul(y, s.a[0]) + z2;
        z2 = mul(xi, s.b[2]) - mul(y, s.a[1]);
        *v = y;
    }
}

/// Zero-phase filtering `x ← R F R F x` ([`Sos::filtfilt_in_place`]) with the
/// coefficients and the samples in any `T: Real`: with the sections of
/// [`butter_lowpass_sections`] in a dual number, the derivative of the
/// filtered record in the cut-off.
pub fn filtfilt_real<T: Real>(sections: &[Biquad<T>], x: &mut [T]) {
    for _ in 0..2 {
        for s in sections {
            run_section(s, T::zero(), x, |v, k| v * k);
        }
        x.reverse();
    }
}

impl Sos {
    /// Butterworth low-pass of `order`, cut-off `f_cut` Hz (−3 dB per pass), at `fs` Hz.
    /// Returns `None` unless `0 < f_cut < fs/2`.
    pub fn butter_lowpass(order: usize, f_cut: f64, fs: f64) -> Option<Sos> {
        butter_lowpass_sections(order, f_cut, fs).map(|sections| Sos { sections })
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
            run_section(s, T::zero(), x, |v, k| v.scale(k));
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
