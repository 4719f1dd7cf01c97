//! Shared helpers of the crate's tests.
#![allow(dead_code)]

use usray_signal::{ChannelMeta, Complex64};

/// A small deterministic generator (SplitMix64), uniform in [−1, 1).
pub struct Rng(pub u64);
impl Rng {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
    pub fn vec(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.next()).collect()
    }
    pub fn cvec(&mut self, n: usize) -> Vec<Complex64> {
        (0..n)
            .map(|_| Complex64::new(self.next(), self.next()))
            .collect()
    }
}

/// Channel metadata: `ne` elements at 0.3 mm, fs, fc, the given angles and t0s.
pub fn meta(ne: usize, fs: f64, fc: f64, angles: &[f64], t0s: &[f64]) -> ChannelMeta {
    let transmits: Vec<serde_json::Value> = angles
        .iter()
        .zip(t0s)
        .map(|(a, t)| serde_json::json!({"kind": "plane_wave", "angle_rad": a, "t0_s": t}))
        .collect();
    serde_json::from_value(serde_json::json!({
        "format": "usray-channels/1", "sampling_frequency_hz": fs, "t0_s": 0.0,
        "sound_speed_m_s": 1540.0, "center_frequency_hz": fc,
        "probe": {"kind": "linear", "n_elements": ne, "pitch_m": 0.3e-3, "element_width_m": 0.27e-3,
                  "bandwidth_percent": 70.0},
        "transmits": transmits
    }))
    .unwrap()
}

pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
pub fn cdot(a: &[Complex64], b: &[Complex64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.re * y.re + x.im * y.im)
        .sum()
}
pub fn norm2(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}
pub const EPS: f64 = f64::EPSILON;
