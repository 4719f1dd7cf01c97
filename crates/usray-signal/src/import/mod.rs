//! Measured acquisitions into CONTRACT §2 channel data, found by content.
//!
//! [`import_mat_with`] reads a MATLAB file ([`crate::mat::read_mat`]) and
//! recognises, in order:
//! - a **full-matrix capture** as in `synaptus` (a cell `data{k}` of
//!   `(time, receive element)` arrays, one per transmitting element, and no
//!   `param`), summed over transmits to one 0° plane wave;
//! - otherwise a **plane-wave acquisition**, whatever its variables are called:
//!   the parameters (sampling frequency, sound speed, pitch, transmit angles,
//!   centre frequency, …) come from the struct holding most of them, or from
//!   top-level variables, under any of their usual spellings (`fs`,
//!   `sampling_frequency`, `TXangle`, `angles_deg`, …); the RF is the largest real
//!   numeric array, its axes matched to samples × elements × transmits (×
//!   frames) in any order by the counts the parameters give. A file's
//!   per-element transmit delays (PyMUST's `param.TXdelay`) that are not plane
//!   waves at known angles give each transmit's wave — plane, diverging or
//!   focused — by a fit on the true element positions (`delays`, `wave_fit`);
//!   a finite `radius` (PyMUST's `param.radius`) makes the array convex.
//!
//! What the file lacks is either supplied by [`ImportOptions`] (the CLI's flags,
//! which override the file), assumed with a stated reason (element width = pitch,
//! t0 = 0, the centre frequency from the data's spectrum), or an error naming
//! what is missing and the names looked for. Every import records, in the
//! output's `source`, which variable gave each quantity and what was assumed.

mod axes;
mod delays;
mod fmc;
mod plane_wave;
mod quantities;
mod record;
mod samples;
mod wave_fit;

use std::path::Path;

pub use axes::Axis;

use crate::array::ArrayKind;
use crate::channels::ChannelData;
use crate::error::{Result, SignalError};
use crate::mat::read_mat;

/// What the user tells an import: a value given here wins over the file's and
/// is recorded in the output's `source.overrides`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImportOptions {
    /// The RF variable (top-level name, or `struct.field`).
    pub rf: Option<String>,
    /// The parameter struct.
    pub param: Option<String>,
    /// The roles of the RF array's axes, in its MATLAB order.
    pub axes: Option<Vec<Axis>>,
    /// Sampling frequency, Hz.
    pub sampling_frequency_hz: Option<f64>,
    /// Centre frequency, Hz.
    pub center_frequency_hz: Option<f64>,
    /// Sound speed, m/s.
    pub sound_speed_m_s: Option<f64>,
    /// Element pitch, m (full-matrix-capture files do not store it).
    pub pitch_m: Option<f64>,
    /// Element width, m.
    pub element_width_m: Option<f64>,
    /// Transmit steering angles, radians (CONTRACT §1 sign).
    pub angles_rad: Option<Vec<f64>>,
    /// Time of sample 0 after the transmit's time origin (the first element
    /// firing), s.
    pub t0_s: Option<f64>,
    /// Offset subtracted from every sample (default: mid-range for unsigned
    /// integers, else 0).
    pub sample_offset: Option<f64>,
}

impl ImportOptions {
    /// Every option that is set: its flag, its key in `source.overrides`, its
    /// value. One table, so the record and the refusal of unused options
    /// cannot disagree.
    fn set(&self) -> Vec<(&'static str, &'static str, serde_json::Value)> {
        use serde_json::Value;
        let num = |v: Option<f64>| v.map(Value::from);
        [
            ("--rf", "rf", self.rf.as_deref().map(Value::from)),
            ("--param", "param", self.param.as_deref().map(Value::from)),
            (
                "--axes",
                "axes",
                self.axes.as_deref().map(|a| axes::join(a).into()),
            ),
            (
                "--fs",
                "sampling_frequency_hz",
                num(self.sampling_frequency_hz),
            ),
            ("--fc", "center_frequency_hz", num(self.center_frequency_hz)),
            ("--c", "sound_speed_m_s", num(self.sound_speed_m_s)),
            ("--pitch", "pitch_m", num(self.pitch_m)),
            ("--width", "element_width_m", num(self.element_width_m)),
            (
                "--angles-deg",
                "angles_rad",
                self.angles_rad.clone().map(Value::from),
            ),
            ("--t0", "t0_s", num(self.t0_s)),
            ("--offset", "sample_offset", num(self.sample_offset)),
        ]
        .into_iter()
        .filter_map(|(flag, key, v)| v.map(|v| (flag, key, v)))
        .collect()
    }

    /// The values set, as the output's `source.overrides` records them.
    pub(crate) fn overrides(&self) -> serde_json::Value {
        serde_json::Value::Object(
            self.set()
                .into_iter()
                .map(|(_, key, v)| (key.to_string(), v))
                .collect(),
        )
    }

    /// An error naming every option set that a `layout` does not use (`used`
    /// lists the ones it does, by flag): an option silently ignored would leave
    /// the user believing it took effect.
    pub(crate) fn refuse_unused(
        &self,
        layout: &str,
        used: &[&str],
    ) -> std::result::Result<(), String> {
        let unused: Vec<&str> = self
            .set()
            .into_iter()
            .map(|(flag, _, _)| flag)
            .filter(|flag| !used.contains(flag))
            .collect();
        if unused.is_empty() {
            Ok(())
        } else {
            Err(format!(
                "{} do(es) not apply to {layout} (it takes {})",
                unused.join(", "),
                used.join(", ")
            ))
        }
    }

