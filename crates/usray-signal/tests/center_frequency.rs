//! The derivative of the B-mode in the centre frequency `f_c` with the channel
//! data fixed (`BMode::center_frequency_vjp`: IQ mixing phases, the low-pass
//! designed at a fraction of `f_c`, and the delay-and-sum's phase rotation),
//! against central finite differences of the whole operator in `f_c`; and the
//! bits of the operator it differentiates, pinned.
//!
//! Tolerance: the central difference with step `h` has truncation error
//! `h²/6·|L'''|`; with `h = 10⁻⁵ f_c` and its Richardson extrapolation from
//! `h` and `2h` (error `O(h⁴)`), the reference is good to ≈ 10⁻⁹ relative at
//! the smooth interior points used (no pixel clips, the arg-max stays put),
//! so the comparison asserts 10⁻⁶.

mod common;
use common::*;
use usray_signal::{post, BMode, ChannelData, Demod, ImagingSettings};

fn hash(v: &[f64]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for x in v {
        for b in x.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// Three point echoes under `nt` plane waves on 16 elements, band-pass
/// sampled like a scanner (20 MHz for 5 MHz), with a little noise.
fn echoes(nt: usize, seed: u64) -> ChannelData {
    let angles: Vec<f64> = (0..nt).map(|t| 0.07 * t as f64 - 0.07).collect();
    let t0s = vec![-0.3e-6; nt];
    let (fs, fc) = (20e6, 5e6);
    let m = meta(16, fs, fc, &angles, &t0s);
    let ns = 200;
    let mut r = Rng(seed);
    let mut samples = vec![0.0; nt * 16 * ns];
    let pts = [(0.1e-3, 3e-3), (-0.5e-3, 4.2e-3), (0.6e-3, 5.1e-3)];
    for t in 0..nt {
        let (s, c) = angles[t].sin_cos();
        for e in 0..16 {
            let xe = (e as f64 - 7.5) * 0.3e-3;
            for k in 0..ns {
                let tk = t0s[t] + k as f64 / fs;
                let mut v = 0.05 * r.next();
                for &(x, z) in &pts {
                    let tof = (x * s + z * c + ((x - xe).powi(2) + z * z).sqrt()) / 1540.0;
                    v += usray_signal::pulse::pulse(tk - tof, fc, 2.5);
                }
                samples[(t * 16 + e) * ns + k] = v;
            }
        }
    }
    ChannelData {
        meta: m,
        n_samples: ns,
        samples,
    }
}

fn settings(demod: Demod, gain: f64) -> ImagingSettings {
    let mut s = ImagingSettings::new([-1e-3, 1e-3], [2.5e-3, 5.5e-3], 0.25e-3);
    s.f_number = 1.0;
    s.demod = demod;
    s.dynamic_range_db = 300.0;
    s.depth_gain_db_per_cm = gain;
    s.iq_bandwidth_fraction = Some(0.8);
    s
}

/// `L = Σ w·I` with fixed weights on the pixels of healthy envelope.
fn weights(b: &BMode, ch: &ChannelData) -> Vec<f64> {
    let mut ws = b.workspace();
    b.forward(ch, &mut ws).unwrap();
    let emax = ws.envelope()[post::argmax(ws.envelope())];
    let mut r = Rng(17);
    ws.envelope()
        .iter()
        .map(|&e| if e > 1e-3 * emax { r.next() } else { 0.0 })
        .collect()
}

/// The image and the VJP of the IQ pipeline (depth gain, low-pass, rotation),
/// as they were before the Butterworth design became generic in `T: Real`.
#[test]
fn bmode_keeps_its_bits() {
    let ch = echoes(3, 4);
    let b = BMode::new(&settings(Demod::Iq, 0.5), &ch.meta, ch.n_samples).unwrap();
    let mut ws = b.workspace();
    let img = b.forward(&ch, &mut ws).unwrap();
    let w = weights(&b, &ch);
    let g = b.vjp(&mut ws, &w).unwrap();
    assert_eq!(
        [hash(&img.data), hash(&g)],
        [8_451_134_258_586_764_841, 7_509_257_058_531_390_483]
    );
}

/// `∂L/∂f_c` by central differences of the whole operator in `f_c` with the
/// data held, step `h` (the operator rebuilt at `f_c ± h`, which moves the
/// mixing, the low-pass and the rotation together).
fn central_difference(ch: &ChannelData, s: &ImagingSettings, w: &[f64], h: f64) -> f64 {
    let at = |fc: f64| {
        let mut meta = ch.meta.clone();
        meta.center_frequency_hz = fc;
        let b = BMode::new(s, &meta, ch.n_samples).unwrap();
        let mut ws = b.workspace();
        let img = b.forward(ch, &mut ws).unwrap();
        img.data.iter().zip(w).map(|(i, w)| i * w).sum::<f64>()
    };
    let fc = ch.meta.center_frequency_hz;
    (at(fc + h) - at(fc - h)) / (2.0 * h)
}

/// The exact derivative against the Richardson extrapolation of central
/// differences (module docs), on one frame and on two frames, with and
/// without depth gain.
#[test]
fn center_frequency_derivative_matches_finite_differences() {
    let framed = |mut ch: ChannelData| {
        for (t, tx) in ch.meta.transmits.iter_mut().enumerate() {
            tx.extra.insert("frame".into(), ((t % 2) as u64).into());
        }
        ch
    };
    for (name, ch, gain) in [
        ("one frame", echoes(3, 4), 0.0),
        ("one frame, depth gain", echoes(3, 5), 0.8),
        ("two frames", framed(echoes(4, 6)), 0.0),
    ] {
        let s = settings(Demod::Iq, gain);
        let b = BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
        let w = weights(&b, &ch);
        let mut ws = b.workspace();
        b.forward(&ch, &mut ws).unwrap();
        let exact = b.center_frequency_vjp(&ch, &mut ws, &w).unwrap();
        let h = 1e-5 * ch.meta.center_frequency_hz;
        let (d1, d2) = (
            central_difference(&ch, &s, &w, h),
            central_difference(&ch, &s, &w, 2.0 * h),
        );
        let fd = (4.0 * d1 - d2) / 3.0;
        let rel = (exact - fd).abs() / fd.abs();
        println!("{name}: exact {exact:e}, FD {fd:e} (h: {d1:e}, 2h: {d2:e}), relative {rel:e}");
        assert!(fd.abs() > 0.0);
        assert!(
            rel < 1e-6,
            "{name}: exact {exact:e} vs FD {fd:e}, relative {rel:e}"
        );
    }
}

/// The old objective's step, `10⁻⁴ f_c`: its central difference agrees with
/// the exact derivative to its own truncation error (estimated by the
/// difference between steps `h` and `h/2`, times 4/3 for a second-order
/// error).
#[test]
fn the_old_central_difference_agrees_to_its_accuracy() {
    let ch = echoes(3, 4);
    let s = settings(Demod::Iq, 0.0);
    let b = BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
    let w = weights(&b, &ch);
    let mut ws = b.workspace();
    b.forward(&ch, &mut ws).unwrap();
    let exact = b.center_frequency_vjp(&ch, &mut ws, &w).unwrap();
    let h = 1e-4 * ch.meta.center_frequency_hz;
    let old = central_difference(&ch, &s, &w, h);
    let half = central_difference(&ch, &s, &w, 0.5 * h);
    let accuracy = 4.0 / 3.0 * (old - half).abs();
    println!(
        "old FD {old:e}, exact {exact:e}, difference {:e}, the FD's error estimate {accuracy:e}",
        (old - exact).abs()
    );
    assert!((old - exact).abs() <= 2.0 * accuracy + 1e-12 * exact.abs());
}

/// With the Hilbert analytic signal `f_c` enters nothing: 0, as the
/// operator rebuilt at another `f_c` gives the same image.
#[test]
fn hilbert_images_do_not_depend_on_the_center_frequency() {
    let ch = echoes(2, 8);
    let s = settings(Demod::Hilbert, 0.0);
    let b = BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
    let w = weights(&b, &ch);
    let mut ws = b.workspace();
    b.forward(&ch, &mut ws).unwrap();
    assert_eq!(b.center_frequency_vjp(&ch, &mut ws, &w).unwrap(), 0.0);
    assert_eq!(central_difference(&ch, &s, &w, 1e3), 0.0);
}
