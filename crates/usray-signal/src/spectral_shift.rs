//! How the echoes' spectra of measured channel data shift against a model's
//! with the path they travelled: the spectral-shift estimate of attenuation.
//!
//! Frequency-dependent attenuation `α(f) = α₀ f` (Np per metre) filters a
//! pulse travelling a two-way path `d` by `exp(−α₀ f d)` in amplitude, so its
//! power spectrum by `exp(−2 α₀ f d)`. For a Gaussian power spectrum of mean
//! `f̄` and variance `σ²` the product is again Gaussian, with its mean moved to
//!
//! `f̄(d) = f̄ − 2 α₀ σ² d`
//!
//! (Kuc, *IEEE Trans. ASSP* 32(1), 1984; Narayana & Ophir, *Ultrason. Imaging*
//! 5, 1983: the centroid downshift). A lower centre frequency of the probe,
//! by contrast, shifts every echo's mean frequency alike, whatever its path.
//! So where the measured echoes' mean frequency falls with the path faster
//! than the model's, by `Δs` Hz per metre, the data carry an attenuation of
//! `α₀ = −Δs / (2σ²)` more than the model.
//!
//! [`spectral_shift`] finds the model's echoes (stretches of each transmit
//! where the model's channel energy lies within a dynamic range of its
//! peak), takes the power-weighted mean frequency of the measured and the
//! model's records over each echo's samples (summed over elements,
//! Hann-windowed), and fits the difference `measured − model` by a line in
//! the echo's two-way path `d = c·t` by weighted least squares. Its standard
//! error comes from the echoes' scatter about the line: it holds whatever
//! makes echoes differ other than the path (a layer's resonance, the grid of a
//! full-wave simulation), not only noise.

use crate::{ChannelData, SignalError};
use rustfft::num_complex::Complex64;
use rustfft::FftPlanner;

/// Settings of [`spectral_shift`], in periods of the probe's centre
/// frequency where they are times.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SpectralShiftOptions {
    /// An echo is where the model's channel energy (summed over elements,
    /// smoothed over [`SpectralShiftOptions::smoothing_periods`]) lies within
    /// this many dB of its peak on the transmit (default 20).
    pub dynamic_range_db: f64,
    /// Length of the moving average of the energy, periods (default 1.25).
    pub smoothing_periods: f64,
    /// Samples added before and after each echo so that its whole pulse is
    /// in the spectrum, periods (default 1.25).
    pub padding_periods: f64,
    /// Shortest echo kept, periods (default 2.5: the spectrum of fewer
    /// cycles is too broad to locate).
    pub min_periods: f64,
    /// Frequencies over which the mean is taken, as multiples of the centre
    /// frequency (default 0.2 to 2).
    pub band: [f64; 2],
}

impl Default for SpectralShiftOptions {
    fn default() -> Self {
        Self {
            dynamic_range_db: 20.0,
            smoothing_periods: 1.25,
            padding_periods: 1.25,
            min_periods: 2.5,
            band: [0.2, 2.0],
        }
    }
}

/// One echo of [`spectral_shift`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct EchoSpectrum {
    /// Transmit it belongs to.
    pub transmit: usize,
    /// Its two-way path `c·t` at the energy-weighted centre of its samples, m.
    pub path_m: f64,
    /// Its weight in the fit: the geometric mean of the measured and the
    /// model's energy over it, each as a share of its record's.
    pub weight: f64,
    /// Power-weighted mean frequency of the measured echo, Hz.
    pub measured_hz: f64,
    /// Power-weighted mean frequency of the model's echo, Hz.
    pub model_hz: f64,
}

/// The measured echoes' mean frequency against the model's along the path
/// ([`spectral_shift`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SpectralShift {
    /// The echoes fitted.
    pub echoes: Vec<EchoSpectrum>,
    /// Mean frequency of measured minus model at the weighted mean path, Hz.
    pub offset_hz: f64,
    /// Standard error of [`SpectralShift::offset_hz`] from the echoes' scatter
    /// about the line (`None` with fewer than three echoes).
    pub offset_std: Option<f64>,
    /// How that difference changes with the two-way path, Hz per metre.
    pub slope_hz_per_m: f64,
    /// Standard error of the slope from the echoes' scatter about the line
    /// (`None` with fewer than three echoes).
    pub slope_std: Option<f64>,
    /// Power-weighted variance of the measured records' spectrum, Hz², the
    /// `σ²` of the module docs.
    pub spectral_variance_hz2: f64,
    /// The attenuation the data carry beyond the model's,
    /// `α₀ = −slope / (2σ²)`, dB/(cm·MHz).
    pub attenuation_db_cm_mhz: f64,
    /// Its standard error (`None` with fewer than three echoes).
    pub attenuation_std: Option<f64>,
}

