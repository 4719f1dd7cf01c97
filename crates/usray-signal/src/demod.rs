//! Demodulation to baseband (IQ) and the RF analytic signal (Hilbert), with VJPs.
//!
//! **IQ** (Szabo, "Diagnostic Ultrasound Imaging: Inside Out", quadrature demodulation; as
//! PyMUST `rf2iq`): `IQ[n] = 2·LP{ rf[n]·exp(−2πi f_c t_n) }` with the absolute time
//! `t_n = t0 + n/f_s` (CONTRACT §1 clock) and `LP` a zero-phase Butterworth low-pass
//! ([`crate::filter`]). Using absolute time matters for band-pass-undersampled data
//! (`f_s < 2 f_c`): the mixing phase is then right even though the carrier aliases.
//! Linear; with `φ_n = 2π f_c t_n`, `I = 2 LP(rf cos φ)`, `Q = −2 LP(rf sin φ)` and
//! the VJP is `r̄f = 2 cos φ · LPᵀ Ī − 2 sin φ · LPᵀ Q̄`.
//!
//! **Analytic signal** (Hilbert, via FFT: Marple, IEEE TSP 47(9), 1999):
//! `a = IFFT(h ⊙ FFT(rf))`, `h = [1, 2, …, 2, (1 at Nyquist for even n), 0, …]`.
//! As a complex-linear map `A = F⁻¹ diag(h) F` is Hermitian (`h` real), so for a
//! real input the VJP is `r̄f = Re(A ā)` with `ā = ∂L/∂Re a + i ∂L/∂Im a`.
//!
//! Complex gradients throughout this crate follow that convention: the cotangent of
//! a complex value `u` is `∂L/∂Re u + i ∂L/∂Im u`.
//!
//! **Derivative in `f_c`** ([`IqDemod::fc_tangent`]): `f_c` enters the mixing
//! phases `φ_n` and, with the low-pass cut-off a fixed fraction of `f_c`
//! (PyMUST `rf2iq`, [`crate::BMode`]), every filter coefficient. The tangent
//! `∂IQ/∂f_c` with the record held is the same computation in a forward dual
//! ([`usray_ad::Dual`]): phases, Butterworth design
//! ([`crate::filter::butter_lowpass_sections`]) and filter
//! ([`crate::filter::filtfilt_real`]) — exact, no finite difference.

use std::sync::Arc;

use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use usray_ad::{Dual, Real};

use crate::filter::{butter_lowpass_sections, filtfilt_real, Sos};

/// IQ demodulator for records of a fixed length.
#[derive(Clone, Debug)]
pub struct IqDemod {
    /// Low-pass applied forward–backward after mixing.
    pub lowpass: Sos,
    /// Mixing frequency, Hz.
    pub fc: f64,
    /// Sampling frequency, Hz.
    pub fs: f64,
    /// The low-pass cut-off, Hz.
    f_cut: f64,
    /// The low-pass's Butterworth order.
    order: usize,
}

impl IqDemod {
    /// Demodulator at `fc` with a Butterworth(`order`) low-pass cutting at `f_cut` Hz.
    /// `None` unless `0 < f_cut < fs/2`.
    pub fn new(fc: f64, fs: f64, f_cut: f64, order: usize) -> Option<Self> {
        Some(IqDemod {
            lowpass: Sos::butter_lowpass(order, f_cut, fs)?,
            fc,
            fs,
            f_cut,
            order,
        })
    }

    /// The mixing phases `(sin φ_n, cos φ_n)`, `φ_n = 2π f_c (t0 + n/f_s)`, of a
    /// record of `n` samples starting at absolute time `t0`: computed once per
    /// transmit and shared by all its records.
    pub fn mixing(&self, t0: f64, n: usize) -> Vec<(f64, f64)> {
        let w = 2.0 * core::f64::consts::PI * self.fc;
        (0..n)
            .map(|k| (w * (t0 + k as f64 / self.fs)).sin_cos())
            .collect()
    }

    /// Forward on one record starting at absolute time `t0`, written to `out`.
    pub fn forward(&self, rf: &[f64], t0: f64, out: &mut [Complex64]) {
        self.forward_mixed(rf, &self.mixing(t0, rf.len()), out);
    }

    /// [`IqDemod::forward`] with the record's mixing phases from
    /// [`IqDemod::mixing`]: mix, low-pass the complex record (real and imaginary
    /// parts independently), double.
    pub fn forward_mixed(&self, rf: &[f64], mixing: &[(f64, f64)], out: &mut [Complex64]) {
        for ((o, &x), &(s, c)) in out.iter_mut().zip(rf).zip(mixing) {
            *o = Complex64::new(x * c, -x * s);
        }
        self.lowpass.filtfilt_in_place(out);
        for o in out.iter_mut() {
            *o = Complex64::new(2.0 * o.re, 2.0 * o.im);
        }
    }

