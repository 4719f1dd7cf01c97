//! Delay-and-sum (paper eq. `das`) and its adjoint, the back-projection (paper eq.
//! `das_adjoint`), on RF or complex (IQ / analytic) channel data, for any array of
//! [`crate::array`] and any transmit of [`crate::transmit`].
//!
//! For pixel `p = (x, z)`, transmit `t` and element `e` centred at `x_e`
//! ([`ArrayGeometry::element`]), the two-way time (s) on the CONTRACT §1 clock is
//!
//! `τ = t_t(p) + ‖p − x_e‖/c`
//!
//! with `t_t` the transmit's arrival time ([`TransmitWave::arrival_time_s`]); for
//! a plane wave on a flat array `τ = (x sin θ + z cos θ)/c + √((x − x_e)² + z²)/c`
//! (Montaldo et al., "Coherent plane-wave compounding for very fast
//! ultrasonography", IEEE TUFFC 56(3), 2009, with the transmit origin at the
//! array centre). The sample position is `s = (τ − t0_t)·f_s` with `t0_t` the time of
//! sample 0 of that transmit; the record is read by linear interpolation
//! `P(s) = (1 − w)·P[i] + w·P[i+1]`, `i = ⌊s⌋`, `w = s − i`; positions with `s < 0`
//! or `i + 1 ≥ n_samples` contribute 0. On baseband IQ data the interpolated value is
//! multiplied by `exp(+2πi f_c τ)` to restore the carrier phase (Szabo, "Diagnostic
//! Ultrasound Imaging: Inside Out", quadrature sampling; as PyMUST `dasmtx`). Receive apodisation by F-number
//! `F`: element `e` contributes with weight 1 if `p` lies in the cone of half-angle
//! `atan(1/(2F))` about the element's normal (for a flat array `|x − x_e| ≤
//! z/(2F)`; PyMUST `dasmtx`), else 0 (rectangular; `F = 0` = full aperture). The
//! pixels are the Cartesian grid `x_m` × `z_m` or a polar sector
//! ([`crate::grid::PolarGrid`], [`Das::new_polar`]). Transmits are summed coherently within
//! each frame (the transmits' `frame` keys, [`ChannelMeta::frames`]); the output
//! holds one coherent image per frame, pixel-major `[nz, nx, n_frames]` (for
//! single-frame data simply `[nz, nx]`).
//!
//! Speed: for a flat array on a Cartesian grid uniform in `x` whose step divides
//! the pitch, the receive distance and phase are tabulated once per distinct `x − x_e`
//! per row (same formula, same values up to rounding). The calibration gradients
//! use the same delays and phases as the forward pass (the phase of a delay as the
//! product of its transmit and receive phases).
//!
//! Parallelism: the forward pass is split over image rows, each pixel summing in a
//! fixed order; the VJP is split over elements, each sample accumulating pixels in
//! a fixed order; the calibration gradients reduce per-row partial sums in row order.
//! Results are therefore bit-identical for any number of threads.

mod lattice;
mod sample;

use rayon::prelude::*;
use rustfft::num_complex::Complex64;

use lattice::RxTable;
use sample::locate;
pub use sample::{linspace, Sample};

use crate::array::{ArrayGeometry, ArrayKind, Element};
use crate::channels::ChannelMeta;
use crate::error::{Result, SignalError};
use crate::grid::PolarGrid;
use crate::transmit::TransmitWave;

const TAU: f64 = 2.0 * core::f64::consts::PI;

