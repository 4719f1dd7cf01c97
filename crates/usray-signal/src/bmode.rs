//! The composed image-formation operator `B`: channel data → B-mode `[nz, nx]` in
//! `[0, 1]` (paper §"Differentiating through beamforming and post-processing"),
//! with one forward call and one VJP call.
//!
//! Chain: depth-gain compensation ([`crate::gain`], optional) → per-record
//! demodulation (IQ at `f_c` + zero-phase Butterworth low-pass, or the Hilbert
//! analytic signal; [`crate::demod`]) → delay-and-sum with coherent compounding
//! of the transmits **within each frame** ([`crate::das`]) → envelope per frame,
//! **mean of the envelopes across frames** (incoherent compounding) →
//! `20·log10(·/max)`, clip to `[0, 1]` ([`crate::post`]).
//!
//! Frames are the acquisitions named by the transmits' `frame` keys
//! ([`ChannelMeta::frames`]): with `F` frames and `u_f` the coherent sum of
//! frame `f`, the envelope is `E_p = (1/F) Σ_f |u_{f,p}|`, whose VJP is
//! `ū_{f,p} = Ē_p/F · u_{f,p}/|u_{f,p}|`. Data without `frame` keys is one frame
//! (`E = |u|`, all transmits coherent). Coherent summation across frames would be
//! wrong for a moving object (the phases of successive frames differ).
//!
//! The derivative in the centre frequency with the channel data held,
//! [`BMode::center_frequency_vjp`], is in `bmode/center_frequency.rs`.
//!
//! The forward pass keeps what the VJP needs in a [`Workspace`] allocated once;
//! nothing is allocated per pixel or per sample. Shape mismatches between the
//! operator, the channel data, the workspace and the cotangents are reported as
//! [`SignalError::Invalid`], never as a panic.

use rayon::prelude::*;
use rustfft::num_complex::Complex64;

use crate::array::{ArrayGeometry, ArrayKind};
use crate::channels::{ChannelData, ChannelMeta};
use crate::das::{CalibrationGrad, Das};
use crate::demod::{Analytic, IqDemod};
use crate::error::{Result, SignalError};
use crate::gain::gain_table;
use crate::grid::{PolarGrid, ScanConversion};
pub use crate::imaging::{Demod, GridKind, ImagingSettings, MAX_PIXELS};
use crate::post;

mod center_frequency;

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
    /// The delay-and-sum stage (grid, clock, aperture, frames): one coherent
    /// image per frame, on the Cartesian pixels or on a polar sector.
    pub das: Das,
    /// The Cartesian axes of the output image, m (columns, rows).
    x_m: Vec<f64>,
    z_m: Vec<f64>,
    /// Polar sector → Cartesian pixels, when delay-and-sum runs on a sector.
    scan: Option<ScanConversion>,
    demod: Option<IqDemod>,
    /// Per transmit, the IQ mixing phases of its records ([`IqDemod::mixing`]).
    mixing: Vec<Vec<(f64, f64)>>,
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
    /// Coherent image of each frame, `[nz, nx, n_frames]`.
    bf: Vec<Complex64>,
    bf_bar: Vec<Complex64>,
    env: Vec<f64>,
    env_bar: Vec<f64>,
    /// Envelope on the polar sector and its cotangent (sector grids only).
    env_polar: Vec<f64>,
    env_polar_bar: Vec<f64>,
    db: Vec<f64>,
    db_bar: Vec<f64>,
    argmax: usize,
    has_forward: bool,
}

impl Workspace {
    /// The beamformed complex images of the last forward call, one per frame,
    /// pixel-major `[nz, nx, n_frames]` (`[nz, nx]` for single-frame data).
    pub fn beamformed(&self) -> &[Complex64] {
        &self.bf
    }
    /// The envelope of the last forward call (mean over frames), `[nz, nx]`.
    pub fn envelope(&self) -> &[f64] {
        &self.env
    }
    /// The unclipped `20 log10(E/max)` image of the last forward call, dB.
    pub fn db(&self) -> &[f64] {
        &self.db
    }
}

fn check_len(what: &str, expected: usize, given: usize) -> Result<()> {
    if expected == given {
        Ok(())
    } else {
        Err(SignalError::Invalid(format!(
            "{what} has {given} values, expected {expected}"
        )))
    }
}

