//! Channel data in memory: CONTRACT §2 (`usray-channels/1`).
//!
//! Samples are held as `f64` in memory (accumulation and gradients want the
//! precision) and written as `float32` NPY on disk, C order
//! `[n_transmits, n_elements, n_samples]`.

use serde::{Deserialize, Serialize};

use crate::array::ArrayGeometry;
use crate::transmit::TransmitWave;

/// The format tag of CONTRACT §2.
pub const CHANNELS_FORMAT: &str = "usray-channels/1";

/// The key on a transmit that names its acquisition (frame); see
/// [`ChannelMeta::frames`].
pub const FRAME_KEY: &str = "frame";

/// The physical ranges [`ChannelMeta::validate`] accepts.
pub mod limits {
    /// Sampling and centre frequencies, Hz: `(1 kHz, 10 GHz]`; a scene's limit too.
    pub const FREQUENCY_HZ: (f64, f64) = (1e3, 1e10);
    /// Sound speed, m/s: `(100, 20 000]` (gases to the fastest solids); every
    /// sound speed of a scene too.
    pub const SOUND_SPEED_M_S: (f64, f64) = (100.0, 20_000.0);
    /// Element pitch, m: `(0, 100 mm]` (arrays have under 2 mm; two separate
    /// transducers centimetres apart are a test set-up); a scene's limit too.
    pub const PITCH_M: (f64, f64) = (0.0, 0.1);
    /// Largest `|t0_s|`, s.
    pub const MAX_ABS_T0_S: f64 = 1.0;
    /// Largest `probe.n_elements` (the largest clinical arrays have 256; 2-D
    /// matrix arrays up to a few thousand); a scene's limit too.
    pub const MAX_ELEMENTS: usize = 4096;
}

/// Probe description carried by channel data (CONTRACT §2 `probe`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbeMeta {
    /// Array kind: `"linear"`, `"phased"` or `"convex"` ([`crate::array`]); a
    /// convex probe also carries `radius_m` (in `extra`, read by
    /// [`crate::array::ArrayGeometry::from_meta`]).
    pub kind: String,
    /// Number of elements.
    pub n_elements: usize,
    /// Centre-to-centre element spacing, metres.
    pub pitch_m: f64,
    /// Element width along the array, metres.
    pub element_width_m: f64,
    /// Keys we do not interpret, kept on round trip.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// One transmit event (CONTRACT §2 `transmits[i]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TransmitMeta {
    /// Transmit kind: `"plane_wave"`, `"diverging"` (key `virtual_source_m`) or
    /// `"focused"` (key `focus_m`), both keys kept in `extra` and read by
    /// [`crate::transmit::TransmitWave::from_meta`].
    pub kind: String,
    /// Steering angle θ of a plane wave, radians; arrival time at `(x, z)` is
    /// `(x sin θ + z cos θ)/c`. Absent (read as 0) for the other kinds.
    #[serde(default)]
    pub angle_rad: f64,
    /// Time of sample 0 for this transmit on the clock of CONTRACT §1, seconds;
    /// overrides the global `t0_s` when present.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t0_s: Option<f64>,
    /// Keys we do not interpret, kept on round trip.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// The JSON sidecar of CONTRACT §2.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChannelMeta {
    /// Always [`CHANNELS_FORMAT`].
    pub format: String,
    /// Sampling frequency `f_s`, hertz.
    pub sampling_frequency_hz: f64,
    /// Time of sample 0 on the clock of CONTRACT §1, seconds.
    pub t0_s: f64,
    /// Sound speed the acquisition assumed, m/s.
    pub sound_speed_m_s: f64,
    /// Centre frequency `f_c`, hertz.
    pub center_frequency_hz: f64,
    /// The probe.
    pub probe: ProbeMeta,
    /// One entry per transmit, in the order of the array's first axis.
    pub transmits: Vec<TransmitMeta>,
    /// Keys we do not interpret, kept on round trip.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

