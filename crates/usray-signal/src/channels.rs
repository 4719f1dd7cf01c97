//! Channel data in memory: CONTRACT §2 (`usray-channels/1`).
//!
//! Samples are held as `f64` in memory (accumulation and gradients want the
//! precision) and written as `float32` NPY on disk, C order
//! `[n_transmits, n_elements, n_samples]`.

use serde::{Deserialize, Serialize};

/// The format tag of CONTRACT §2.
pub const CHANNELS_FORMAT: &str = "usray-channels/1";

/// Probe description carried by channel data (CONTRACT §2 `probe`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbeMeta {
    /// Array kind; only `"linear"` is defined so far.
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
    /// Transmit kind; only `"plane_wave"` is defined so far.
    pub kind: String,
    /// Steering angle θ, radians; arrival time at `(x, z)` is `(x sin θ + z cos θ)/c`.
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
    /// Number of transmits (`meta.transmits.len()`).
    pub fn n_transmits(&self) -> usize {
        self.meta.transmits.len()
    }
    /// Number of elements (`meta.probe.n_elements`).
    pub fn n_elements(&self) -> usize {
        self.meta.probe.n_elements
    }
    /// The record of one (transmit, element) pair.
    pub fn record(&self, tx: usize, el: usize) -> &[f64] {
        let n = self.n_samples;
        let start = (tx * self.n_elements() + el) * n;
        &self.samples[start..start + n]
    }
}
