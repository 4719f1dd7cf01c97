//! Plane-wave delay-and-sum (paper eq. `das`) and its adjoint, the back-projection
//! (paper eq. `das_adjoint`), on RF or complex (IQ / analytic) channel data.
//!
//! For pixel `(x, z)`, transmit `θ` (CONTRACT §1 clock) and element `e` at
//! `x_e = (e − (N−1)/2)·pitch` on `z = 0`, the two-way time (s) is
//!
//! `τ = (x sin θ + z cos θ)/c + √((x − x_e)² + z²)/c`
//!
//! (Montaldo et al., IEEE TUFFC 56(3), 2009, eq. 2 with the transmit origin at the
//! array centre). The sample position is `s = (τ − t0_θ)·f_s` with `t0_θ` the time of
//! sample 0 of that transmit; the record is read by linear interpolation
//! `P(s) = (1 − w)·P[i] + w·P[i+1]`, `i = ⌊s⌋`, `w = s − i`; positions with `s < 0`
//! or `i + 1 ≥ n_samples` contribute 0. On baseband IQ data the interpolated value is
//! multiplied by `exp(+2πi f_c τ)` to restore the carrier phase (Szabo, "Diagnostic
//! Ultrasound Imaging", §10.5; as PyMUST `dasmtx`). Receive apodisation by F-number
//! `F`: element `e` contributes with weight 1 if `|x − x_e| ≤ z/(2F)`, else 0
//! (rectangular; `F = 0` = full aperture). Transmits are summed coherently.
//!
//! Parallelism: the forward pass is split over image rows, each pixel summing in a
//! fixed order; the VJP is split over elements, each sample accumulating pixels in
//! a fixed order; the calibration gradients reduce per-row partial sums in row order.
//! Results are therefore bit-identical for any number of threads.

use rayon::prelude::*;
use rustfft::num_complex::Complex64;

use crate::channels::ChannelMeta;
use crate::error::{Result, SignalError};

const TAU: f64 = 2.0 * core::f64::consts::PI;

/// A delay-and-sum configuration: pixel grid, array, clock and aperture.
#[derive(Clone, Debug, PartialEq)]
pub struct Das {
    /// Lateral pixel positions, m (image columns).
    pub x_m: Vec<f64>,
    /// Depth pixel positions, m (image rows).
    pub z_m: Vec<f64>,
    /// Number of elements.
    pub n_elements: usize,
    /// Element pitch, m.
    pub pitch_m: f64,
    /// Sound speed the beamformer assumes, m/s.
    pub sound_speed_m_s: f64,
    /// Sampling frequency, Hz.
    pub fs_hz: f64,
    /// Centre (demodulation) frequency, Hz; used for the phase rotation.
    pub fc_hz: f64,
    /// Per transmit: steering angle, rad.
    pub angles_rad: Vec<f64>,
    /// Per transmit: time of sample 0, s (CONTRACT §1 clock).
    pub t0_s: Vec<f64>,
    /// Samples per record.
    pub n_samples: usize,
    /// Receive F-number; 0 = full aperture.
    pub f_number: f64,
    /// Multiply complex samples by `exp(+2πi f_c τ)` (true for baseband IQ, false for
    /// RF and analytic signals).
    pub rotate: bool,
}

/// Gradient of a scalar loss with respect to the beamformer's calibration
/// parameters (through the delays, the interpolation and the phase rotation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationGrad {
    /// `∂L/∂c`, per (m/s).
    pub d_sound_speed: f64,
    /// `∂L/∂pitch`, per m.
    pub d_pitch: f64,
}

/// A real or complex channel sample (RF: `f64`, IQ/analytic: `Complex64`).
pub trait Sample:
    Copy
    + Send
    + Sync
    + core::ops::Add<Output = Self>
    + core::ops::AddAssign
    + core::ops::Sub<Output = Self>
    + 'static
{
    /// Zero.
    fn zero() -> Self;
    /// `self · k`.
    fn scale(self, k: f64) -> Self;
    /// `self · r` (for `f64`, `r` is always 1: RF is never rotated).
    fn rot(self, r: Complex64) -> Self;
    /// `self · conj(r)`.
    fn rot_conj(self, r: Complex64) -> Self;
    /// `Re(conj(g)·self)`: the real inner product of two samples.
    fn dot(self, g: Self) -> f64;
    /// `self · i` (only used with rotation, i.e. complex).
    fn times_i(self) -> Self;
}