impl ChannelMeta {
    /// The acquisitions (frames) the transmits belong to, as groups of transmit
    /// indices: one group per distinct `frame` label, in increasing label order,
    /// transmits in file order within a group.
    ///
    /// The `frame` key (a non-negative integer on each entry of `transmits`, an
    /// extension allowed by CONTRACT §2's "extra keys") says which acquisition a
    /// transmit belongs to: transmits of one frame image the same (static) object
    /// and are compounded coherently; different frames (e.g. successive
    /// acquisitions of a moving object) are not. When no transmit carries `frame`,
    /// all transmits form one frame. Either every transmit carries it or none does.
    ///
    /// ```
    /// let m: usray_signal::ChannelMeta = serde_json::from_value(serde_json::json!({
    ///     "format": "usray-channels/1", "sampling_frequency_hz": 20e6, "t0_s": 0.0,
    ///     "sound_speed_m_s": 1540.0, "center_frequency_hz": 5e6,
    ///     "probe": {"kind": "linear", "n_elements": 8, "pitch_m": 0.3e-3, "element_width_m": 0.27e-3},
    ///     "transmits": [
    ///         {"kind": "plane_wave", "angle_rad": -0.1, "frame": 1},
    ///         {"kind": "plane_wave", "angle_rad": 0.1, "frame": 0},
    ///         {"kind": "plane_wave", "angle_rad": 0.0, "frame": 1}]
    /// })).unwrap();
    /// assert_eq!(m.frames().unwrap(), vec![vec![1], vec![0, 2]]);
    /// ```
    pub fn frames(&self) -> Result<Vec<Vec<usize>>, String> {
        let n_tagged = self
            .transmits
            .iter()
            .filter(|t| t.extra.contains_key(FRAME_KEY))
            .count();
        if n_tagged == 0 {
            return Ok(vec![(0..self.transmits.len()).collect()]);
        }
        let mut labelled = Vec::with_capacity(self.transmits.len());
        for (i, t) in self.transmits.iter().enumerate() {
            let label = match t.extra.get(FRAME_KEY) {
                None => {
                    return Err(format!(
                        "transmits[{i}] has no `{FRAME_KEY}` key but {n_tagged} other transmit(s) do: either every transmit carries `{FRAME_KEY}` or none does"
                    ))
                }
                Some(v) => v.as_u64().ok_or_else(|| {
                    format!("transmits[{i}].{FRAME_KEY} is {v}; a non-negative integer is required")
                })?,
            };
            labelled.push((label, i));
        }
        labelled.sort(); // stable by (label, index)
        let mut groups: Vec<Vec<usize>> = Vec::new();
        let mut last = None;
        for (label, i) in labelled {
            if last != Some(label) {
                groups.push(Vec::new());
                last = Some(label);
            }
            if let Some(g) = groups.last_mut() {
                g.push(i);
            }
        }
        Ok(groups)
    }

    /// Checks every field against its physical range ([`limits`]): the format
    /// tag, positive finite frequencies, speed and pitch, a width in
    /// `(0, pitch]`, a known probe kind (`"linear"`, `"phased"`, `"convex"` with a
    /// radius of at least half the aperture; [`ArrayGeometry::from_meta`]) and
    /// transmit kind (`"plane_wave"` with an angle inside ±90°, `"diverging"`
    /// from behind the array, `"focused"` in front of it;
    /// [`TransmitWave::from_meta`]), finite times of sample 0, and consistent
    /// frame tags. The error names the field.
    pub fn validate(&self) -> Result<(), String> {
        if self.format != CHANNELS_FORMAT {
            return Err(format!(
                "`format` is {:?}, expected {CHANNELS_FORMAT:?}",
                self.format
            ));
        }
        let in_range = |name: &str, v: f64, (lo, hi): (f64, f64)| {
            if v.is_finite() && v > lo && v <= hi {
                Ok(())
            } else {
                Err(format!("`{name}` must lie in ({lo:e}, {hi:e}], got {v}"))
            }
        };
        in_range(
            "sampling_frequency_hz",
            self.sampling_frequency_hz,
            limits::FREQUENCY_HZ,
        )?;
        in_range(
            "center_frequency_hz",
            self.center_frequency_hz,
            limits::FREQUENCY_HZ,
        )?;
        in_range(
            "sound_speed_m_s",
            self.sound_speed_m_s,
            limits::SOUND_SPEED_M_S,
        )?;
        in_range("probe.pitch_m", self.probe.pitch_m, limits::PITCH_M)?;
        ArrayGeometry::from_meta(&self.probe)?;
        if !(self.t0_s.is_finite() && self.t0_s.abs() <= limits::MAX_ABS_T0_S) {
            return Err(format!(
                "`t0_s` must be finite and within ±{} s, got {}",
                limits::MAX_ABS_T0_S,
                self.t0_s
            ));
        }
        if !(1..=limits::MAX_ELEMENTS).contains(&self.probe.n_elements) {
            return Err(format!(
                "`probe.n_elements` must lie in 1..={}, got {}",
                limits::MAX_ELEMENTS,
                self.probe.n_elements
            ));
        }
        if self.transmits.is_empty() {
            return Err("`transmits` is empty".into());
        }
        for (i, t) in self.transmits.iter().enumerate() {
            TransmitWave::from_meta(i, t)?;
            if let Some(t0) = t.t0_s {
                if !(t0.is_finite() && t0.abs() <= limits::MAX_ABS_T0_S) {
                    return Err(format!(
                        "transmits[{i}].t0_s must be finite and within ±{} s, got {t0}",
                        limits::MAX_ABS_T0_S
                    ));
                }
            }
        }
        self.frames()?;
        Ok(())
    }