/// A delay-and-sum configuration: pixel grid, array, clock and aperture.
#[derive(Clone, Debug, PartialEq)]
pub struct Das {
    /// Lateral pixel positions, m (image columns); empty on a polar grid.
    pub x_m: Vec<f64>,
    /// Depth pixel positions, m (image rows); empty on a polar grid.
    pub z_m: Vec<f64>,
    /// The polar pixel grid (rows = radii, columns = angles) when the image is
    /// formed on a sector rather than on `x_m` × `z_m`.
    pub polar: Option<PolarGrid>,
    /// Array kind (element positions: [`crate::array`]).
    pub kind: ArrayKind,
    /// Radius of curvature of a convex array, m (∞ for flat arrays).
    pub radius_m: f64,
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
    /// Per transmit: the wave and its time model ([`crate::transmit`]).
    pub waves: Vec<TransmitWave<f64>>,
    /// Per transmit: time of sample 0, s (CONTRACT §1 clock).
    pub t0_s: Vec<f64>,
    /// Samples per record.
    pub n_samples: usize,
    /// Receive F-number; 0 = full aperture.
    pub f_number: f64,
    /// Multiply complex samples by `exp(+2πi f_c τ)` (true for baseband IQ, false for
    /// RF and analytic signals).
    pub rotate: bool,
    /// Per transmit: index of its frame in `0..n_frames` ([`ChannelMeta::frames`]).
    pub frame_of: Vec<usize>,
    /// Number of frames (coherent images in the output).
    pub n_frames: usize,
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

/// One image row's working buffers for [`Das::forward`]: per transmit and
/// pixel, the transmit delay from sample 0 (`ttx`), the transmit phase (`rtx`) and
/// the running element sum (`acc`), `[n_transmits, nx]`; per pixel, one element's
/// receive delay, phase and aperture flag when no lattice table applies.
struct RowScratch<S> {
    ttx: Vec<f64>,
    rtx: Vec<Complex64>,
    acc: Vec<S>,
    trx: Vec<f64>,
    rrx: Vec<Complex64>,
    ok: Vec<bool>,
}

impl<S: Sample> RowScratch<S> {
    fn new(nt: usize, nx: usize) -> Self {
        RowScratch {
            ttx: vec![0.0; nt * nx],
            rtx: vec![Complex64::new(1.0, 0.0); nt * nx],
            acc: vec![S::zero(); nt * nx],
            trx: vec![0.0; nx],
            rrx: vec![Complex64::new(1.0, 0.0); nx],
            ok: vec![false; nx],
        }
    }
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
        if x_m.is_empty() || z_m.is_empty() {
            return Err(SignalError::Invalid("empty pixel grid".into()));
        }
        Das::build(meta, n_samples, (x_m, z_m, None), c, f_number, rotate)
    }

    /// A beamformer like [`Das::new`] on the polar grid `grid` (sector imaging,
    /// [`crate::grid`]): the output's rows are `grid.r_m`, its columns
    /// `grid.theta_rad`.
    pub fn new_polar(
        meta: &ChannelMeta,
        n_samples: usize,
        grid: PolarGrid,
        c: f64,
        f_number: f64,
        rotate: bool,
    ) -> Result<Das> {
        Das::build(
            meta,
            n_samples,
            (Vec::new(), Vec::new(), Some(grid)),
            c,
            f_number,
            rotate,
        )
    }

    fn build(
        meta: &ChannelMeta,
        n_samples: usize,
        (x_m, z_m, polar): (Vec<f64>, Vec<f64>, Option<PolarGrid>),
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
        if meta.probe.n_elements == 0 {
            return Err(SignalError::Invalid("probe with 0 elements".into()));
        }
        let array = ArrayGeometry::from_meta(&meta.probe).map_err(SignalError::Invalid)?;
        let waves = meta
            .transmits
            .iter()
            .enumerate()
            .map(|(i, t)| TransmitWave::from_meta(i, t))
            .collect::<std::result::Result<Vec<_>, String>>()
            .map_err(SignalError::Invalid)?;
        let nt = meta.transmits.len();
        let groups = meta.frames().map_err(SignalError::Invalid)?;
        let mut frame_of = vec![0; nt];
        for (f, g) in groups.iter().enumerate() {
            for &t in g {
                frame_of[t] = f;
            }
        }
        Ok(Das {
            x_m,
            z_m,
            polar,
            kind: array.kind,
            radius_m: array.radius_m,
            n_elements: meta.probe.n_elements,
            pitch_m: meta.probe.pitch_m,
            sound_speed_m_s: c,
            fs_hz: meta.sampling_frequency_hz,
            fc_hz: meta.center_frequency_hz,
            waves,
            t0_s: (0..nt).map(|i| meta.t0_for(i)).collect(),
            n_samples,
            f_number,
            rotate,
            frame_of,
            n_frames: groups.len(),
        })
    }