impl BMode {
    /// Build `B` for channel data described by `meta` with `n_samples` per record.
    ///
    /// Transmits are grouped into frames by their `frame` keys
    /// ([`ChannelMeta::frames`]).
    pub fn new(settings: &ImagingSettings, meta: &ChannelMeta, n_samples: usize) -> Result<BMode> {
        let (x, z) = settings.grid()?;
        let c = settings.sound_speed_m_s.unwrap_or(meta.sound_speed_m_s);
        if !(settings.dynamic_range_db.is_finite() && settings.dynamic_range_db > 0.0) {
            return Err(SignalError::Invalid(format!(
                "imaging.dynamic_range_db = {} (must be > 0)",
                settings.dynamic_range_db
            )));
        }
        if let Some(m) = settings.reference_amplitude {
            if !(m.is_finite() && m > 0.0) {
                return Err(SignalError::Invalid(format!(
                    "imaging.reference_amplitude = {m} (must be > 0)"
                )));
            }
        }
        if meta.probe.n_elements == 0 || meta.transmits.is_empty() || n_samples < 2 {
            return Err(SignalError::Invalid(format!(
                "channel data shape [{} transmits, {} elements, {n_samples} samples]: need at least 1 transmit, 1 element and 2 samples",
                meta.transmits.len(),
                meta.probe.n_elements
            )));
        }
        meta.transmits
            .len()
            .checked_mul(meta.probe.n_elements)
            .and_then(|r| r.checked_mul(n_samples))
            .ok_or_else(|| SignalError::Invalid("channel data shape overflows".into()))?;
        let (fs, fc) = (meta.sampling_frequency_hz, meta.center_frequency_hz);
        for (name, v) in [
            ("sampling_frequency_hz", fs),
            ("center_frequency_hz", fc),
            ("probe.pitch_m", meta.probe.pitch_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(SignalError::Invalid(format!(
                    "channel metadata `{name}` = {v} (must be positive and finite)"
                )));
            }
        }
        let rotate = settings.demod == Demod::Iq;
        let array = ArrayGeometry::from_meta(&meta.probe).map_err(SignalError::Invalid)?;
        let sector = match settings.grid {
            GridKind::Auto => array.kind != ArrayKind::Linear,
            GridKind::Cartesian => false,
            GridKind::Sector => true,
        };
        let (das, scan) = if sector {
            let polar = PolarGrid::sector(
                &array,
                settings.x_range_m,
                settings.z_range_m,
                settings.pixel_m,
            )
            .map_err(|e| SignalError::Invalid(format!("imaging grid (sector): {e}")))?;
            let scan = ScanConversion::new(&polar, &x, &z);
            let das = Das::new_polar(meta, n_samples, polar, c, settings.f_number, rotate)?;
            (das, Some(scan))
        } else {
            let das = Das::new(
                meta,
                n_samples,
                x.clone(),
                z.clone(),
                c,
                settings.f_number,
                rotate,
            )?;
            (das, None)
        };
        if settings.demod == Demod::Iq && !(1..=20).contains(&settings.filter_order) {
            return Err(SignalError::Invalid(format!(
                "imaging.filter_order = {} (the IQ low-pass order must be 1–20)",
                settings.filter_order
            )));
        }
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
        let mixing = demod.as_ref().map_or_else(Vec::new, |d| {
            das.t0_s.iter().map(|&t0| d.mixing(t0, n_samples)).collect()
        });
        Ok(BMode {
            settings: settings.clone(),
            das,
            x_m: x,
            z_m: z,
            scan,
            demod,
            mixing,
            analytic,
            gain,
            n_elements: meta.probe.n_elements,
        })
    }

    /// Image shape `(nz, nx)`.
    pub fn image_shape(&self) -> (usize, usize) {
        (self.z_m.len(), self.x_m.len())
    }

    /// Number of delay-and-sum pixels (Cartesian, or polar on a sector).
    fn das_pixels(&self) -> usize {
        let (a, b) = self.das.image_shape();
        a * b
    }

    /// The polar sector delay-and-sum runs on, if the image is scan-converted.
    pub fn sector(&self) -> Option<&PolarGrid> {
        self.das.polar.as_ref()
    }