impl SpectralShift {
    /// [`SpectralShift::offset_hz`] in its standard errors.
    pub fn offset_z(&self) -> Option<f64> {
        self.offset_std
            .filter(|s| *s > 0.0)
            .map(|s| self.offset_hz / s)
    }

    /// [`SpectralShift::attenuation_db_cm_mhz`] in its standard errors.
    pub fn attenuation_z(&self) -> Option<f64> {
        self.attenuation_std
            .filter(|s| *s > 0.0)
            .map(|s| self.attenuation_db_cm_mhz / s)
    }
}

/// Np/(m·Hz) to dB/(cm·MHz): 20/ln 10 dB per neper, 0.01 m per cm, 10⁶ Hz per
/// MHz.
const DB_CM_MHZ_PER_NP_M_HZ: f64 = 8.685_889_638_065_035 * 0.01 * 1e6;

/// The spectral shift of `measured` against `model` (module docs):
/// both channel data of the same acquisition (transmits and elements in the
/// same order; sampling and record lengths may differ), `sound_speed_m_s` the
/// speed that turns time into path, `center_frequency_hz` the probe's.
///
/// # Errors
/// Data of other transmit or element counts, a non-positive speed or centre
/// frequency, fewer than two echoes, or echoes all at one path.
///
/// ```
/// use usray_signal::{pulse::pulse, spectral_shift, ChannelData, ChannelMeta, SpectralShiftOptions};
/// // Echoes at 10, 15 and 20 mm; the measured probe is centred 4% low
/// // (4.8 MHz for 5): every echo's spectrum moves down alike, which is an
/// // offset, not an attenuation.
/// let meta: ChannelMeta = serde_json::from_value(serde_json::json!({
///     "format": "usray-channels/1", "sampling_frequency_hz": 40e6, "t0_s": 0.0,
///     "sound_speed_m_s": 1500.0, "center_frequency_hz": 5e6,
///     "probe": {"kind": "linear", "n_elements": 1, "pitch_m": 0.3e-3, "element_width_m": 0.27e-3},
///     "transmits": [{"kind": "plane_wave", "angle_rad": 0.0}]
/// })).unwrap();
/// let record = |f_c: f64| -> Vec<f64> {
///     (0..2048)
///         .map(|k| [0.010, 0.015, 0.020].iter().map(|z| pulse(k as f64 / 40e6 - 2.0 * z / 1500.0, f_c, 3.0)).sum())
///         .collect()
/// };
/// let model = ChannelData { meta: meta.clone(), n_samples: 2048, samples: record(5e6) };
/// let measured = ChannelData { meta, n_samples: 2048, samples: record(4.8e6) };
/// let s = spectral_shift(&measured, &model, 1500.0, 5e6, &SpectralShiftOptions::default()).unwrap();
/// assert_eq!(s.echoes.len(), 3);
/// assert!(s.offset_hz < -0.1e6, "{}", s.offset_hz);
/// assert!(s.attenuation_db_cm_mhz.abs() < 0.02, "{}", s.attenuation_db_cm_mhz);
/// ```
pub fn spectral_shift(
    measured: &ChannelData,
    model: &ChannelData,
    sound_speed_m_s: f64,
    center_frequency_hz: f64,
    opts: &SpectralShiftOptions,
) -> Result<SpectralShift, SignalError> {
    if measured.n_transmits() != model.n_transmits() || measured.n_elements() != model.n_elements()
    {
        return Err(SignalError::Invalid(format!(
            "spectral shift: the measured data have {} transmits × {} elements, the model {} × {}",
            measured.n_transmits(),
            measured.n_elements(),
            model.n_transmits(),
            model.n_elements()
        )));
    }
    if !(sound_speed_m_s > 0.0 && center_frequency_hz > 0.0) {
        return Err(SignalError::Invalid(format!(
            "spectral shift: sound speed {sound_speed_m_s} m/s and centre frequency {center_frequency_hz} Hz must be positive"
        )));
    }
    let band_hz = [
        opts.band[0] * center_frequency_hz,
        opts.band[1] * center_frequency_hz,
    ];
    let fs_model = model.meta.sampling_frequency_hz;
    let fs_measured = measured.meta.sampling_frequency_hz;
    let period_samples = |p: f64| (p * fs_model / center_frequency_hz).round() as usize;
    let (smoothing, pad, min_len) = (
        period_samples(opts.smoothing_periods),
        period_samples(opts.padding_periods),
        period_samples(opts.min_periods).max(4),
    );
    let mut planner = FftPlanner::new();
    let mut echoes = Vec::new();
    for tx in 0..model.n_transmits() {
        let t0_model = model.meta.t0_for(tx);
        let t0_measured = measured.meta.t0_for(tx);
        let energy_model = smoothed_energy(model, tx, smoothing);
        let energy_measured = energy(measured, tx);
        let total_model: f64 = energy_model.iter().sum();
        let total_measured: f64 = energy_measured.iter().sum();
        if !(total_model > 0.0 && total_measured > 0.0) {
            continue;
        }
        let peak = energy_model.iter().copied().fold(0.0, f64::max);
        let threshold = peak * 10f64.powf(-opts.dynamic_range_db / 10.0);
        for (a, b) in runs_above(&energy_model, threshold) {
            let (a, b) = (a.saturating_sub(pad), (b + pad).min(model.n_samples));
            if b - a < min_len {
                continue;
            }
            // The same times in the measured record.
            let t_a = t0_model + a as f64 / fs_model;
            let t_b = t0_model + b as f64 / fs_model;
            let ma = ((t_a - t0_measured) * fs_measured).round();
            let mb = ((t_b - t0_measured) * fs_measured).round();
            if ma < 0.0 || mb > measured.n_samples as f64 || mb - ma < 4.0 {
                continue;
            }
            let (ma, mb) = (ma as usize, mb as usize);
            let Some(model_hz) = mean_frequency(model, tx, a, b, fs_model, band_hz, &mut planner)
            else {
                continue;
            };
            let Some(measured_hz) =
                mean_frequency(measured, tx, ma, mb, fs_measured, band_hz, &mut planner)
            else {
                continue;
            };
            let e_model: f64 = energy_model[a..b].iter().sum();
            let e_measured: f64 = energy_measured[ma..mb].iter().sum();
            let weight = (e_model / total_model * e_measured / total_measured).sqrt();
            let t_centre = t0_model
                + energy_model[a..b]
                    .iter()
                    .enumerate()
                    .map(|(i, e)| (a + i) as f64 * e)
                    .sum::<f64>()
                    / e_model
                    / fs_model;
            echoes.push(EchoSpectrum {
                transmit: tx,
                path_m: sound_speed_m_s * t_centre,
                weight,
                measured_hz,
                model_hz,
            });
        }
    }
    if echoes.len() < 2 {
        return Err(SignalError::Invalid(format!(
            "spectral shift: {} echo(es) found in the model's channel data; a slope takes two",
            echoes.len()
        )));
    }
    let w: Vec<f64> = echoes.iter().map(|e| e.weight).collect();
    let x: Vec<f64> = echoes.iter().map(|e| e.path_m).collect();
    let y: Vec<f64> = echoes.iter().map(|e| e.measured_hz - e.model_hz).collect();
    let line = weighted_line(&x, &y, &w).ok_or_else(|| {
        SignalError::Invalid("spectral shift: every echo lies at the same path".into())
    })?;
    let spectral_variance_hz2 = spectrum_moments(measured, band_hz, &mut planner)
        .map(|(_, v)| v)
        .filter(|v| *v > 0.0)
        .ok_or_else(|| {
            SignalError::Invalid(
                "spectral shift: the measured data have no power in the band".into(),
            )
        })?;
    let to_attenuation = -DB_CM_MHZ_PER_NP_M_HZ / (2.0 * spectral_variance_hz2);
    Ok(SpectralShift {
        echoes,
        offset_hz: line.offset,
        offset_std: line.offset_std,
        slope_hz_per_m: line.slope,
        slope_std: line.slope_std,
        spectral_variance_hz2,
        attenuation_db_cm_mhz: line.slope * to_attenuation,
        attenuation_std: line.slope_std.map(|s| s * to_attenuation.abs()),
    })
}