    /// `∂IQ/∂f_c` of one record starting at absolute time `t0`, with the
    /// record `rf` held and the cut-off moving with `f_c` (`f_cut ∝ f_c`): the
    /// tangent of [`IqDemod::forward`] by a forward dual through the mixing
    /// phases `φ_n = 2π f_c t_n`, the Butterworth design and the zero-phase
    /// filter (module docs).
    ///
    /// ```
    /// use usray_signal::demod::IqDemod;
    /// use usray_signal::Complex64;
    /// let rf: Vec<f64> = (0..64).map(|n| (0.9 * n as f64).sin()).collect();
    /// let at = |fc: f64| {
    ///     let d = IqDemod::new(fc, 20e6, 0.4 * fc, 4).unwrap();
    ///     let mut out = vec![Complex64::new(0.0, 0.0); 64];
    ///     d.forward(&rf, 1e-6, &mut out);
    ///     out
    /// };
    /// let d = IqDemod::new(3e6, 20e6, 0.4 * 3e6, 4).unwrap();
    /// let exact = d.fc_tangent(&rf, 1e-6);
    /// let h = 10.0;
    /// let (p, m) = (at(3e6 + h), at(3e6 - h));
    /// for n in 0..64 {
    ///     let fd = (p[n] - m[n]) / (2.0 * h);
    ///     assert!((fd - exact[n]).norm() < 1e-6 * exact[n].norm().max(1e-9));
    /// }
    /// ```
    pub fn fc_tangent(&self, rf: &[f64], t0: f64) -> Vec<Complex64> {
        let fc = Dual::<1>::variable(self.fc, 0);
        // f_cut = k·f_c: ∂f_cut/∂f_c = f_cut/f_c.
        let f_cut = Dual {
            re: self.f_cut,
            eps: [self.f_cut / self.fc],
        };
        let Some(sections) = butter_lowpass_sections(self.order, f_cut, self.fs) else {
            return vec![Complex64::new(0.0, 0.0); rf.len()];
        };
        let w = fc.scale(2.0 * core::f64::consts::PI);
        let (mut re, mut im): (Vec<Dual<1>>, Vec<Dual<1>>) = rf
            .iter()
            .enumerate()
            .map(|(k, &x)| {
                let phi = w.scale(t0 + k as f64 / self.fs);
                (phi.cos().scale(x), -phi.sin().scale(x))
            })
            .unzip();
        filtfilt_real(&sections, &mut re);
        filtfilt_real(&sections, &mut im);
        re.iter()
            .zip(&im)
            .map(|(r, i)| Complex64::new(2.0 * r.eps[0], 2.0 * i.eps[0]))
            .collect()
    }

    /// VJP on one record: given the IQ cotangent, write `r̄f`.
    pub fn vjp(&self, iq_bar: &[Complex64], t0: f64, rf_bar: &mut [f64]) {
        let mut scratch = iq_bar.to_vec();
        self.vjp_mixed(&mut scratch, &self.mixing(t0, rf_bar.len()), rf_bar);
    }

    /// [`IqDemod::vjp`] with the record's mixing phases from [`IqDemod::mixing`];
    /// `iq_bar` is overwritten (filtered in place).
    pub fn vjp_mixed(&self, iq_bar: &mut [Complex64], mixing: &[(f64, f64)], rf_bar: &mut [f64]) {
        self.lowpass.filtfilt_vjp_in_place(iq_bar);
        for ((r, v), &(s, c)) in rf_bar.iter_mut().zip(iq_bar.iter()).zip(mixing) {
            *r = 2.0 * (c * v.re - s * v.im);
        }
    }
}

/// Analytic-signal operator for records of length `n`.
#[derive(Clone)]
pub struct Analytic {
    fwd: Arc<dyn Fft<f64>>,
    inv: Arc<dyn Fft<f64>>,
    h: Vec<f64>,
}

impl std::fmt::Debug for Analytic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Analytic(n = {})", self.h.len())
    }
}

impl Analytic {
    /// Plan for records of `n` samples.
    pub fn new(n: usize) -> Self {
        let mut p = FftPlanner::new();
        let mut h = vec![0.0; n];
        if n > 0 {
            h[0] = 1.0;
            for v in h.iter_mut().take(n.div_ceil(2)).skip(1) {
                *v = 2.0;
            }
            if n % 2 == 0 {
                h[n / 2] = 1.0;
            }
        }
        Analytic {
            fwd: p.plan_fft_forward(n),
            inv: p.plan_fft_inverse(n),
            h,
        }
    }
    /// Scratch length the transforms need.
    pub fn scratch_len(&self) -> usize {
        self.fwd
            .get_inplace_scratch_len()
            .max(self.inv.get_inplace_scratch_len())
    }
    /// `buf ← A buf` in place (complex input allowed; for the forward, pass the
    /// real record with zero imaginary part).
    pub fn apply(&self, buf: &mut [Complex64], scratch: &mut [Complex64]) {
        let n = buf.len() as f64;
        self.fwd.process_with_scratch(buf, scratch);
        for (v, &h) in buf.iter_mut().zip(&self.h) {
            *v *= h / n;
        }
        self.inv.process_with_scratch(buf, scratch);
    }
    /// Forward on a real record.
    pub fn forward(&self, rf: &[f64], out: &mut [Complex64], scratch: &mut [Complex64]) {
        for (o, &x) in out.iter_mut().zip(rf) {
            *o = Complex64::new(x, 0.0);
        }
        self.apply(out, scratch);
    }
    /// VJP: `r̄f = Re(A ā)`; `abar` is overwritten.
    pub fn vjp(&self, abar: &mut [Complex64], rf_bar: &mut [f64], scratch: &mut [Complex64]) {
        self.apply(abar, scratch);
        for (r, v) in rf_bar.iter_mut().zip(abar.iter()) {
            *r = v.re;
        }
    }
}

/// Hilbert envelope `|a|` of one RF record.
pub fn hilbert_envelope(rf: &[f64]) -> Vec<f64> {
    let a = Analytic::new(rf.len());
    let mut out = vec![Complex64::new(0.0, 0.0); rf.len()];
    let mut scratch = vec![Complex64::new(0.0, 0.0); a.scratch_len()];
    a.forward(rf, &mut out, &mut scratch);
    out.iter().map(|v| v.norm()).collect()
}