    /// Shape of the channel data this operator takes:
    /// `(n_transmits, n_elements, n_samples)`.
    pub fn channel_shape(&self) -> (usize, usize, usize) {
        (self.das.n_transmits(), self.n_elements, self.das.n_samples)
    }

    /// Number of frames (incoherently averaged acquisitions).
    pub fn n_frames(&self) -> usize {
        self.das.n_frames
    }

    /// The transmits (indices into the channel data) of each frame.
    pub fn frame_transmits(&self) -> Vec<Vec<usize>> {
        let mut out = vec![Vec::new(); self.das.n_frames];
        for (t, &f) in self.das.frame_of.iter().enumerate() {
            out[f].push(t);
        }
        out
    }

    /// Allocate the workspace for this operator.
    pub fn workspace(&self) -> Workspace {
        let n = self.das.data_len();
        let (nz, nx) = self.image_shape();
        let m = nz * nx;
        let zero = Complex64::new(0.0, 0.0);
        Workspace {
            cx: vec![zero; n],
            cx_bar: Vec::new(),
            scratch: Vec::new(),
            bf: vec![zero; self.das.out_len()],
            bf_bar: Vec::new(),
            env: vec![0.0; m],
            env_bar: Vec::new(),
            env_polar: vec![
                0.0;
                if self.scan.is_some() {
                    self.das_pixels()
                } else {
                    0
                }
            ],
            env_polar_bar: Vec::new(),
            db: vec![0.0; m],
            db_bar: Vec::new(),
            argmax: 0,
            has_forward: false,
        }
    }

    /// Allocates the VJP's buffers of `ws` on its first VJP: a forward-only user
    /// (`usray beamform`) never pays for them.
    fn vjp_buffers(&self, ws: &mut Workspace) {
        let (nz, nx) = self.image_shape();
        let (n, m) = (self.das.data_len(), nz * nx);
        let zero = Complex64::new(0.0, 0.0);
        ws.cx_bar.resize(n, zero);
        ws.scratch.resize(n, zero);
        ws.bf_bar.resize(self.das.out_len(), zero);
        ws.env_bar.resize(m, 0.0);
        ws.env_polar_bar.resize(ws.env_polar.len(), 0.0);
        ws.db_bar.resize(m, 0.0);
    }

    /// `Err` unless `ws` was made by [`BMode::workspace`] of an operator of this shape.
    fn check_workspace(&self, ws: &Workspace) -> Result<()> {
        let (nz, nx) = self.image_shape();
        let (n, m, f) = (self.das.data_len(), nz * nx, self.das.n_frames);
        let polar = if self.scan.is_some() {
            self.das_pixels()
        } else {
            0
        };
        // The VJP's buffers are empty until its first call.
        let vjp_ok = |len: usize, want: usize| len == 0 || len == want;
        let ok = ws.cx.len() == n
            && vjp_ok(ws.cx_bar.len(), n)
            && vjp_ok(ws.scratch.len(), n)
            && ws.bf.len() == self.das.out_len()
            && vjp_ok(ws.bf_bar.len(), self.das.out_len())
            && ws.env_polar.len() == polar
            && vjp_ok(ws.env_polar_bar.len(), polar)
            && [&ws.env, &ws.db].iter().all(|v| v.len() == m)
            && [&ws.env_bar, &ws.db_bar].iter().all(|v| vjp_ok(v.len(), m));
        if ok {
            Ok(())
        } else {
            Err(SignalError::Invalid(format!(
                "workspace does not belong to this operator (it holds {} channel samples and {} frame pixels; expected {n} and {f} × {m}): make it with BMode::workspace",
                ws.cx.len(),
                ws.bf.len()
            )))
        }
    }