    /// Number of transmits.
    pub fn n_transmits(&self) -> usize {
        self.waves.len()
    }
    /// Image size `(nz, nx)`.
    pub fn image_shape(&self) -> (usize, usize) {
        match &self.polar {
            Some(g) => g.shape(),
            None => (self.z_m.len(), self.x_m.len()),
        }
    }
    /// Output length `nz · nx · n_frames`.
    pub fn out_len(&self) -> usize {
        let (nz, nx) = self.image_shape();
        nz * nx * self.n_frames
    }
    /// Number of channel samples `n_transmits · n_elements · n_samples`.
    pub fn data_len(&self) -> usize {
        self.n_transmits() * self.n_elements * self.n_samples
    }
    /// Element centre `x_e` of a flat array, m.
    #[inline]
    pub fn element_x(&self, e: usize) -> f64 {
        (e as f64 - (self.n_elements as f64 - 1.0) / 2.0) * self.pitch_m
    }

    /// The array this beamformer assumes (its current `kind`, `pitch_m`,
    /// `radius_m`; the element width plays no part in delay-and-sum and is
    /// reported as the pitch).
    pub fn array<T: usray_ad::Real>(&self, pitch_m: T) -> ArrayGeometry<T> {
        ArrayGeometry {
            kind: self.kind,
            n_elements: self.n_elements,
            pitch_m,
            element_width_m: pitch_m,
            radius_m: T::from_f64(self.radius_m),
        }
    }

    /// Probe-frame position `(x, z)` of pixel (row `iz`, column `ix`), m.
    #[inline(always)]
    pub fn pixel(&self, iz: usize, ix: usize) -> [f64; 2] {
        match &self.polar {
            Some(g) => g.pixel(iz, ix),
            None => [self.x_m[ix], self.z_m[iz]],
        }
    }

    /// Per transmit, `(sin θ, cos θ)` of a plane wave (unused for other waves).
    fn plane_trig(&self) -> Vec<(f64, f64)> {
        self.waves
            .iter()
            .map(|w| match w {
                TransmitWave::PlaneWave { angle_rad } => angle_rad.sin_cos(),
                _ => (0.0, 0.0),
            })
            .collect()
    }

    /// Arrival time of transmit `t` at `p`, s: [`TransmitWave::arrival_time_s`],
    /// with a plane wave's sine and cosine taken from `trig` rather than
    /// recomputed per pixel (the same expression, so the same bits).
    #[inline(always)]
    fn tx_time(&self, t: usize, p: [f64; 2], trig: &[(f64, f64)]) -> f64 {
        match &self.waves[t] {
            TransmitWave::PlaneWave { .. } => {
                (p[0] * trig[t].0 + p[1] * trig[t].1) / self.sound_speed_m_s
            }
            w => w.arrival_time_s(p, self.sound_speed_m_s),
        }
    }

    /// Receive time and phase for (pixel `iz, ix`, element `e`), or `None` outside
    /// the aperture.
    #[inline(always)]
    fn rx(
        &self,
        table: Option<&RxTable>,
        els: &[Element<f64>],
        iz: usize,
        ix: usize,
        e: usize,
    ) -> Option<(f64, Complex64)> {
        if let Some(t) = table {
            let idx = iz * t.len + ix + t.k * (self.n_elements - 1 - e);
            return t.ok[idx].then(|| (t.trx[idx], t.rrx[idx]));
        }
        let p = self.pixel(iz, ix);
        let el = &els[e];
        let (dx, dz) = (p[0] - el.centre_m[0], p[1] - el.centre_m[1]);
        if !self.in_aperture(dx, dz, el.normal) {
            return None;
        }
        let trx = (dx * dx + dz * dz).sqrt() / self.sound_speed_m_s;
        let rrx = if self.rotate {
            let (s, co) = (TAU * self.fc_hz * trx).sin_cos();
            Complex64::new(co, s)
        } else {
            Complex64::new(1.0, 0.0)
        };
        Some((trx, rrx))
    }