impl Sample for f64 {
    fn zero() -> Self {
        0.0
    }
    fn scale(self, k: f64) -> Self {
        self * k
    }
    fn rot(self, _r: Complex64) -> Self {
        self
    }
    fn rot_conj(self, _r: Complex64) -> Self {
        self
    }
    fn dot(self, g: Self) -> f64 {
        self * g
    }
    fn times_i(self) -> Self {
        0.0
    }
}

impl Sample for Complex64 {
    fn zero() -> Self {
        Complex64::new(0.0, 0.0)
    }
    fn scale(self, k: f64) -> Self {
        self * k
    }
    fn rot(self, r: Complex64) -> Self {
        self * r
    }
    fn rot_conj(self, r: Complex64) -> Self {
        self * r.conj()
    }
    fn dot(self, g: Self) -> f64 {
        self.re * g.re + self.im * g.im
    }
    fn times_i(self) -> Self {
        Complex64::new(-self.im, self.re)
    }
}

/// Integer sample `i` and fraction `w` of position `s`, if both `i` and `i + 1` lie
/// in a record of `ns` samples (NaN and negative positions give `None`).
#[inline]
fn locate(s: f64, ns: usize) -> Option<(usize, f64)> {
    if s.is_nan() || s < 0.0 {
        return None;
    }
    let i = s as usize;
    (i + 1 < ns).then_some((i, s - i as f64))
}

/// `n` points from `a` to `b` inclusive (`n = 1` gives `a`).
pub fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    if n == 1 {
        return vec![a];
    }
    (0..n)
        .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
        .collect()
}

impl Das {
    /// A beamformer for channel data described by `meta` with `n_samples` per record,
    /// on the grid `x_m` × `z_m`, at sound speed `c` (m/s) and F-number `f_number`.
    pub fn new(
        meta: &ChannelMeta,
        n_samples: usize,
        x_m: Vec<f64>,
        z_m: Vec<f64>,
        c: f64,
        f_number: f64,
        rotate: bool,
    ) -> Result<Das> {
        if !(c.is_finite() && c > 0.0) {
            return Err(SignalError::Invalid(format!(
                "beamforming sound speed {c} m/s"
            )));
        }
        if !(f_number.is_finite() && f_number >= 0.0) {
            return Err(SignalError::Invalid(format!(
                "F-number {f_number} (must be ≥ 0)"
            )));
        }
        if x_m.is_empty() || z_m.is_empty() {
            return Err(SignalError::Invalid("empty pixel grid".into()));
        }
        let nt = meta.transmits.len();
        Ok(Das {
            x_m,
            z_m,
            n_elements: meta.probe.n_elements,
            pitch_m: meta.probe.pitch_m,
            sound_speed_m_s: c,
            fs_hz: meta.sampling_frequency_hz,
            fc_hz: meta.center_frequency_hz,
            angles_rad: meta.transmits.iter().map(|t| t.angle_rad).collect(),
            t0_s: (0..nt).map(|i| meta.t0_for(i)).collect(),
            n_samples,
            f_number,
            rotate,
        })
    }

    /// Number of transmits.
    pub fn n_transmits(&self) -> usize {
        self.angles_rad.len()
    }
    /// Image size `(nz, nx)`.
    pub fn image_shape(&self) -> (usize, usize) {
        (self.z_m.len(), self.x_m.len())
    }
    /// Number of channel samples `n_transmits · n_elements · n_samples`.
    pub fn data_len(&self) -> usize {
        self.n_transmits() * self.n_elements * self.n_samples
    }
    /// Element centre `x_e`, m.
    #[inline]
    pub fn element_x(&self, e: usize) -> f64 {
        (e as f64 - (self.n_elements as f64 - 1.0) / 2.0) * self.pitch_m
    }

    #[inline]
    fn in_aperture(&self, dx: f64, z: f64) -> bool {
        self.f_number <= 0.0 || 2.0 * self.f_number * dx.abs() <= z
    }

    fn check(&self, data_len: usize, out_len: usize) {
        let (nz, nx) = self.image_shape();
        assert_eq!(data_len, self.data_len(), "channel buffer length");
        assert_eq!(out_len, nz * nx, "image buffer length");
    }