    /// Forward: `I = B(P)`.
    ///
    /// # Errors
    /// [`SignalError::Invalid`] if `ch` does not have the shape `B` was built for
    /// (the message gives both shapes) or `ws` was made for another operator.
    pub fn forward(&self, ch: &ChannelData, ws: &mut Workspace) -> Result<Image> {
        let want = self.channel_shape();
        let got = ch.shape();
        if got != want || ch.samples.len() != self.das.data_len() {
            return Err(SignalError::Invalid(format!(
                "channel data shape [{}, {}, {}] ({} samples) differs from the shape this B-mode operator was built for: expected [{}, {}, {}] ({} samples) [n_transmits, n_elements, n_samples]",
                got.0,
                got.1,
                got.2,
                ch.samples.len(),
                want.0,
                want.1,
                want.2,
                self.das.data_len()
            )));
        }
        self.check_workspace(ws)?;
        ws.has_forward = false;
        let ns = self.das.n_samples;
        let ne = self.n_elements;
        // 1–2. gain and demodulation, per record.
        let gain = self.gain.as_deref();
        ws.cx.par_chunks_mut(ns).enumerate().for_each_init(
            || {
                (
                    vec![0.0; if gain.is_some() { ns } else { 0 }],
                    self.analytic
                        .as_ref()
                        .map(|a| vec![Complex64::new(0.0, 0.0); a.scratch_len()]),
                )
            },
            |(gained, fsc), (rec, out)| {
                let t = rec / ne;
                let mut src = &ch.samples[rec * ns..(rec + 1) * ns];
                if let Some(g) = gain {
                    for (k, v) in gained.iter_mut().enumerate() {
                        *v = src[k] * g[t * ns + k];
                    }
                    src = gained;
                }
                if let Some(d) = &self.demod {
                    d.forward_mixed(src, &self.mixing[t], out);
                } else if let (Some(a), Some(sc)) = (&self.analytic, fsc.as_mut()) {
                    a.forward(src, out, sc);
                }
            },
        );
        // 3. delay-and-sum, coherent within each frame.
        let (nz, nx) = self.image_shape();
        let npix = nz * nx;
        self.das.forward(&ws.cx, &mut ws.bf);
        // 4. envelope per frame, mean over frames (scan-converted from a
        //    sector), log, clip.
        match &self.scan {
            None => self.mean_envelope(&ws.bf, &mut ws.env),
            Some(sc) => {
                self.mean_envelope(&ws.bf, &mut ws.env_polar);
                sc.forward(&ws.env_polar, &mut ws.env);
            }
        }
        match self.settings.reference_amplitude {
            None => ws.argmax = post::log_compress(&ws.env, &mut ws.db),
            Some(m) => post::log_compress_against(&ws.env, m, &mut ws.db),
        }
        let mut data = vec![0.0; npix];
        post::clip_dynamic_range(&ws.db, self.settings.dynamic_range_db, &mut data);
        ws.has_forward = true;
        Ok(Image {
            nz,
            nx,
            x_m: self.x_m.clone(),
            z_m: self.z_m.clone(),
            data,
        })
    }

    /// `env = (1/F) Σ_f |bf_f|` (for one frame exactly `|bf|`).
    fn mean_envelope(&self, bf: &[Complex64], env: &mut [f64]) {
        let nf = self.das.n_frames;
        if nf == 1 {
            post::envelope(bf, env);
        } else {
            let inv = 1.0 / nf as f64;
            env.par_iter_mut()
                .zip(bf.par_chunks(nf))
                .for_each(|(e, u)| *e = u.iter().map(|v| v.norm()).sum::<f64>() * inv);
        }
    }

