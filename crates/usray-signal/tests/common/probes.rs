//! Helpers of the phased and convex tests: PyMUST-like IQ demodulation, the
//! delay-and-sum envelope, one transmit at a time, and point-target localisation.

use usray_signal::array::ArrayGeometry;
use usray_signal::das::{linspace, Das};
use usray_signal::demod::IqDemod;
use usray_signal::transmit::TransmitWave;
use usray_signal::{ChannelData, Complex64};

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

pub fn envelope(das: &Das, iq: &[Complex64]) -> Vec<f64> {
    let mut out = vec![Complex64::new(0.0, 0.0); das.out_len()];
    das.forward(iq, &mut out);
    out.iter().map(|v| v.norm()).collect()
}

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

/// Whether the wave reaches `p` along a ray from its virtual source or
/// through its focus that leaves the array: the line from the wave's point
/// through `p` crosses `z = 0` within the end elements (outside that cone the
/// circular-wave time model does not describe the field, PyMUST or usray).
pub fn insonified(wave: &TransmitWave<f64>, p: [f64; 2], half_aperture_m: f64) -> bool {
    let q = match *wave {
        TransmitWave::Diverging { source_m } => source_m,
        TransmitWave::Focused { focus_m } => focus_m,
        TransmitWave::PlaneWave { .. } => return true,
    };
    if p[1] == q[1] {
        return false;
    }
    let x_hit = q[0] + (p[0] - q[0]) * (0.0 - q[1]) / (p[1] - q[1]);
    x_hit.abs() <= half_aperture_m
}

/// Every point target `(xs, zs)` insonified by a transmit of `ch` is found,
/// on that transmit's image alone, within 0.2 mm of its true position (peak of
/// the envelope, F-number 0); returns the worst error and how many targets
/// were insonified by some transmit.
pub fn localise(name: &str, ch: &ChannelData, xs: &[f64], zs: &[f64]) -> (f64, usize) {
    let array = ArrayGeometry::from_meta(&ch.meta.probe).unwrap();
    let els = array.elements();
    let half = els[els.len() - 1].centre_m[0];
    let mut worst: f64 = 0.0;
    let mut seen = vec![false; xs.len()];
    for t in 0..ch.n_transmits() {
        let c1 = one_transmit(ch, t);
        let wave = TransmitWave::from_meta(0, &c1.meta.transmits[0]).unwrap();
        let iq = iq(&c1);
        let peak = |x: Vec<f64>, z: Vec<f64>| {
            let das = Das::new(
                &c1.meta,
                c1.n_samples,
                x.clone(),
                z.clone(),
                1540.0,
                0.0,
                true,
            )
            .unwrap();
            let k = usray_signal::post::argmax(&envelope(&das, &iq));
            (x[k % x.len()], z[k / x.len()])
        };
        for (i, (&xt, &zt)) in xs.iter().zip(zs).enumerate() {
            if !insonified(&wave, [xt, zt], half) {
                continue;
            }
            seen[i] = true;
            // Coarse: ±1 mm × ±2 mm at 0.1 mm; fine: ±0.15 mm at 0.01 mm.
            let (xc, zc) = peak(
                linspace(xt - 1e-3, xt + 1e-3, 21),
                linspace(zt - 2e-3, zt + 2e-3, 41),
            );
            let (xf, zf) = peak(
                linspace(xc - 0.15e-3, xc + 0.15e-3, 31),
                linspace(zc - 0.15e-3, zc + 0.15e-3, 31),
            );
            let err = (xf - xt).hypot(zf - zt);
            eprintln!(
                "{name} transmit {t}: point ({:.1}, {:.1}) mm found at ({:.3}, {:.3}) mm, error {:.3} mm",
                xt * 1e3, zt * 1e3, xf * 1e3, zf * 1e3, err * 1e3
            );
            assert!(
                err < 0.2e-3,
                "{name} transmit {t}, point ({xt}, {zt}): error {err} m"
            );
            worst = worst.max(err);
        }
    }
    (worst, seen.iter().filter(|&&s| s).count())
}