/// Energy `Σ_el x²` of each sample of transmit `tx`.
fn energy(ch: &ChannelData, tx: usize) -> Vec<f64> {
    let mut e = vec![0.0; ch.n_samples];
    for el in 0..ch.n_elements() {
        for (acc, v) in e.iter_mut().zip(ch.record(tx, el)) {
            *acc += v * v;
        }
    }
    e
}

/// [`energy`] under a centred moving average of `len` samples.
fn smoothed_energy(ch: &ChannelData, tx: usize, len: usize) -> Vec<f64> {
    let e = energy(ch, tx);
    let len = len.max(1);
    let mut prefix = vec![0.0; e.len() + 1];
    for (i, v) in e.iter().enumerate() {
        prefix[i + 1] = prefix[i] + v;
    }
    (0..e.len())
        .map(|i| {
            let a = i.saturating_sub(len / 2);
            let b = (a + len).min(e.len());
            (prefix[b] - prefix[a]) / (b - a) as f64
        })
        .collect()
}

/// Maximal runs `[a, b)` where `e` exceeds `threshold`.
fn runs_above(e: &[f64], threshold: f64) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut start = None;
    for (i, v) in e.iter().enumerate() {
        match (start, *v > threshold) {
            (None, true) => start = Some(i),
            (Some(a), false) => {
                runs.push((a, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(a) = start {
        runs.push((a, e.len()));
    }
    runs
}

/// Power-weighted mean frequency, Hz, over `band_hz` of samples `a..b` of
/// transmit `tx`, Hann-windowed and zero-padded fourfold, power summed over
/// elements; `None` without power in the band.
fn mean_frequency(
    ch: &ChannelData,
    tx: usize,
    a: usize,
    b: usize,
    fs: f64,
    band_hz: [f64; 2],
    planner: &mut FftPlanner<f64>,
) -> Option<f64> {
    let n = b - a;
    let nfft = 4 * n;
    let fft = planner.plan_fft_forward(nfft);
    let window: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * (i as f64 + 0.5) / n as f64).cos())
        .collect();
    let mut power = vec![0.0; nfft / 2 + 1];
    let mut buf = vec![Complex64::new(0.0, 0.0); nfft];
    for el in 0..ch.n_elements() {
        buf.iter_mut().for_each(|c| *c = Complex64::new(0.0, 0.0));
        for ((c, v), w) in buf.iter_mut().zip(&ch.record(tx, el)[a..b]).zip(&window) {
            c.re = v * w;
        }
        fft.process(&mut buf);
        for (p, c) in power.iter_mut().zip(&buf) {
            *p += c.norm_sqr();
        }
    }
    moments(&power, fs / nfft as f64, band_hz).map(|(mean, _)| mean)
}

/// Power-weighted mean and variance, Hz and Hz², over `band_hz` of the
/// whole records (every transmit and element, no window): the spectrum the
/// attenuation filters, whose variance is the `σ²` of the module docs (a
/// window over one echo would broaden it).
fn spectrum_moments(
    ch: &ChannelData,
    band_hz: [f64; 2],
    planner: &mut FftPlanner<f64>,
) -> Option<(f64, f64)> {
    let n = ch.n_samples;
    let fft = planner.plan_fft_forward(n);
    let mut power = vec![0.0; n / 2 + 1];
    let mut buf = vec![Complex64::new(0.0, 0.0); n];
    for tx in 0..ch.n_transmits() {
        for el in 0..ch.n_elements() {
            for (c, v) in buf.iter_mut().zip(ch.record(tx, el)) {
                *c = Complex64::new(*v, 0.0);
            }
            fft.process(&mut buf);
            for (p, c) in power.iter_mut().zip(&buf) {
                *p += c.norm_sqr();
            }
        }
    }
    moments(&power, ch.meta.sampling_frequency_hz / n as f64, band_hz)
}

/// Mean and variance of frequency under the power spectrum `power` (bin `i`
/// at `i·df`), over `band_hz`; `None` without power there.
fn moments(power: &[f64], df: f64, band_hz: [f64; 2]) -> Option<(f64, f64)> {
    let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
    for (i, p) in power.iter().enumerate() {
        let f = i as f64 * df;
        if f > band_hz[0] && f < band_hz[1] {
            s0 += p;
            s1 += p * f;
            s2 += p * f * f;
        }
    }
    (s0 > 0.0).then(|| {
        let mean = s1 / s0;
        (mean, (s2 / s0 - mean * mean).max(0.0))
    })
}

/// A weighted least-squares line ([`weighted_line`]).
struct Line {
    /// Its value at the weighted mean of `x`.
    offset: f64,
    offset_std: Option<f64>,
    slope: f64,
    slope_std: Option<f64>,
}

/// The line `y ≈ offset + slope·(x − x̄)` minimising `Σ w (y − …)²`, `x̄` the
/// weighted mean of `x`. The slope's standard error takes the weights as
/// relative precisions and the residual scale from the fit, with
/// `n_eff = (Σw)²/Σw²` points (fewer than `n` where a few echoes dominate):
/// `se² = Σ w r² / Σw / (n_eff − 2) / (Σ w (x − x̄)² / Σw)`, and the
/// offset's (the weighted mean's) `se² = Σ w r² / Σw / (n_eff − 2)`; `None`
/// where `n_eff ≤ 2`. `None` for the whole line where every `x` is the same.
fn weighted_line(x: &[f64], y: &[f64], w: &[f64]) -> Option<Line> {
    let sw: f64 = w.iter().sum();
    let xm = x.iter().zip(w).map(|(x, w)| w * x).sum::<f64>() / sw;
    let ym = y.iter().zip(w).map(|(y, w)| w * y).sum::<f64>() / sw;
    let sxx = x
        .iter()
        .zip(w)
        .map(|(x, w)| w * (x - xm).powi(2))
        .sum::<f64>();
    if sxx.is_nan() || sxx <= 0.0 {
        return None;
    }
    let sxy = x
        .iter()
        .zip(y)
        .zip(w)
        .map(|((x, y), w)| w * (x - xm) * (y - ym))
        .sum::<f64>();
    let slope = sxy / sxx;
    let n_eff = sw * sw / w.iter().map(|w| w * w).sum::<f64>();
    let rss = x
        .iter()
        .zip(y)
        .zip(w)
        .map(|((x, y), w)| w * (y - ym - slope * (x - xm)).powi(2))
        .sum::<f64>();
    let scale = (n_eff > 2.0).then(|| rss / sw / (n_eff - 2.0));
    let slope_std = scale.map(|v| (v / (sxx / sw)).sqrt());
    Some(Line {
        offset: ym,
        offset_std: scale.map(f64::sqrt),
        slope,
        slope_std,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ChannelMeta;

    /// One element's record of Gaussian echoes (amplitude spectrum of σ 1 MHz
    /// about `f_c`) at `depths_m`, each attenuated by `α₀ f d` along its
    /// two-way path `d`, `alpha` in dB/(cm·MHz): the closed form of the
    /// module docs.
    fn echoes(f_c: f64, alpha: f64, depths_m: &[f64]) -> ChannelData {
        let meta: ChannelMeta = serde_json::from_value(serde_json::json!({
            "format": "usray-channels/1", "sampling_frequency_hz": 40e6, "t0_s": 0.0,
            "sound_speed_m_s": 1500.0, "center_frequency_hz": 5e6,
            "probe": {"kind": "linear", "n_elements": 1, "pitch_m": 0.3e-3, "element_width_m": 0.27e-3},
            "transmits": [{"kind": "plane_wave", "angle_rad": 0.0}]
        }))
        .unwrap();
        let n = 2048;
        let alpha0 = alpha / DB_CM_MHZ_PER_NP_M_HZ;
        let mut x = vec![0.0; n];
        for depth in depths_m {
            let d = 2.0 * depth;
            for (k, v) in x.iter_mut().enumerate() {
                for i in 1..400 {
                    let f = i as f64 * 25e3;
                    let a = (-(f - f_c).powi(2) / 2e12 - alpha0 * f * d).exp();
                    *v +=
                        a * (2.0 * std::f64::consts::PI * f * (k as f64 / 40e6 - d / 1500.0)).cos();
                }
            }
        }
        ChannelData {
            meta,
            n_samples: n,
            samples: x,
        }
    }

    #[test]
    fn the_line_s_standard_errors_are_the_closed_form_s() {
        // Equal weights, residuals ±0.1 or 0 about y = 3 + 2x at x = 0..6,
        // summing to zero with and without the weight x (so the fit is the
        // line itself and the residuals are these): the offset's
        // standard error is sqrt(Σr²/n/(n − 2)), the slope's
        // sqrt(Σr²/n/(n − 2)/(Σ(x − x̄)²/n)).
        let x: Vec<f64> = (0..6).map(f64::from).collect();
        let r = [0.1, -0.1, 0.0, 0.0, -0.1, 0.1];
        let y: Vec<f64> = x.iter().zip(r).map(|(x, r)| 3.0 + 2.0 * x + r).collect();
        let line = weighted_line(&x, &y, &[1.0; 6]).unwrap();
        let (n, rss): (f64, f64) = (6.0, 4.0 * 0.01);
        let sxx = x.iter().map(|x| (x - 2.5f64).powi(2)).sum::<f64>();
        assert!(
            (line.offset - (3.0 + 2.0 * 2.5)).abs() < 1e-12,
            "{}",
            line.offset
        );
        let offset_std = (rss / n / (n - 2.0)).sqrt();
        assert!((line.offset_std.unwrap() - offset_std).abs() < 1e-12);
        let slope_std = (rss / n / (n - 2.0) / (sxx / n)).sqrt();
        assert!((line.slope_std.unwrap() - slope_std).abs() < 1e-12);
        // Two points fit exactly and leave no spread to estimate.
        let two = weighted_line(&x[..2], &y[..2], &[1.0; 2]).unwrap();
        assert_eq!((two.offset_std, two.slope_std), (None, None));
    }

    #[test]
    fn attenuation_is_recovered_and_a_lower_centre_is_an_offset_not_a_slope() {
        let depths = [0.010, 0.015, 0.020, 0.025];
        let model = echoes(5e6, 0.0, &depths);
        let opts = SpectralShiftOptions::default();
        // 0.5 dB/(cm·MHz): the slope −2α₀σ² per metre of path.
        let s = spectral_shift(&echoes(5e6, 0.5, &depths), &model, 1500.0, 5e6, &opts).unwrap();
        assert_eq!(s.echoes.len(), 4);
        assert!((s.attenuation_db_cm_mhz - 0.5).abs() < 0.05, "{s:?}");
        // A centre 4% low: every echo 0.2 MHz lower, no attenuation.
        let s = spectral_shift(&echoes(4.8e6, 0.0, &depths), &model, 1500.0, 5e6, &opts).unwrap();
        assert!((s.offset_hz + 0.2e6).abs() < 0.01e6, "{s:?}");
        assert!(s.attenuation_db_cm_mhz.abs() < 0.02, "{s:?}");
        // Data of another shape are refused, naming both shapes.
        let mut other = model.clone();
        other.meta.transmits.push(other.meta.transmits[0].clone());
        other.samples.extend(model.samples.clone());
        let e = spectral_shift(&other, &model, 1500.0, 5e6, &opts).unwrap_err();
        assert!(
            e.to_string()
                .contains("2 transmits × 1 elements, the model 1 × 1"),
            "{e}"
        );
    }

    #[test]
    fn a_weighted_line_through_exact_points_has_their_slope_and_no_error() {
        let l = weighted_line(
            &[0.0, 1.0, 2.0, 3.0],
            &[1.0, 3.0, 5.0, 7.0],
            &[1.0, 2.0, 1.0, 3.0],
        )
        .unwrap();
        assert!((l.slope - 2.0).abs() < 1e-12);
        assert!(l.slope_std.unwrap() < 1e-12);
        assert!(weighted_line(&[1.0, 1.0], &[0.0, 1.0], &[1.0, 1.0]).is_none());
    }

    #[test]
    fn the_slope_error_of_equal_weights_is_the_textbook_one() {
        // y = x + (+1, −1, −1, +1), the residuals orthogonal to x: slope 1,
        // RSS 4, se² = (RSS/(n − 2)) / Σ(x − x̄)² = (4/2)/5.
        let l = weighted_line(&[0.0, 1.0, 2.0, 3.0], &[1.0, 0.0, 1.0, 4.0], &[1.0; 4]).unwrap();
        assert!((l.slope - 1.0).abs() < 1e-12);
        assert!((l.slope_std.unwrap() - (4.0f64 / 2.0 / 5.0).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn runs_are_maximal_and_close_at_the_end() {
        assert_eq!(
            runs_above(&[0.0, 2.0, 3.0, 0.0, 5.0], 1.0),
            vec![(1, 3), (4, 5)]
        );
    }
}
