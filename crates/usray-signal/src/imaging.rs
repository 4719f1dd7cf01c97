//! Imaging settings: the pixel grid, aperture, dynamic range and demodulation
//! of [`crate::BMode`] (CONTRACT §3 `[imaging]`), and the grid chosen from the
//! channel data alone ([`ImagingSettings::for_channels`]).

use serde::{Deserialize, Serialize};

use crate::array::{ArrayGeometry, ArrayKind};
use crate::channels::ChannelMeta;
use crate::das::linspace;
use crate::error::{Result, SignalError};

/// Largest image (`nz · nx`) [`ImagingSettings::grid`] accepts.
pub const MAX_PIXELS: usize = 20_000_000;

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

/// Where delay-and-sum forms the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum GridKind {
    /// `cartesian` for a linear probe, `sector` for phased and convex probes.
    #[default]
    Auto,
    /// Directly on the Cartesian pixels.
    Cartesian,
    /// On the probe's polar sector ([`crate::grid::PolarGrid::sector`]), then scan-converted
    /// (bilinear, on the envelope) to the Cartesian pixels; pixels outside the
    /// sector are black.
    Sector,
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
    /// Beamforming grid: Cartesian, or a sector scan-converted to the Cartesian
    /// pixels (default: by probe kind).
    pub grid: GridKind,
    /// The envelope shown at 0 dB, in the unit of the channel data's samples
    /// (`None`: each image's own maximum). Images compressed against one
    /// reference keep their absolute levels ([`crate::post`], "A fixed
    /// reference").
    pub reference_amplitude: Option<f64>,
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
            grid: GridKind::Auto,
            reference_amplitude: None,
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

    /// Settings that show everything `meta`'s records (`n_samples` each) can
    /// image, for beamforming without a scene: depth from 0 to the deepest
    /// echo the longest record holds (`c·t_last/2` from the probe-frame origin,
    /// `t_last` the time of its last sample on CONTRACT §1's clock); laterally
    /// the aperture of a linear probe, the ±45° sector of a phased one, the arc's
    /// angular span of a convex one (grid: [`GridKind::Auto`]); pixels of a
    /// quarter wavelength at `f_c`, coarsened so no axis exceeds 1000 pixels.
    /// Other fields keep their defaults.
    pub fn for_channels(meta: &ChannelMeta, n_samples: usize) -> Result<Self> {
        let array = ArrayGeometry::from_meta(&meta.probe).map_err(SignalError::Invalid)?;
        let c = meta.sound_speed_m_s;
        let t_last = (0..meta.transmits.len())
            .map(|t| {
                meta.t0_for(t) + n_samples.saturating_sub(1) as f64 / meta.sampling_frequency_hz
            })
            .fold(f64::NEG_INFINITY, f64::max);
        let depth = c * t_last / 2.0;
        if !(depth.is_finite() && depth > 0.0) {
            return Err(SignalError::Invalid(format!(
                "the records end at t = {t_last} s: nothing in front of the probe to image"
            )));
        }
        let half = match array.kind {
            ArrayKind::Linear => (array.n_elements as f64 - 1.0) * array.pitch_m / 2.0,
            ArrayKind::Phased => depth * std::f64::consts::FRAC_PI_4.sin(),
            ArrayKind::Convex => {
                let h = array.apothem_m();
                let span = array.angular_pitch_rad() * (array.n_elements as f64 - 1.0) / 2.0;
                (depth + h) * span.sin()
            }
        }
        .max(array.pitch_m);
        let lambda = c / meta.center_frequency_hz;
        let pixel = (lambda / 4.0).max((2.0 * half).max(depth) / 999.0);
        Ok(ImagingSettings::new([-half, half], [0.0, depth], pixel))
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
            let n = ((r[1] - r[0]) / self.pixel_m).round();
            if n.is_nan() || n >= 100_000.0 {
                return Err(SignalError::Invalid(format!(
                    "imaging.{name}: {} pixels is too many (at most 100000 per axis)",
                    n + 1.0
                )));
            }
            Ok(linspace(r[0], r[1], n as usize + 1))
        };
        let (x, z) = (
            axis("x_range_m", self.x_range_m)?,
            axis("z_range_m", self.z_range_m)?,
        );
        if x.len() * z.len() > MAX_PIXELS {
            return Err(SignalError::Invalid(format!(
                "imaging grid of {} × {} = {} pixels is too large (at most {MAX_PIXELS})",
                z.len(),
                x.len(),
                x.len() * z.len()
            )));
        }
        Ok((x, z))
    }
}