    /// An error naming the first flag that is not a finite number in its
    /// physical sign (positive, or any finite value for t0, offset and angles).
    pub fn check(&self) -> std::result::Result<(), String> {
        for (flag, v) in [
            ("--fs", self.sampling_frequency_hz),
            ("--fc", self.center_frequency_hz),
            ("--c", self.sound_speed_m_s),
            ("--pitch", self.pitch_m),
            ("--width", self.element_width_m),
        ] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(format!("{flag} must be a positive number, got {v}"));
            }
        }
        for (flag, v) in [("--t0", self.t0_s), ("--offset", self.sample_offset)] {
            if let Some(v) = v.filter(|v| !v.is_finite()) {
                return Err(format!("{flag} must be a finite number, got {v}"));
            }
        }
        if let Some(a) = &self.angles_rad {
            if let Some(v) = a
                .iter()
                .find(|v| !(v.is_finite() && v.abs() < std::f64::consts::FRAC_PI_2))
            {
                return Err(format!(
                    "--angles-deg: {} is not an angle strictly between -90 and 90 degrees",
                    v.to_degrees()
                ));
            }
        }
        Ok(())
    }
}

/// Convert a MATLAB `.mat` acquisition into CONTRACT §2 channel data, with
/// nothing supplied by the user (see [`import_mat_with`]).
pub fn import_mat(path: impl AsRef<Path>) -> Result<ChannelData> {
    import_mat_with(path, &ImportOptions::default())
}

/// Convert a MATLAB `.mat` acquisition into CONTRACT §2 channel data, the layout
/// found by content (module documentation) and `options` supplying or overriding
/// what the file stores.
///
/// Plane-wave clock (CONTRACT §1): transmit delays are taken to start at 0 on the
/// first-firing element (Verasonics' and PyMUST's `txdelay` convention), with
/// sample 0 at the file's `t0` (0 if absent) on that clock; the steered wave then
/// passes the array centre `(L/2)·|sin θ|/c` later (`L` the aperture), so each
/// transmit's `t0_s = t0 − (L/2)·|sin θ|/c`. A file's per-element transmit delays,
/// when present and linear in the element position, give that centre-crossing
/// time instead (their value at `x = 0`). Delays that are not linear, or come
/// without angles, or fire a convex array, are fitted transmit by transmit: the
/// plane, diverging or focused wave whose delay law `τ_e` (CONTRACT §1) gives
/// `d_e = a + τ_e` within 0.1 sample, `t0_s = t0 − a` (the fit and its
/// residual are recorded in `source.transmit_fit`; no fit is an error naming
/// the transmit).
///
/// Full-matrix capture (`synaptus`): `fs` (MHz), `MWB` (µs, time of sample 0
/// after the excitation), `cp` (m/s), `nTotElem`, optional `fc` (Hz); the sum
/// over transmits `Σ_k data{k}` is the 0° plane wave fired by all elements at
/// once, so `t0_s = MWB`. The pitch is required from `options.pitch_m`; the
/// element width is set to the pitch; without `fc` in the file or the options,
/// the centre frequency is estimated from the samples as for plane waves.
///
/// Errors name the file and what is missing or unmappable.
pub fn import_mat_with(path: impl AsRef<Path>, options: &ImportOptions) -> Result<ChannelData> {
    let path = path.as_ref();
    options.check().map_err(|w| SignalError::format(path, w))?;
    let vars = read_mat(path)?;
    if options.rf.is_none() && fmc::is_full_matrix_capture(&vars) {
        return fmc::import(path, &vars, options);
    }
    plane_wave::import(path, &vars, options)
}

/// The largest pitch, in wavelengths at the centre frequency, of a flat array
/// imported as `phased` (P4-2v: 0.53).
pub const PHASED_PITCH_WAVELENGTHS: f64 = 0.6;

/// CONTRACT §2's `probe.kind` of `kind`.
pub(crate) fn kind_name(kind: ArrayKind) -> &'static str {
    match kind {
        ArrayKind::Linear => "linear",
        ArrayKind::Phased => "phased",
        ArrayKind::Convex => "convex",
    }
}

/// The kind of a flat array of pitch `pitch_m` at sound speed `c` and centre
/// frequency `fc`: `phased` when the pitch is at most
/// [`PHASED_PITCH_WAVELENGTHS`] wavelengths (phased arrays are built near λ/2
/// to steer without grating lobes; a file does not say which it is), with the
/// note recording that; else `linear`.
pub(crate) fn flat_kind(pitch_m: f64, c: f64, fc: f64) -> (ArrayKind, Option<String>) {
    let limit_m = PHASED_PITCH_WAVELENGTHS * c / fc;
    if pitch_m <= limit_m {
        let note = format!(
            "a flat array of pitch {:.3} mm, at most {PHASED_PITCH_WAVELENGTHS} wavelengths ({:.3} mm at fc): recorded as a phased array (sector image)",
            pitch_m * 1e3,
            limit_m * 1e3
        );
        (ArrayKind::Phased, Some(note))
    } else {
        (ArrayKind::Linear, None)
    }
}

/// `data` if it passes [`ChannelData::validate`] (every field in its physical
/// range, samples present and finite), else an error naming `path`.
pub(crate) fn validated(path: &Path, data: ChannelData) -> Result<ChannelData> {
    data.validate().map_err(|w| {
        SignalError::format(
            path,
            format!("the imported data are not valid channel data: {w}"),
        )
    })?;
    Ok(data)
}
