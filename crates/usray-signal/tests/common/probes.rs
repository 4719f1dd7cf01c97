//! Helpers of the phased and convex tests: which pixels a diverging or
//! focused wave insonifies, and point-target localisation one transmit at a
//! time (on [`super::pymust`]'s demodulation and peak search).

use super::pymust::{iq, one_transmit, peak_near};
use usray_signal::array::ArrayGeometry;
use usray_signal::transmit::TransmitWave;
use usray_signal::ChannelData;

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
        for (i, (&xt, &zt)) in xs.iter().zip(zs).enumerate() {
            if !insonified(&wave, [xt, zt], half) {
                continue;
            }
            seen[i] = true;
            let (xf, zf) = peak_near(&c1.meta, c1.n_samples, &iq, xt, zt);
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
