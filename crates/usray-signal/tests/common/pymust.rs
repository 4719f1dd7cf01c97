//! Comparisons with PyMUST's images and point targets, shared by the PyMUST
//! tests (`pymust_points.rs`: linear array, plane waves; `pymust_probes.rs`:
//! phased and convex arrays, diverging and focused waves).

use usray_signal::das::{linspace, Das};
use usray_signal::demod::IqDemod;
use usray_signal::{ChannelData, ChannelMeta, Complex64};

/// Normalised cross-correlation (Pearson's r) of two equally long images.
pub fn ncc(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

/// How well usray's dB image matches PyMUST's over a set of pixels.
pub struct Agreement {
    /// NCC of the two dB images over the pixels.
    pub ncc: f64,
    /// Largest absolute difference, dB.
    pub max_diff_db: f64,
    /// Number of pixels compared.
    pub pixels: usize,
}

/// Compares usray's dB image `usray_db` with PyMUST's `pymust_db` (same pixel
/// order) over the pixels where PyMUST's is above −40 dB and `mask(k)` holds
/// for the pixel's index `k` (the region where the two models describe the
/// same field).
pub fn agreement(usray_db: &[f64], pymust_db: &[f64], mask: impl Fn(usize) -> bool) -> Agreement {
    let (mut a, mut r) = (vec![], vec![]);
    for (k, (&u, &p)) in usray_db.iter().zip(pymust_db).enumerate() {
        if p > -40.0 && mask(k) {
            a.push(u);
            r.push(p);
        }
    }
    let max_diff_db = a
        .iter()
        .zip(&r)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    Agreement {
        ncc: ncc(&a, &r),
        max_diff_db,
        pixels: a.len(),
    }
}

/// Transmit `t` of `ch` as channel data of its own (its `t0` kept).
pub fn one_transmit(ch: &ChannelData, t: usize) -> ChannelData {
    let mut meta = ch.meta.clone();
    let mut tx = meta.transmits[t].clone();
    tx.t0_s = Some(ch.meta.t0_for(t));
    meta.transmits = vec![tx];
    let n = ch.n_elements() * ch.n_samples;
    ChannelData {
        meta,
        n_samples: ch.n_samples,
        samples: ch.samples[t * n..(t + 1) * n].to_vec(),
    }
}

/// IQ demodulation of every record as PyMUST `rf2iq` (mix at f_c on the
/// absolute clock, Butterworth(5) low-pass at bandwidth/2, forward-backward).
pub fn iq(ch: &ChannelData) -> Vec<Complex64> {
    let (fc, fs) = (ch.meta.center_frequency_hz, ch.meta.sampling_frequency_hz);
    let bw = ch.meta.probe.extra["bandwidth_percent"].as_f64().unwrap() / 100.0;
    let d = IqDemod::new(fc, fs, bw * fc / 2.0, 5).unwrap();
    let ns = ch.n_samples;
    let ne = ch.n_elements();
    let mut out = vec![Complex64::new(0.0, 0.0); ch.samples.len()];
    for (rec, o) in out.chunks_mut(ns).enumerate() {
        d.forward(
            &ch.samples[rec * ns..(rec + 1) * ns],
            ch.meta.t0_for(rec / ne),
            o,
        );
    }
    out
}

/// The envelope of the delay-and-sum image `das` of the IQ records `iq`.
pub fn envelope(das: &Das, iq: &[Complex64]) -> Vec<f64> {
    let mut out = vec![Complex64::new(0.0, 0.0); das.out_len()];
    das.forward(iq, &mut out);
    out.iter().map(|v| v.norm()).collect()
}

/// Where the delay-and-sum envelope of `iq` (records of `meta`, `n_samples`
/// each; 1540 m/s, full aperture) peaks near the target `(xt, zt)` (m):
/// coarse over ±1 mm × ±2 mm at 0.1 mm, then ±0.15 mm at 0.01 mm around the
/// coarse peak.
pub fn peak_near(
    meta: &ChannelMeta,
    n_samples: usize,
    iq: &[Complex64],
    xt: f64,
    zt: f64,
) -> (f64, f64) {
    let peak = |x: Vec<f64>, z: Vec<f64>| {
        let das = Das::new(meta, n_samples, x.clone(), z.clone(), 1540.0, 0.0, true).unwrap();
        let k = usray_signal::post::argmax(&envelope(&das, iq));
        (x[k % x.len()], z[k / x.len()])
    };
    let (xc, zc) = peak(
        linspace(xt - 1e-3, xt + 1e-3, 21),
        linspace(zt - 2e-3, zt + 2e-3, 41),
    );
    peak(
        linspace(xc - 0.15e-3, xc + 0.15e-3, 31),
        linspace(zc - 0.15e-3, zc + 0.15e-3, 31),
    )
}
