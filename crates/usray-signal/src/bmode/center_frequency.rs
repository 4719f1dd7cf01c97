//! The derivative of the B-mode in the centre frequency `f_c` with the channel
//! data held: [`BMode::center_frequency_vjp`].
//!
//! `I = post(DAS_{f_c}(IQ_{f_c}(P)))`, and `f_c` enters three places:
//! 1. the IQ mixing phases `φ_n = 2π f_c t_n` ([`crate::demod`]);
//! 2. the IQ low-pass, whose cut-off is a fixed fraction of `f_c` (PyMUST
//!    `rf2iq`: Butterworth at bandwidth/2);
//! 3. the delay-and-sum's phase rotation `exp(+2πi f_c τ)` ([`crate::das`]).
//!
//! With `ū = ∂L/∂u` the cotangent of the beamformed images (the B-mode VJP
//! down to them) and the complex convention of [`crate::demod`],
//!
//! `∂L/∂f_c = Re⟨DASᵀ ū, ∂IQ/∂f_c⟩ + Σ Re(conj(ū)·2πiτ·v·e^{iωτ})`,
//!
//! `v` the interpolated IQ sample of a (pixel, transmit, element) and `τ` its
//! delay. The first term (1 and 2) is the tangent of the demodulation in a
//! forward dual ([`IqDemod::fc_tangent`]). The second (3) is read off
//! [`Das::calibration_vjp`]: its sound-speed derivative sums, per (pixel,
//! transmit, element), `Re(conj(ū)·[f_s(P[i+1] − P[i]) + iω·v]·e^{iωτ})·(−τ/c)`,
//! the slope of the interpolation and the rate of the rotation; run on
//! [`PhaseRate`] samples, which keep the second term alone, it gives
//! `g = −(ω/c)·Σ Re(conj(ū)·i·v·e^{iωτ})·τ`, so that term 3 is `−g·c/f_c`
//! (`ω = 2π f_c`). Same delays, apertures and phases as the forward pass, by
//! construction. Every term is exact: there is no finite difference.
//!
//! With the Hilbert analytic signal `f_c` enters nothing (no mixing, no
//! rotation): the derivative is 0.

use rayon::prelude::*;
use rustfft::num_complex::Complex64;

use super::{check_len, BMode, Workspace};
use crate::channels::ChannelData;
use crate::das::{Das, Sample};
use crate::demod::IqDemod;
use crate::error::Result;

impl BMode {
    /// `∂L/∂f_c` with the channel data `ch` held, at the point of the last
    /// [`BMode::forward`] on `ws` (which must have been of `ch`), given
    /// `d_image = ∂L/∂I` (module docs). `ws`'s VJP buffers are overwritten.
    ///
    /// # Errors
    /// As [`BMode::vjp`], and if `ch` does not have the operator's shape.
    pub fn center_frequency_vjp(
        &self,
        ch: &ChannelData,
        ws: &mut Workspace,
        d_image: &[f64],
    ) -> Result<f64> {
        check_len(
            "BMode::center_frequency_vjp: channel data",
            self.das.data_len(),
            ch.samples.len(),
        )?;
        let Some(demod) = &self.demod else {
            return Ok(0.0);
        };
        self.image_to_bf_bar(ws, d_image, "BMode::center_frequency_vjp")?;
        let rotation = rotation_fc_part(&self.das, &ws.cx, &ws.bf_bar);
        // DASᵀ ū, then Re⟨·, ∂IQ/∂f_c⟩ record by record, summed in record order.
        self.das.vjp(&ws.bf_bar, &mut ws.cx_bar, &mut ws.scratch);
        let per_record = self.demodulation_fc_parts(demod, ch, &ws.cx_bar);
        Ok(rotation + per_record.iter().sum::<f64>())
    }

    /// `Re⟨cx_bar_r, ∂IQ_r/∂f_c⟩` of every record `r` of `ch` (with the depth
    /// gain of the forward pass applied to the record first).
    fn demodulation_fc_parts(
        &self,
        demod: &IqDemod,
        ch: &ChannelData,
        cx_bar: &[Complex64],
    ) -> Vec<f64> {
        let ns = self.das.n_samples;
        let ne = self.n_elements;
        let gain = self.gain.as_deref();
        cx_bar
            .par_chunks(ns)
            .enumerate()
            .map(|(rec, cb)| {
                let t = rec / ne;
                let src = &ch.samples[rec * ns..(rec + 1) * ns];
                let gained: Vec<f64>;
                let rf = match gain {
                    Some(g) => {
                        gained = src.iter().zip(&g[t * ns..]).map(|(v, k)| v * k).collect();
                        &gained
                    }
                    None => src,
                };
                let tangent = demod.fc_tangent(rf, self.das.t0_s[t]);
                cb.iter().zip(&tangent).map(|(g, d)| g.dot(*d)).sum::<f64>()
            })
            .collect()
    }
}

/// Term 3 of the module docs: `Σ Re(conj(ū)·2πiτ·v·e^{iωτ})` from
/// [`Das::calibration_vjp`] on [`PhaseRate`] samples of the IQ data `cx` and
/// the image cotangent `bf_bar`.
fn rotation_fc_part(das: &Das, cx: &[Complex64], bf_bar: &[Complex64]) -> f64 {
    let lift = |v: &[Complex64]| -> Vec<PhaseRate> {
        v.iter()
            .map(|&value| PhaseRate {
                value,
                rate: Complex64::new(0.0, 0.0),
            })
            .collect()
    };
    let g = das.calibration_vjp(&lift(cx), &lift(bf_bar));
    -g.d_sound_speed * das.sound_speed_m_s / das.fc_hz
}

/// A complex sample with a second channel that only the rotation's rate
/// reaches: `times_i` moves `i·value` into `rate` (and clears `value`), the
/// other operations act on both channels, and `dot` pairs `rate` with the
/// cotangent's `value`. In [`Das::calibration_vjp`], whose derivative of a
/// rotated sample is `(f_s·(P[i+1] − P[i]) + iω·v)·e^{iωτ}`, the product then
/// holds the rotation's term `iω·v·e^{iωτ}` alone (module docs).
#[derive(Clone, Copy, Debug)]
struct PhaseRate {
    value: Complex64,
    rate: Complex64,
}

impl core::ops::Add for PhaseRate {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        PhaseRate {
            value: self.value + o.value,
            rate: self.rate + o.rate,
        }
    }
}

impl core::ops::AddAssign for PhaseRate {
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl core::ops::Sub for PhaseRate {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        PhaseRate {
            value: self.value - o.value,
            rate: self.rate - o.rate,
        }
    }
}

impl Sample for PhaseRate {
    fn zero() -> Self {
        PhaseRate {
            value: Complex64::new(0.0, 0.0),
            rate: Complex64::new(0.0, 0.0),
        }
    }
    fn scale(self, k: f64) -> Self {
        PhaseRate {
            value: self.value * k,
            rate: self.rate * k,
        }
    }
    fn rot(self, r: Complex64) -> Self {
        PhaseRate {
            value: self.value * r,
            rate: self.rate * r,
        }
    }
    fn rot_conj(self, r: Complex64) -> Self {
        self.rot(r.conj())
    }
    fn dot(self, g: Self) -> f64 {
        self.rate.dot(g.value)
    }
    fn times_i(self) -> Self {
        PhaseRate {
            value: Complex64::new(0.0, 0.0),
            rate: self.value.times_i(),
        }
    }
}
