//! The composed image-formation operator `B`: channel data → B-mode `[nz, nx]` in
//! `[0, 1]` (paper §"Differentiating through beamforming and post-processing"),
//! with one forward call and one VJP call.
//!
//! Chain: depth-gain compensation ([`crate::gain`], optional) → per-record
//! demodulation (IQ at `f_c` + zero-phase Butterworth low-pass, or the Hilbert
//! analytic signal; [`crate::demod`]) → delay-and-sum with coherent compounding
//! ([`crate::das`]) → envelope, `20·log10(·/max)`, clip to `[0, 1]`
//! ([`crate::post`]).
//!
//! The forward pass keeps what the VJP needs in a [`Workspace`] allocated once;
//! nothing is allocated per pixel or per sample.

use rayon::prelude::*;
use rustfft::num_complex::Complex64;
use serde::{Deserialize, Serialize};

use crate::channels::{ChannelData, ChannelMeta};
use crate::das::{linspace, CalibrationGrad, Das};
use crate::demod::{Analytic, IqDemod};
use crate::error::{Result, SignalError};
use crate::gain::gain_table;
use crate::post;

/// How complex samples are formed before delay-and-sum.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Demod {
    /// Baseband IQ: mix at `f_c` with absolute time, low-pass, rotate by
    /// `exp(+2πi f_c τ)` after the delay (PyMUST `rf2iq` + `dasmtx`). Required for
    /// band-pass-undersampled data (`f_s < 2 f_c`).
    #[default]
    Iq,
    /// Analytic signal of the RF (FFT Hilbert transform), delayed without rotation.
    Hilbert,
}

/// Imaging settings: CONTRACT §3 `[imaging]` plus demodulation choices.
/// Deserialises from the `[imaging]` table (missing keys take the defaults below).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ImagingSettings {
    /// Lateral extent `[x_min, x_max]`, m.
    pub x_range_m: [f64; 2],
    /// Depth extent `[z_min, z_max]`, m.
    pub z_range_m: [f64; 2],
    /// Pixel size, m: the grid is `linspace(min, max, round((max − min)/pixel) + 1)`
    /// on each axis.
    pub pixel_m: f64,
    /// Receive F-number; 0 = full aperture.
    pub f_number: f64,
    /// Dynamic range `D`, dB: grey = clamp((dB + D)/D, 0, 1).
    pub dynamic_range_db: f64,
    /// Sound speed the beamformer assumes, m/s; `None` = the channel data's.
    pub sound_speed_m_s: Option<f64>,
    /// Demodulation before delay-and-sum.
    pub demod: Demod,
    /// IQ low-pass cut-off as a fraction of `f_c`, *full* band: cut-off =
    /// fraction·f_c/2 (PyMUST `rf2iq`: Butterworth at bandwidth/2). `None` = the
    /// probe's `bandwidth_percent`/100 when the channel data carries it, else 1.
    pub iq_bandwidth_fraction: Option<f64>,
    /// Butterworth order of the IQ low-pass (PyMUST: 5).
    pub filter_order: usize,
    /// Depth-gain compensation applied before demodulation, dB/cm (0 = off).
    pub depth_gain_db_per_cm: f64,
}

impl Default for ImagingSettings {
    fn default() -> Self {
        ImagingSettings {
            x_range_m: [-0.02, 0.02],
            z_range_m: [0.001, 0.035],
            pixel_m: 0.1e-3,
            f_number: 1.5,
            dynamic_range_db: 60.0,
            sound_speed_m_s: None,
            demod: Demod::Iq,
            iq_bandwidth_fraction: None,
            filter_order: 5,
            depth_gain_db_per_cm: 0.0,
        }
    }
}

impl ImagingSettings {
    /// Settings on the given ranges and pixel size, other fields default.
    pub fn new(x_range_m: [f64; 2], z_range_m: [f64; 2], pixel_m: f64) -> Self {
        ImagingSettings {
            x_range_m,
            z_range_m,
            pixel_m,
            ..Default::default()
        }
    }