    /// Pull `d_image` back to `ws.bf_bar` (`[nz, nx, n_frames]`), checking lengths.
    fn image_to_bf_bar(&self, ws: &mut Workspace, d_image: &[f64], who: &str) -> Result<()> {
        if !ws.has_forward {
            return Err(SignalError::Invalid(format!(
                "{who} needs a successful BMode::forward on this workspace first"
            )));
        }
        self.check_workspace(ws)?;
        self.vjp_buffers(ws);
        let (nz, nx) = self.image_shape();
        if d_image.len() != nz * nx {
            return Err(SignalError::Invalid(format!(
                "{who}: d_image has {} values, expected nz × nx = {nz} × {nx} = {}",
                d_image.len(),
                nz * nx
            )));
        }
        post::clip_dynamic_range_vjp(
            &ws.db,
            self.settings.dynamic_range_db,
            d_image,
            &mut ws.db_bar,
        );
        match self.settings.reference_amplitude {
            None => post::log_compress_vjp(&ws.env, ws.argmax, &ws.db_bar, &mut ws.env_bar),
            Some(_) => {
                post::log_compress_against_vjp(&ws.env, &ws.db_bar, &mut ws.env_bar);
            }
        }
        let env_bar: &[f64] = match &self.scan {
            None => &ws.env_bar,
            Some(sc) => {
                sc.vjp(&ws.env_bar, &mut ws.env_polar_bar);
                &ws.env_polar_bar
            }
        };
        let nf = self.das.n_frames;
        if nf == 1 {
            post::envelope_vjp(&ws.bf, env_bar, &mut ws.bf_bar);
        } else {
            // E = (1/F) Σ_f |u_f|  ⇒  ū_f = (Ē/F)·u_f/|u_f|.
            let inv = 1.0 / nf as f64;
            ws.bf_bar
                .par_chunks_mut(nf)
                .zip(ws.bf.par_chunks(nf))
                .zip(env_bar)
                .for_each(|((ub, u), &g)| {
                    for (b, v) in ub.iter_mut().zip(u) {
                        let n = v.norm();
                        *b = if n > 0.0 {
                            *v * (g * inv / n)
                        } else {
                            Complex64::new(0.0, 0.0)
                        };
                    }
                });
        }
        Ok(())
    }

    /// VJP: `∂L/∂P = Bᵀ(∂L/∂I)` at the point of the last [`BMode::forward`] on `ws`.
    /// `d_image` is `[nz, nx]`; the result has the layout of `ChannelData::samples`.
    ///
    /// # Errors
    /// [`SignalError::Invalid`] if no successful forward pass was run on `ws`, or
    /// `d_image` does not have `nz · nx` values.
    pub fn vjp(&self, ws: &mut Workspace, d_image: &[f64]) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.das.data_len()];
        self.vjp_into(ws, d_image, &mut out)?;
        Ok(out)
    }

    /// [`BMode::vjp`] writing into a caller-provided buffer (allocation-free apart
    /// from per-thread record buffers); `d_channels` must have the length of
    /// `ChannelData::samples`.
    pub fn vjp_into(
        &self,
        ws: &mut Workspace,
        d_image: &[f64],
        d_channels: &mut [f64],
    ) -> Result<()> {
        check_len(
            "BMode::vjp_into: d_channels",
            self.das.data_len(),
            d_channels.len(),
        )?;
        self.image_to_bf_bar(ws, d_image, "BMode::vjp")?;
        let ns = self.das.n_samples;
        let ne = self.n_elements;
        self.das.vjp(&ws.bf_bar, &mut ws.cx_bar, &mut ws.scratch);
        let gain = self.gain.as_deref();
        d_channels
            .par_chunks_mut(ns)
            .zip(ws.cx_bar.par_chunks_mut(ns))
            .enumerate()
            .for_each_init(
                || {
                    self.analytic
                        .as_ref()
                        .map(|a| vec![Complex64::new(0.0, 0.0); a.scratch_len()])
                },
                |fsc, (rec, (dst, cb))| {
                    let t = rec / ne;
                    if let Some(d) = &self.demod {
                        d.vjp_mixed(cb, &self.mixing[t], dst);
                    } else if let (Some(a), Some(sc)) = (&self.analytic, fsc.as_mut()) {
                        a.vjp(cb, dst, sc);
                    }
                    if let Some(g) = gain {
                        for (k, v) in dst.iter_mut().enumerate() {
                            *v *= g[t * ns + k];
                        }
                    }
                },
            );
        Ok(())
    }

    /// Gradient of `L` with respect to the beamforming sound speed and pitch at the
    /// last forward point, given `∂L/∂I` (uses the same chain down to the
    /// beamformed images, then [`Das::calibration_vjp`]). On a sector the polar
    /// pixels are held where they are: the derivative does not include the
    /// sector's own motion with the pitch (a convex array's arc centre moves).
    ///
    /// # Errors
    /// As [`BMode::vjp`].
    pub fn calibration_vjp(&self, ws: &mut Workspace, d_image: &[f64]) -> Result<CalibrationGrad> {
        self.image_to_bf_bar(ws, d_image, "BMode::calibration_vjp")?;
        Ok(self.das.calibration_vjp(&ws.cx, &ws.bf_bar))
    }
}