    /// Whether the pixel at `(dx, dz)` from an element with normal `n` lies in
    /// its receive cone: the angle `α` between `(dx, dz)` and `n` has
    /// `tan α ≤ 1/(2F)`, i.e. `2F·|(dx, dz) × n| ≤ (dx, dz)·n` (PyMUST `dasmtx`:
    /// `|x − x_e| ≤ z/(2F)` for a linear array, `|asin(dx/r) − θ_e| ≤
    /// atan(1/(2F))` for a convex one). For `n = (0, 1)` this is exactly the
    /// linear rule `2F|dx| ≤ dz`.
    #[inline]
    fn in_aperture(&self, dx: f64, dz: f64, n: [f64; 2]) -> bool {
        let cross = dx * n[1] - dz * n[0];
        let dot = dx * n[0] + dz * n[1];
        self.f_number <= 0.0 || 2.0 * self.f_number * cross.abs() <= dot
    }

    fn check(&self, data_len: usize, out_len: usize) {
        assert!(
            self.frame_of.len() == self.n_transmits()
                && self.frame_of.iter().all(|&f| f < self.n_frames),
            "frame_of must give each of the {} transmits a frame in 0..{}",
            self.n_transmits(),
            self.n_frames
        );
        assert_eq!(data_len, self.data_len(), "channel buffer length");
        assert_eq!(out_len, self.out_len(), "image buffer length");
    }

    /// Forward: `out[(iz·nx + ix)·F + f] = Σ_{θ ∈ frame f} Σ_e P_θ,e(s)·rot` (paper
    /// eq. `das`). `data` is `[n_transmits, n_elements, n_samples]`, `out` is
    /// `[nz, nx, n_frames]`.
    ///
    /// # Panics
    /// If the buffer lengths disagree with the configuration (a programming error).
    pub fn forward<S: Sample>(&self, data: &[S], out: &mut [S]) {
        self.check(data.len(), out.len());
        let nx = self.image_shape().1;
        let nt = self.n_transmits();
        let (fs, ns, ne) = (self.fs_hz, self.n_samples, self.n_elements);
        let w = TAU * self.fc_hz;
        let trig = self.plane_trig();
        let els = self.array(self.pitch_m).elements();
        let table = self.rx_table();
        let table = table.as_ref();
        let nf = self.n_frames;
        out.par_chunks_mut(nx * nf).enumerate().for_each_init(
            || RowScratch::<S>::new(nt, nx),
            |sc, (iz, row)| {
                let RowScratch {
                    ttx,
                    rtx,
                    acc,
                    trx: trx_buf,
                    rrx: rrx_buf,
                    ok: ok_buf,
                } = sc;
                // Step 1: each transmit's delay (from sample 0) and phase along the row.
                for t in 0..nt {
                    for ix in 0..nx {
                        let tt = self.tx_time(t, self.pixel(iz, ix), &trig);
                        ttx[t * nx + ix] = tt - self.t0_s[t];
                        if self.rotate {
                            let (s, co) = (w * tt).sin_cos();
                            rtx[t * nx + ix] = Complex64::new(co, s);
                        }
                    }
                }
                acc.fill(S::zero());
                // Step 2: per element, its receive delays and phases along the row
                // (a slice of the lattice table, or computed), then each transmit's
                // record read along the row: one record at a time stays in cache,
                // and every (pixel, transmit) still sums its elements in order.
                for e in 0..ne {
                    let (trx, rrx, ok): (&[f64], &[Complex64], &[bool]) = match table {
                        Some(tb) => {
                            let o = iz * tb.len + tb.k * (ne - 1 - e);
                            (&tb.trx[o..o + nx], &tb.rrx[o..o + nx], &tb.ok[o..o + nx])
                        }
                        None => {
                            for ix in 0..nx {
                                let r = self.rx(None, &els, iz, ix, e);
                                ok_buf[ix] = r.is_some();
                                if let Some((t, p)) = r {
                                    trx_buf[ix] = t;
                                    rrx_buf[ix] = p;
                                }
                            }
                            (trx_buf, rrx_buf, ok_buf)
                        }
                    };
                    for t in 0..nt {
                        let rec = &data[(t * ne + e) * ns..(t * ne + e + 1) * ns];
                        let tt = &ttx[t * nx..(t + 1) * nx];
                        let acc = &mut acc[t * nx..(t + 1) * nx];
                        for ix in 0..nx {
                            if !ok[ix] {
                                continue;
                            }
                            let s = (tt[ix] + trx[ix]) * fs;
                            let Some((i, fw)) = locate(s, ns) else {
                                continue;
                            };
                            let [a, b] = [rec[i], rec[i + 1]];
                            acc[ix] += (a.scale(1.0 - fw) + b.scale(fw)).rot(rrx[ix]);
                        }
                    }
                }
                // Step 3: each transmit's sum, rotated by its transmit phase, into
                // its frame, transmits in order.
                for (ix, px) in row.chunks_exact_mut(nf).enumerate() {
                    px.fill(S::zero());
                    for t in 0..nt {
                        px[self.frame_of[t]] += acc[t * nx + ix].rot(rtx[t * nx + ix]);
                    }
                }
            },
        );
    }