    /// The pixel grid `(x_m, z_m)`.
    pub fn grid(&self) -> Result<(Vec<f64>, Vec<f64>)> {
        let axis = |name: &str, r: [f64; 2]| -> Result<Vec<f64>> {
            if !(r[0].is_finite() && r[1].is_finite() && r[1] >= r[0]) {
                return Err(SignalError::Invalid(format!(
                    "imaging.{name} = {r:?} (need min ≤ max, finite)"
                )));
            }
            if !(self.pixel_m.is_finite() && self.pixel_m > 0.0) {
                return Err(SignalError::Invalid(format!(
                    "imaging.pixel_m = {}",
                    self.pixel_m
                )));
            }
            let n = ((r[1] - r[0]) / self.pixel_m).round() as usize + 1;
            if n > 100_000 {
                return Err(SignalError::Invalid(format!(
                    "imaging.{name}: {n} pixels is too many"
                )));
            }
            Ok(linspace(r[0], r[1], n))
        };
        Ok((
            axis("x_range_m", self.x_range_m)?,
            axis("z_range_m", self.z_range_m)?,
        ))
    }
}

/// A B-mode image `[nz, nx]` (row = depth), values in `[0, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Rows.
    pub nz: usize,
    /// Columns.
    pub nx: usize,
    /// Lateral positions of the columns, m.
    pub x_m: Vec<f64>,
    /// Depths of the rows, m.
    pub z_m: Vec<f64>,
    /// Pixel values, row-major.
    pub data: Vec<f64>,
}

impl Image {
    /// Write as float32 NPY `[nz, nx]`, atomically.
    pub fn write_npy(&self, path: impl AsRef<std::path::Path>) -> Result<()> {
        crate::io::write_bmode_npy(path, self.nz, self.nx, &self.data)
    }
    /// Write as 8-bit grey PNG, atomically.
    pub fn write_png(&self, path: impl AsRef<std::path::Path>) -> Result<()> {
        crate::io::write_bmode_png(path, self.nz, self.nx, &self.data)
    }
}

/// The composed operator `B`.
#[derive(Clone, Debug)]
pub struct BMode {
    /// The settings it was built from.
    pub settings: ImagingSettings,
    /// The delay-and-sum stage (grid, clock, aperture).
    pub das: Das,
    demod: Option<IqDemod>,
    analytic: Option<Analytic>,
    gain: Option<Vec<f64>>,
    n_elements: usize,
}

/// Buffers for [`BMode::forward`] and [`BMode::vjp`], allocated once.
#[derive(Clone, Debug)]
pub struct Workspace {
    cx: Vec<Complex64>,
    cx_bar: Vec<Complex64>,
    scratch: Vec<Complex64>,
    bf: Vec<Complex64>,
    bf_bar: Vec<Complex64>,
    env: Vec<f64>,
    env_bar: Vec<f64>,
    db: Vec<f64>,
    db_bar: Vec<f64>,
    argmax: usize,
    has_forward: bool,
}

impl Workspace {
    /// The beamformed complex image of the last forward call, `[nz, nx]`.
    pub fn beamformed(&self) -> &[Complex64] {
        &self.bf
    }
    /// The envelope of the last forward call.
    pub fn envelope(&self) -> &[f64] {
        &self.env
    }
    /// The unclipped `20 log10(E/max)` image of the last forward call, dB.
    pub fn db(&self) -> &[f64] {
        &self.db
    }
}