    /// Time of sample 0 for transmit `tx`, seconds: the transmit's own `t0_s` if
    /// it has one, else the global one.
    pub fn t0_for(&self, tx: usize) -> f64 {
        self.transmits
            .get(tx)
            .and_then(|t| t.t0_s)
            .unwrap_or(self.t0_s)
    }
}

/// RF channel data: metadata plus samples, C order `[n_transmits, n_elements, n_samples]`.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelData {
    /// The sidecar metadata.
    pub meta: ChannelMeta,
    /// Number of samples per (transmit, element) record.
    pub n_samples: usize,
    /// The samples, `samples[(tx * n_elements + el) * n_samples + k]`.
    pub samples: Vec<f64>,
}

impl ChannelData {
    /// `(n_transmits, n_elements, n_samples)` as the metadata and `n_samples` say.
    pub fn shape(&self) -> (usize, usize, usize) {
        (self.n_transmits(), self.n_elements(), self.n_samples)
    }
    /// Checks the metadata ([`ChannelMeta::validate`]), at least one sample per
    /// record, and that the samples fill the shape and are finite.
    pub fn validate(&self) -> Result<(), String> {
        self.meta.validate()?;
        if self.n_samples == 0 {
            return Err("the records hold no samples".into());
        }
        let expect = self.n_transmits() * self.n_elements() * self.n_samples;
        if self.samples.len() != expect {
            return Err(format!(
                "channel data holds {} samples, its shape needs {expect}",
                self.samples.len()
            ));
        }
        if let Some(i) = self.samples.iter().position(|v| !v.is_finite()) {
            return Err(format!("sample {i} is not finite"));
        }
        Ok(())
    }
    /// Number of transmits (`meta.transmits.len()`).
    pub fn n_transmits(&self) -> usize {
        self.meta.transmits.len()
    }
    /// Number of elements (`meta.probe.n_elements`).
    pub fn n_elements(&self) -> usize {
        self.meta.probe.n_elements
    }
    /// The record of one (transmit, element) pair.
    ///
    /// # Panics
    /// If `tx` or `el` is out of range (like slice indexing); [`ChannelData::get_record`]
    /// is the non-panicking form.
    pub fn record(&self, tx: usize, el: usize) -> &[f64] {
        self.get_record(tx, el).unwrap_or_else(|| {
            panic!(
                "record ({tx}, {el}) out of range: shape [{}, {}, {}] with {} samples",
                self.n_transmits(),
                self.n_elements(),
                self.n_samples,
                self.samples.len()
            )
        })
    }

    /// The record of one (transmit, element) pair, or `None` if `tx` or `el` is
    /// out of range or `samples` is shorter than the shape says.
    pub fn get_record(&self, tx: usize, el: usize) -> Option<&[f64]> {
        if tx >= self.n_transmits() || el >= self.n_elements() {
            return None;
        }
        let n = self.n_samples;
        let start = (tx * self.n_elements() + el).checked_mul(n)?;
        self.samples.get(start..start.checked_add(n)?)
    }
}