    /// Forward: `out[iz·nx + ix] = Σ_θ Σ_e P_θ,e(s)·rot` (paper eq. `das`).
    /// `data` is `[n_transmits, n_elements, n_samples]`, `out` is `[nz, nx]`.
    ///
    /// # Panics
    /// If the buffer lengths disagree with the configuration (a programming error).
    pub fn forward<S: Sample>(&self, data: &[S], out: &mut [S]) {
        self.check(data.len(), out.len());
        let nx = self.x_m.len();
        let nt = self.n_transmits();
        let (c, fs, ns, ne) = (
            self.sound_speed_m_s,
            self.fs_hz,
            self.n_samples,
            self.n_elements,
        );
        let w = TAU * self.fc_hz;
        let trig: Vec<(f64, f64)> = self.angles_rad.iter().map(|a| a.sin_cos()).collect();
        out.par_chunks_mut(nx).enumerate().for_each_init(
            || {
                (
                    vec![0.0; nt],
                    vec![Complex64::new(1.0, 0.0); nt],
                    vec![S::zero(); nt],
                )
            },
            |(ttx, rtx, acc), (iz, row)| {
                let z = self.z_m[iz];
                for (ix, o) in row.iter_mut().enumerate() {
                    let x = self.x_m[ix];
                    for t in 0..nt {
                        let tt = (x * trig[t].0 + z * trig[t].1) / c;
                        ttx[t] = tt - self.t0_s[t];
                        if self.rotate {
                            let (s, co) = (w * tt).sin_cos();
                            rtx[t] = Complex64::new(co, s);
                        }
                        acc[t] = S::zero();
                    }
                    for e in 0..ne {
                        let dx = x - self.element_x(e);
                        if !self.in_aperture(dx, z) {
                            continue;
                        }
                        let trx = (dx * dx + z * z).sqrt() / c;
                        let rrx = if self.rotate {
                            let (s, co) = (w * trx).sin_cos();
                            Complex64::new(co, s)
                        } else {
                            Complex64::new(1.0, 0.0)
                        };
                        for t in 0..nt {
                            let s = (ttx[t] + trx) * fs;
                            let Some((i, fw)) = locate(s, ns) else {
                                continue;
                            };
                            let base = (t * ne + e) * ns + i;
                            let v = data[base].scale(1.0 - fw) + data[base + 1].scale(fw);
                            acc[t] += v.rot(rrx);
                        }
                    }
                    let mut sum = S::zero();
                    for t in 0..nt {
                        sum += acc[t].rot(rtx[t]);
                    }
                    *o = sum;
                }
            },
        );
    }

    /// VJP (paper eq. `das_adjoint`): back-projects the image cotangent `out_bar`
    /// (`[nz, nx]`) into `data_bar` (`[n_transmits, n_elements, n_samples]`,
    /// overwritten) with the same interpolation weights (and the conjugate
    /// rotation). `scratch` must have `data_len()` entries (element-major staging).
    ///
    /// # Panics
    /// If the buffer lengths disagree with the configuration.
    pub fn vjp<S: Sample>(&self, out_bar: &[S], data_bar: &mut [S], scratch: &mut [S]) {
        self.check(data_bar.len(), out_bar.len());
        assert_eq!(scratch.len(), self.data_len(), "scratch length");
        let nx = self.x_m.len();
        let nt = self.n_transmits();
        let (c, fs, ns, ne) = (
            self.sound_speed_m_s,
            self.fs_hz,
            self.n_samples,
            self.n_elements,
        );
        let w = TAU * self.fc_hz;
        let trig: Vec<(f64, f64)> = self.angles_rad.iter().map(|a| a.sin_cos()).collect();
        // Transmit delays and rotations per (transmit, pixel), once per call, so the
        // per-element loop pays one sqrt and one sincos per (pixel, element) like
        // the forward pass.
        let npix = nx * self.z_m.len();
        let mut txt = vec![0.0; nt * npix];
        let mut txr = vec![Complex64::new(1.0, 0.0); if self.rotate { nt * npix } else { 0 }];
        txt.par_chunks_mut(npix).enumerate().for_each(|(t, tab)| {
            for (p, v) in tab.iter_mut().enumerate() {
                let (x, z) = (self.x_m[p % nx], self.z_m[p / nx]);
                *v = (x * trig[t].0 + z * trig[t].1) / c;
            }
        });
        if self.rotate {
            txr.par_chunks_mut(npix).enumerate().for_each(|(t, tab)| {
                for (p, v) in tab.iter_mut().enumerate() {
                    let (sn, co) = (w * txt[t * npix + p]).sin_cos();
                    *v = Complex64::new(co, sn);
                }
            });
        }
        // scratch layout [e][t][ns]: one contiguous block per element.
        scratch
            .par_chunks_mut(nt * ns)
            .enumerate()
            .for_each(|(e, blk)| {
                blk.fill(S::zero());
                let xe = self.element_x(e);
                for (iz, &z) in self.z_m.iter().enumerate() {
                    for (ix, &x) in self.x_m.iter().enumerate() {
                        let dx = x - xe;
                        if !self.in_aperture(dx, z) {
                            continue;
                        }
                        let p = iz * nx + ix;
                        let g = out_bar[p];
                        let trx = (dx * dx + z * z).sqrt() / c;
                        let grx = if self.rotate {
                            let (sn, co) = (w * trx).sin_cos();
                            g.rot_conj(Complex64::new(co, sn))
                        } else {
                            g
                        };
                        for t in 0..nt {
                            let s = (txt[t * npix + p] - self.t0_s[t] + trx) * fs;
                            let Some((i, fw)) = locate(s, ns) else {
                                continue;
                            };
                            let gr = if self.rotate {
                                grx.rot_conj(txr[t * npix + p])
                            } else {
                                grx
                            };
                            let base = t * ns + i;
                            blk[base] += gr.scale(1.0 - fw);
                            blk[base + 1] += gr.scale(fw);
                        }
                    }
                }
            });
        data_bar
            .par_chunks_mut(ns)
            .enumerate()
            .for_each(|(rec, dst)| {
                let (t, e) = (rec / ne, rec % ne);
                let src = (e * nt + t) * ns;
                dst.copy_from_slice(&scratch[src..src + ns]);
            });
    }