impl BMode {
    /// Build `B` for channel data described by `meta` with `n_samples` per record.
    pub fn new(settings: &ImagingSettings, meta: &ChannelMeta, n_samples: usize) -> Result<BMode> {
        let (x, z) = settings.grid()?;
        let c = settings.sound_speed_m_s.unwrap_or(meta.sound_speed_m_s);
        if !(settings.dynamic_range_db.is_finite() && settings.dynamic_range_db > 0.0) {
            return Err(SignalError::Invalid(format!(
                "imaging.dynamic_range_db = {} (must be > 0)",
                settings.dynamic_range_db
            )));
        }
        let rotate = settings.demod == Demod::Iq;
        let das = Das::new(meta, n_samples, x, z, c, settings.f_number, rotate)?;
        let fs = meta.sampling_frequency_hz;
        let fc = meta.center_frequency_hz;
        let (demod, analytic) = match settings.demod {
            Demod::Iq => {
                let frac = settings.iq_bandwidth_fraction.unwrap_or_else(|| {
                    meta.probe
                        .extra
                        .get("bandwidth_percent")
                        .and_then(|v| v.as_f64())
                        .map_or(1.0, |p| p / 100.0)
                });
                let cut = frac * fc / 2.0;
                let d = IqDemod::new(fc, fs, cut, settings.filter_order).ok_or_else(|| {
                    SignalError::Invalid(format!(
                        "IQ low-pass cut-off {cut} Hz must lie in (0, fs/2 = {} Hz)",
                        fs / 2.0
                    ))
                })?;
                (Some(d), None)
            }
            Demod::Hilbert => (None, Some(Analytic::new(n_samples))),
        };
        let gain = (settings.depth_gain_db_per_cm != 0.0).then(|| {
            let mut g = Vec::with_capacity(das.n_transmits() * n_samples);
            for t in 0..das.n_transmits() {
                g.extend(gain_table(
                    n_samples,
                    das.t0_s[t],
                    fs,
                    settings.depth_gain_db_per_cm,
                    c,
                ));
            }
            g
        });
        Ok(BMode {
            settings: settings.clone(),
            das,
            demod,
            analytic,
            gain,
            n_elements: meta.probe.n_elements,
        })
    }

    /// Image shape `(nz, nx)`.
    pub fn image_shape(&self) -> (usize, usize) {
        self.das.image_shape()
    }

    /// Allocate the workspace for this operator.
    pub fn workspace(&self) -> Workspace {
        let n = self.das.data_len();
        let (nz, nx) = self.image_shape();
        let m = nz * nx;
        let zero = Complex64::new(0.0, 0.0);
        Workspace {
            cx: vec![zero; n],
            cx_bar: vec![zero; n],
            scratch: vec![zero; n],
            bf: vec![zero; m],
            bf_bar: vec![zero; m],
            env: vec![0.0; m],
            env_bar: vec![0.0; m],
            db: vec![0.0; m],
            db_bar: vec![0.0; m],
            argmax: 0,
            has_forward: false,
        }
    }

    fn record_t0(&self, rec: usize) -> f64 {
        self.das.t0_s[rec / self.n_elements]
    }

    /// Forward: `I = B(P)`.
    ///
    /// # Panics
    /// If `ch` does not have the shape `B` was built for (a programming error:
    /// build `B` from the same metadata).
    pub fn forward(&self, ch: &ChannelData, ws: &mut Workspace) -> Image {
        assert_eq!(
            ch.samples.len(),
            self.das.data_len(),
            "channel data shape differs from the one B was built for"
        );
        let ns = self.das.n_samples;
        let fs = self.das.fs_hz;
        // 1–2. gain and demodulation, per record.
        let gain = self.gain.as_deref();
        ws.cx
            .par_chunks_mut(ns)
            .zip(ws.scratch.par_chunks_mut(ns))
            .enumerate()
            .for_each_init(
                || {
                    (
                        vec![0.0; ns],
                        vec![0.0; ns],
                        self.analytic
                            .as_ref()
                            .map(|a| vec![Complex64::new(0.0, 0.0); a.scratch_len()]),
                    )
                },
                |(re, im, fsc), (rec, (out, _))| {
                    let src = &ch.samples[rec * ns..(rec + 1) * ns];
                    let t = rec / self.n_elements;
                    match gain {
                        Some(g) => {
                            for (k, v) in re.iter_mut().enumerate() {
                                *v = src[k] * g[t * ns + k];
                            }
                        }
                        None => re.copy_from_slice(src),
                    }
                    if let Some(d) = &self.demod {
                        let t0 = self.record_t0(rec);
                        let w = 2.0 * core::f64::consts::PI * d.fc;
                        for (n, v) in re.iter_mut().enumerate() {
                            let (s, c) = (w * (t0 + n as f64 / fs)).sin_cos();
                            im[n] = -*v * s;
                            *v *= c;
                        }
                        d.lowpass.filtfilt_in_place(re);
                        d.lowpass.filtfilt_in_place(im);
                        for n in 0..ns {
                            out[n] = Complex64::new(2.0 * re[n], 2.0 * im[n]);
                        }
                    } else if let (Some(a), Some(sc)) = (&self.analytic, fsc.as_mut()) {
                        a.forward(re, out, sc);
                    }
                },
            );
        // 3. delay-and-sum.
        self.das.forward(&ws.cx, &mut ws.bf);
        // 4. envelope, log, clip.
        post::envelope(&ws.bf, &mut ws.env);
        ws.argmax = post::log_compress(&ws.env, &mut ws.db);
        let (nz, nx) = self.image_shape();
        let mut data = vec![0.0; nz * nx];
        post::clip_dynamic_range(&ws.db, self.settings.dynamic_range_db, &mut data);
        ws.has_forward = true;
        Image {
            nz,
            nx,
            x_m: self.das.x_m.clone(),
            z_m: self.das.z_m.clone(),
            data,
        }
    }