    /// VJP (paper eq. `das_adjoint`): back-projects the image cotangent `out_bar`
    /// (`[nz, nx, n_frames]`) into `data_bar` (`[n_transmits, n_elements, n_samples]`,
    /// overwritten) with the same interpolation weights (and the conjugate
    /// rotation). `scratch` must have `data_len()` entries (element-major staging).
    ///
    /// # Panics
    /// If the buffer lengths disagree with the configuration.
    pub fn vjp<S: Sample>(&self, out_bar: &[S], data_bar: &mut [S], scratch: &mut [S]) {
        self.check(data_bar.len(), out_bar.len());
        assert_eq!(scratch.len(), self.data_len(), "scratch length");
        let (nz, nx) = self.image_shape();
        let nt = self.n_transmits();
        let (fs, ns, ne) = (self.fs_hz, self.n_samples, self.n_elements);
        let w = TAU * self.fc_hz;
        let trig = self.plane_trig();
        let els = self.array(self.pitch_m).elements();
        // Transmit delays and rotations per (transmit, pixel), once per call, so the
        // per-element loop pays one sqrt and one sincos per (pixel, element) like
        // the forward pass.
        let npix = nx * nz;
        let mut txt = vec![0.0; nt * npix];
        let mut txr = vec![Complex64::new(1.0, 0.0); if self.rotate { nt * npix } else { 0 }];
        txt.par_chunks_mut(npix).enumerate().for_each(|(t, tab)| {
            for (p, v) in tab.iter_mut().enumerate() {
                *v = self.tx_time(t, self.pixel(p / nx, p % nx), &trig);
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
        let table = self.rx_table();
        let table = table.as_ref();
        // scratch layout [e][t][ns]: one contiguous block per element.
        let nf = self.n_frames;
        scratch.par_chunks_mut(nt * ns).enumerate().for_each_init(
            || vec![S::zero(); nf],
            |grx, (e, blk)| {
                blk.fill(S::zero());
                for iz in 0..nz {
                    for ix in 0..nx {
                        let Some((trx, rrx)) = self.rx(table, &els, iz, ix, e) else {
                            continue;
                        };
                        let p = iz * nx + ix;
                        for (f, g) in grx.iter_mut().enumerate() {
                            let ob = out_bar[p * nf + f];
                            *g = if self.rotate { ob.rot_conj(rrx) } else { ob };
                        }
                        for t in 0..nt {
                            let grx = grx[self.frame_of[t]];
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
            },
        );
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
    /// `∂τ/∂c = −τ/c` (every transmit model and the receive path are a length
    /// over `c`), `∂τ/∂pitch = −(p − x_e)·(∂x_e/∂pitch)/(c·r)` with the element
    /// centre's derivative `∂x_e/∂pitch` taken by dual numbers through
    /// [`ArrayGeometry::element`] (for a flat array `(e − (N−1)/2, 0)`; the
    /// transmit models do not depend on the pitch: plane waves pass the origin,
    /// virtual sources and foci are given as points). The F-number aperture mask
    /// is held fixed (a discontinuity without a derivative).
    ///
    /// # Panics
    /// If the buffer lengths disagree with the configuration.
    pub fn calibration_vjp<S: Sample>(&self, data: &[S], out_bar: &[S]) -> CalibrationGrad {
        self.check(data.len(), out_bar.len());
        let (nz, nx) = self.image_shape();
        let nt = self.n_transmits();
        let (c, fs, ns, ne) = (
            self.sound_speed_m_s,
            self.fs_hz,
            self.n_samples,
            self.n_elements,
        );
        let w = TAU * self.fc_hz;
        let trig = self.plane_trig();
        let els = self.array(self.pitch_m).elements();
        let del: Vec<[f64; 2]> = self
            .array(usray_ad::Dual::<1>::variable(self.pitch_m, 0))
            .elements()
            .iter()
            .map(|el| [el.centre_m[0].eps[0], el.centre_m[1].eps[0]])
            .collect();
        // The delays and phases of the forward pass (receive lattice when it
        // applies, transmit part once per pixel), so that this differentiates the
        // forward pass's own sample positions and rotations; the rotation
        // `exp(iωτ)` is the product of the transmit and receive phases, one
        // sincos per (pixel, transmit) and per receive distance instead of one
        // per (pixel, element, transmit).
        let table = self.rx_table();
        let table = table.as_ref();
        let rows: Vec<(f64, f64)> = (0..nz)
            .into_par_iter()
            .map_init(
                || {
                    (
                        vec![0.0; nt],
                        vec![0.0; nt],
                        vec![Complex64::new(1.0, 0.0); nt],
                    )
                },
                |(ttr, ttx, rtx), iz| {
                    let (mut gc, mut gp) = (0.0, 0.0);
                    for ix in 0..nx {
                        let px = self.pixel(iz, ix);
                        let p = (iz * nx + ix) * self.n_frames;
                        for t in 0..nt {
                            // Transmit time, its offset from sample 0 and its phase.
                            let tt = self.tx_time(t, px, &trig);
                            ttr[t] = tt;
                            ttx[t] = tt - self.t0_s[t];
                            if self.rotate {
                                let (sn, co) = (w * tt).sin_cos();
                                rtx[t] = Complex64::new(co, sn);
                            }
                        }
                        for e in 0..ne {
                            let Some((trx, rrx)) = self.rx(table, &els, iz, ix, e) else {
                                continue;
                            };
                            let dx = px[0] - els[e].centre_m[0];
                            let dz = px[1] - els[e].centre_m[1];
                            let cr = c * (dx * dx + dz * dz).sqrt().max(1e-300);
                            let dtau_dp = -dx / cr * del[e][0] + -dz / cr * del[e][1];
                            for t in 0..nt {
                                let s = (ttx[t] + trx) * fs;
                                let Some((i, fw)) = locate(s, ns) else {
                                    continue;
                                };
                                let base = (t * ne + e) * ns + i;
                                let (d0, d1) = (data[base], data[base + 1]);
                                let mut dv = (d1 - d0).scale(fs);
                                if self.rotate {
                                    let v = d0.scale(1.0 - fw) + d1.scale(fw);
                                    dv = (dv + v.times_i().scale(w)).rot(rrx * rtx[t]);
                                }
                                let q = dv.dot(out_bar[p + self.frame_of[t]]);
                                let tau = ttr[t] + trx;
                                gc += q * (-tau / c);
                                gp += q * dtau_dp;
                            }
                        }
                    }
                    (gc, gp)
                },
            )
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