    /// Gradient of `L` with respect to the beamforming sound speed and the element
    /// pitch, given the image cotangent `out_bar` (`∂L/∂out`, complex convention of
    /// [`crate::demod`]) and the data the forward pass used. Differentiates
    /// `τ(c, pitch)` through the linear interpolation (`∂P/∂s = P[i+1] − P[i]`) and
    /// the rotation (`∂ exp(iωτ)/∂τ = iω exp(iωτ)`):
    /// `∂τ/∂c = −τ/c`, `∂τ/∂pitch = −(x − x_e)/(c·r)·(e − (N−1)/2)`. The F-number
    /// aperture mask is held fixed (a discontinuity without a derivative).
    pub fn calibration_vjp<S: Sample>(&self, data: &[S], out_bar: &[S]) -> CalibrationGrad {
        self.check(data.len(), out_bar.len());
        let nx = self.x_m.len();
        let nt = self.n_transmits();
        let (c, fs, ns, ne) = (
            self.sound_speed_m_s,
            self.fs_hz,
            self.n_samples,
            self.n_elements,
        );
        let w = TAU * self.fc_hz;
        let trig: Vec<(f64, f64)> = self.angles_rad.iter().map(|a| a.sin_cos()).collect();
        let mid = (ne as f64 - 1.0) / 2.0;
        let rows: Vec<(f64, f64)> = (0..self.z_m.len())
            .into_par_iter()
            .map(|iz| {
                let z = self.z_m[iz];
                let (mut gc, mut gp) = (0.0, 0.0);
                for (ix, &x) in self.x_m.iter().enumerate() {
                    let g = out_bar[iz * nx + ix];
                    for e in 0..ne {
                        let dx = x - self.element_x(e);
                        if !self.in_aperture(dx, z) {
                            continue;
                        }
                        let r = (dx * dx + z * z).sqrt();
                        let trx = r / c;
                        let dtau_dp = -dx / (c * r.max(1e-300)) * (e as f64 - mid);
                        for t in 0..nt {
                            let tt = (x * trig[t].0 + z * trig[t].1) / c;
                            let tau = tt + trx;
                            let s = (tau - self.t0_s[t]) * fs;
                            let Some((i, fw)) = locate(s, ns) else {
                                continue;
                            };
                            let base = (t * ne + e) * ns + i;
                            let (d0, d1) = (data[base], data[base + 1]);
                            let mut dv = (d1 - d0).scale(fs);
                            if self.rotate {
                                let v = d0.scale(1.0 - fw) + d1.scale(fw);
                                let (sn, co) = (w * tau).sin_cos();
                                dv = (dv + v.times_i().scale(w)).rot(Complex64::new(co, sn));
                            }
                            let q = dv.dot(g);
                            gc += q * (-tau / c);
                            gp += q * dtau_dp;
                        }
                    }
                }
                (gc, gp)
            })
            .collect();
        let (mut gc, mut gp) = (0.0, 0.0);
        for (a, b) in rows {
            gc += a;
            gp += b;
        }
        CalibrationGrad {
            d_sound_speed: gc,
            d_pitch: gp,
        }
    }
}