    /// VJP: `∂L/∂P = Bᵀ(∂L/∂I)` at the point of the last [`BMode::forward`] on `ws`.
    /// `d_image` is `[nz, nx]`; the result has the layout of `ChannelData::samples`.
    ///
    /// # Panics
    /// If no forward pass was run on `ws`, or `d_image` has the wrong length.
    pub fn vjp(&self, ws: &mut Workspace, d_image: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.das.data_len()];
        self.vjp_into(ws, d_image, &mut out);
        out
    }

    /// [`BMode::vjp`] writing into a caller-provided buffer (allocation-free).
    pub fn vjp_into(&self, ws: &mut Workspace, d_image: &[f64], d_channels: &mut [f64]) {
        assert!(
            ws.has_forward,
            "BMode::vjp needs a forward pass on this workspace first"
        );
        let (nz, nx) = self.image_shape();
        assert_eq!(d_image.len(), nz * nx, "d_image length");
        assert_eq!(d_channels.len(), self.das.data_len(), "d_channels length");
        post::clip_dynamic_range_vjp(
            &ws.db,
            self.settings.dynamic_range_db,
            d_image,
            &mut ws.db_bar,
        );
        post::log_compress_vjp(&ws.env, ws.argmax, &ws.db_bar, &mut ws.env_bar);
        post::envelope_vjp(&ws.bf, &ws.env_bar, &mut ws.bf_bar);
        self.das.vjp(&ws.bf_bar, &mut ws.cx_bar, &mut ws.scratch);
        let ns = self.das.n_samples;
        let gain = self.gain.as_deref();
        d_channels
            .par_chunks_mut(ns)
            .zip(ws.cx_bar.par_chunks_mut(ns))
            .enumerate()
            .for_each_init(
                || {
                    (
                        vec![0.0; ns],
                        vec![0.0; ns],
                        self.analytic
                            .as_ref()
                            .map(|a| vec![Complex64::new(0.0, 0.0); a.scratch_len()]),
                    )
                },
                |(re, im, fsc), (rec, (dst, cb))| {
                    if let Some(d) = &self.demod {
                        d.vjp(cb, self.record_t0(rec), re, im, dst);
                    } else if let (Some(a), Some(sc)) = (&self.analytic, fsc.as_mut()) {
                        a.vjp(cb, dst, sc);
                    }
                    if let Some(g) = gain {
                        let t = rec / self.n_elements;
                        for (k, v) in dst.iter_mut().enumerate() {
                            *v *= g[t * ns + k];
                        }
                    }
                },
            );
    }

    /// Gradient of `L` with respect to the beamforming sound speed and pitch at the
    /// last forward point, given `∂L/∂I` (uses the same chain down to the
    /// beamformed image, then [`Das::calibration_vjp`]).
    pub fn calibration_vjp(&self, ws: &mut Workspace, d_image: &[f64]) -> CalibrationGrad {
        assert!(
            ws.has_forward,
            "BMode::calibration_vjp needs a forward pass first"
        );
        post::clip_dynamic_range_vjp(
            &ws.db,
            self.settings.dynamic_range_db,
            d_image,
            &mut ws.db_bar,
        );
        post::log_compress_vjp(&ws.env, ws.argmax, &ws.db_bar, &mut ws.env_bar);
        post::envelope_vjp(&ws.bf, &ws.env_bar, &mut ws.bf_bar);
        self.das.calibration_vjp(&ws.cx, &ws.bf_bar)
    }
}
