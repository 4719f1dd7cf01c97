//! VJPs of the nonlinear operators and of the whole `B`, and the calibration
//! gradients (sound speed, pitch), against central finite differences.
//!
//! Tolerance: a central difference with step `h` has truncation error
//! `h²/6·|f'''|` and round-off `ε|f|/h`. Steps are chosen so both are ≲ 1e-7
//! relative at the smooth interior points used (envelopes bounded away from 0, no
//! pixel at a clip boundary, a unique arg-max that does not move within ±h), and
//! the comparison uses relative tolerance 1e-5 — two orders above that estimate,
//! far below the O(1) error of a wrong derivative.

mod common;
use common::*;
use usray_ad::Real;
use usray_signal::das::{linspace, Das};
use usray_signal::{post, BMode, ChannelData, Complex64, Demod, ImagingSettings};

#[test]
fn post_chain_vjp_matches_fd() {
    let mut r = Rng(11);
    let n = 50;
    let u: Vec<Complex64> = (0..n)
        .map(|_| Complex64::new(1.0 + r.next(), r.next()) * (1.5 + r.next()))
        .collect();
    let d_range = 200.0; // wide: no pixel clips (all envelopes within 20 dB)
    let w = r.vec(n);
    let loss = |u: &[Complex64]| {
        let mut env = vec![0.0; n];
        post::envelope(u, &mut env);
        let mut db = vec![0.0; n];
        post::log_compress(&env, &mut db);
        let mut img = vec![0.0; n];
        post::clip_dynamic_range(&db, d_range, &mut img);
        (dot(&img, &w), post::argmax(&env))
    };
    let mut env = vec![0.0; n];
    post::envelope(&u, &mut env);
    let mut db = vec![0.0; n];
    let q = post::log_compress(&env, &mut db);
    let mut db_bar = vec![0.0; n];
    post::clip_dynamic_range_vjp(&db, d_range, &w, &mut db_bar);
    let mut env_bar = vec![0.0; n];
    post::log_compress_vjp(&env, q, &db_bar, &mut env_bar);
    let mut u_bar = vec![Complex64::new(0.0, 0.0); n];
    post::envelope_vjp(&u, &env_bar, &mut u_bar);
    let v = r.cvec(n);
    let h = 1e-6;
    let up: Vec<Complex64> = u.iter().zip(&v).map(|(a, b)| a + b * h).collect();
    let um: Vec<Complex64> = u.iter().zip(&v).map(|(a, b)| a - b * h).collect();
    let ((lp, qp), (lm, qm)) = (loss(&up), loss(&um));
    assert_eq!((qp, qm), (q, q), "arg-max moved: pick another point");
    let fd = (lp - lm) / (2.0 * h);
    let an = cdot(&u_bar, &v);
    assert!(rel(fd, an) < 1e-5, "fd {fd} vjp {an}");
    // The exact max gradient matters: dropping it (detached max) is measurably wrong.
    let mut detached = env_bar.clone();
    let total: f64 = db_bar.iter().sum();
    detached[q] += 20.0 / core::f64::consts::LN_10 * total / env[q];
    let mut ub2 = vec![Complex64::new(0.0, 0.0); n];
    post::envelope_vjp(&u, &detached, &mut ub2);
    assert!(rel(fd, cdot(&ub2, &v)) > 1e-3);
}

/// Channel data: three point echoes plus noise, small probe.
fn synthetic(nt: usize, seed: u64) -> ChannelData {
    let angles: Vec<f64> = (0..nt).map(|t| 0.08 * t as f64 - 0.08).collect();
    let t0s = vec![-0.2e-6; nt];
    let (fs, fc) = (20e6, 5e6);
    let m = meta(16, fs, fc, &angles, &t0s);
    let ns = 180;
    let mut r = Rng(seed);
    let mut samples = vec![0.0; nt * 16 * ns];
    let pts = [(0.0, 3e-3), (-0.6e-3, 4e-3), (0.5e-3, 5e-3)];
    for t in 0..nt {
        let (s, c) = angles[t].sin_cos();
        for e in 0..16 {
            let xe = (e as f64 - 7.5) * 0.3e-3;
            for k in 0..ns {
                let tk = t0s[t] + k as f64 / fs;
                let mut v = 0.05 * r.next();
                for &(x, z) in &pts {
                    let tof = (x * s + z * c + ((x - xe).powi(2) + z * z).sqrt()) / 1540.0;
                    v += usray_signal::pulse::pulse(tk - tof, fc, 2.0);
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

/// Tag the transmits of `ch` with `frame` labels.
fn with_frames(mut ch: ChannelData, labels: &[u64]) -> ChannelData {
    assert_eq!(labels.len(), ch.n_transmits());
    for (t, &l) in ch.meta.transmits.iter_mut().zip(labels) {
        t.extra.insert("frame".into(), l.into());
    }
    ch
}

fn check_b(demod: Demod, fnum: f64, gain: f64) {
    check_b_on(synthetic(2, 5), demod, fnum, gain, 1e-5);
}

/// The imaging settings of the FD checks: a dynamic range wide enough that no
/// pixel clips.
fn settings(demod: Demod, fnum: f64, gain: f64) -> ImagingSettings {
    let mut s = ImagingSettings::new([-1e-3, 1e-3], [2.5e-3, 5.5e-3], 0.25e-3);
    s.f_number = fnum;
    s.demod = demod;
    s.dynamic_range_db = 300.0;
    s.depth_gain_db_per_cm = gain;
    s
}

/// FD check of the whole `B` at `ch`, step `h_rel` × the largest |sample|.
fn check_b_on(ch: ChannelData, demod: Demod, fnum: f64, gain: f64, h_rel: f64) {
    check_b_with(ch, &settings(demod, fnum, gain), h_rel);
}

/// [`check_b_on`] with any settings.
fn check_b_with(ch: ChannelData, s: &ImagingSettings, h_rel: f64) {
    let (demod, fnum, gain) = (s.demod, s.f_number, s.depth_gain_db_per_cm);
    let b = BMode::new(s, &ch.meta, ch.n_samples).unwrap();
    let mut ws = b.workspace();
    let img = b.forward(&ch, &mut ws).unwrap();
    let q = post::argmax(ws.envelope());
    // Weights on pixels with a healthy envelope only (log is smooth there).
    let emax = ws.envelope()[q];
    let mut r = Rng(9);
    let w: Vec<f64> = ws
        .envelope()
        .iter()
        .map(|&e| if e > 1e-3 * emax { r.next() } else { 0.0 })
        .collect();
    assert!(
        img.data.iter().all(|&v| v > 0.0),
        "a pixel clips at 0: widen D"
    );
    let g = b.vjp(&mut ws, &w).unwrap();
    let v = r.vec(ch.samples.len());
    let scale = ch.samples.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let h = h_rel * scale;
    let eval = |sign: f64| {
        let mut c = ch.clone();
        for (a, b) in c.samples.iter_mut().zip(&v) {
            *a += sign * h * b;
        }
        let mut ws2 = b.workspace();
        let im = b.forward(&c, &mut ws2).unwrap();
        assert_eq!(post::argmax(ws2.envelope()), q, "arg-max moved");
        dot(&im.data, &w)
    };
    let fd = (eval(1.0) - eval(-1.0)) / (2.0 * h);
    let an = dot(&g, &v);
    eprintln!(
        "B ({} frame(s), {demod:?}, F# {fnum}, gain {gain} dB/cm): fd {fd:.9e} vjp {an:.9e} rel {:.2e}",
        b.n_frames(),
        rel(fd, an)
    );
    assert!(rel(fd, an) < 1e-5, "fd {fd} vjp {an}");
}

/// Against a fixed reference (`reference_amplitude`) the image keeps its
/// absolute level: data twice as strong are `20 log10 2` dB brighter in every
/// pixel (against its own maximum the image would not change), and the VJP,
/// which then has no maximum term, matches finite differences.
#[test]
fn fixed_reference_keeps_absolute_levels_and_its_vjp_matches_fd() {
    let ch = synthetic(2, 5);
    let mut s = settings(Demod::Iq, 1.0, 0.0);
    let image_of = |s: &ImagingSettings, ch: &ChannelData| {
        let b = BMode::new(s, &ch.meta, ch.n_samples).unwrap();
        let mut ws = b.workspace();
        let img = b.forward(ch, &mut ws).unwrap();
        (
            img.data,
            post::argmax(ws.envelope()),
            ws.envelope().to_vec(),
        )
    };
    let (_, q, env) = image_of(&s, &ch);
    s.reference_amplitude = Some(4.0 * env[q]);
    let mut twice = ch.clone();
    twice.samples.iter_mut().for_each(|v| *v *= 2.0);
    let (a, _, _) = image_of(&s, &ch);
    let (b, _, _) = image_of(&s, &twice);
    let step = 20.0 * 2f64.log10() / s.dynamic_range_db;
    for (p, (x, y)) in a.iter().zip(&b).enumerate() {
        assert!(
            (y - x - step).abs() < 1e-9,
            "pixel {p}: {x} → {y}, expected +{step}"
        );
    }
    // Its own maximum at 0 dB: the image does not change.
    s.reference_amplitude = None;
    let (a, _, _) = image_of(&s, &ch);
    let (b, _, _) = image_of(&s, &twice);
    assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-12));
    s.reference_amplitude = Some(4.0 * env[q]);
    check_b_with(ch, &s, 1e-5);
    // A reference that is not a positive amplitude is refused, naming the key.
    s.reference_amplitude = Some(0.0);
    let e = BMode::new(&s, &synthetic(1, 5).meta, 100)
        .unwrap_err()
        .to_string();
    assert!(e.contains("reference_amplitude"), "{e}");
}

#[test]
fn whole_b_vjp_matches_fd_iq() {
    check_b(Demod::Iq, 0.0, 0.0);
    check_b(Demod::Iq, 1.0, 0.7);
}

/// Several frames (incoherent mean of per-frame envelopes), including frames whose
/// transmits are not contiguous in the data (labels 1, 0, 1, 0): the VJP of the
/// whole `B` must still match finite differences.
///
/// At the first point the directional derivative nearly cancels (|L'| ≈ 0.019
/// against ≈ 1 elsewhere), so the h² truncation term is ~100× larger relative to
/// it; the step is 10× smaller there. Measured: rel. error 7.1e-4, 7.1e-6, 4.4e-8
/// at steps 1e-4, 1e-5, 1e-6 — the h² decay of truncation, not a VJP error.
#[test]
fn whole_b_vjp_matches_fd_multi_frame() {
    let (iq, hil) = (Demod::Iq, Demod::Hilbert);
    check_b_on(
        with_frames(synthetic(4, 5), &[1, 0, 1, 0]),
        iq,
        0.0,
        0.0,
        1e-6,
    );
    check_b_on(
        with_frames(synthetic(4, 5), &[0, 0, 1, 1]),
        iq,
        0.0,
        0.0,
        1e-5,
    );
    check_b_on(
        with_frames(synthetic(4, 6), &[0, 1, 2, 3]),
        iq,
        1.0,
        0.7,
        1e-5,
    );
    check_b_on(
        with_frames(synthetic(3, 7), &[2, 0, 2]),
        hil,
        0.0,
        0.0,
        1e-5,
    );
}

/// Multi-frame `B` is the mean of the per-frame envelopes: against one
/// single-frame `B` per frame, envelopes averaged by hand.
#[test]
fn multi_frame_envelope_is_mean_of_frame_envelopes() {
    let ch = with_frames(synthetic(4, 3), &[1, 0, 1, 0]);
    let s = ImagingSettings::new([-1e-3, 1e-3], [2.5e-3, 5.5e-3], 0.25e-3);
    let b = BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
    assert_eq!(b.n_frames(), 2);
    assert_eq!(
        b.frame_transmits(),
        vec![&[1usize, 3][..], &[0usize, 2][..]]
    );
    let mut ws = b.workspace();
    b.forward(&ch, &mut ws).unwrap();
    let mut mean = vec![0.0; ws.envelope().len()];
    for txs in [[1usize, 3], [0, 2]] {
        let per = ch.n_elements() * ch.n_samples;
        let mut sub = ch.clone();
        sub.meta.transmits = txs.iter().map(|&t| ch.meta.transmits[t].clone()).collect();
        for t in &mut sub.meta.transmits {
            t.extra.remove("frame");
        }
        sub.samples = txs
            .iter()
            .flat_map(|&t| ch.samples[t * per..(t + 1) * per].to_vec())
            .collect();
        let b1 = BMode::new(&s, &sub.meta, sub.n_samples).unwrap();
        assert_eq!(b1.n_frames(), 1);
        let mut w1 = b1.workspace();
        b1.forward(&sub, &mut w1).unwrap();
        for (m, e) in mean.iter_mut().zip(w1.envelope()) {
            *m += e / 2.0;
        }
    }
    for (a, e) in ws.envelope().iter().zip(&mean) {
        assert!((a - e).abs() <= 1e-12 * e.abs().max(1e-300), "{a} vs {e}");
    }
    // And it differs from coherent compounding of all four transmits.
    let mut coh = ch.clone();
    for t in &mut coh.meta.transmits {
        t.extra.remove("frame");
    }
    let bc = BMode::new(&s, &coh.meta, coh.n_samples).unwrap();
    let mut wc = bc.workspace();
    bc.forward(&coh, &mut wc).unwrap();
    let diff = wc
        .envelope()
        .iter()
        .zip(ws.envelope())
        .map(|(a, b)| (a / 2.0 - b).abs())
        .fold(0.0, f64::max);
    assert!(diff > 1e-3 * mean.iter().fold(0.0f64, |a, &b| a.max(b)));
}

#[test]
fn whole_b_vjp_matches_fd_hilbert() {
    check_b(Demod::Hilbert, 0.0, 0.0);
}

#[test]
fn calibration_gradients_match_fd() {
    let ch = synthetic(2, 8);
    let mut r = Rng(4);
    for rotate in [true, false] {
        // IQ-like complex data for rotate = true (demodulated), RF for false.
        let x = linspace(-1e-3, 1e-3, 9);
        let z = linspace(2.5e-3, 5.5e-3, 13);
        let make = |c: f64, pitch: f64| {
            let mut m = ch.meta.clone();
            m.probe.pitch_m = pitch;
            Das::new(&m, ch.n_samples, x.clone(), z.clone(), c, 0.0, rotate).unwrap()
        };
        let data: Vec<Complex64> = if rotate {
            let d = usray_signal::demod::IqDemod::new(5e6, 20e6, 2e6, 5).unwrap();
            let ns = ch.n_samples;
            let mut out = vec![Complex64::new(0.0, 0.0); ch.samples.len()];
            for (rec, o) in out.chunks_mut(ns).enumerate() {
                d.forward(
                    &ch.samples[rec * ns..(rec + 1) * ns],
                    ch.meta.t0_for(rec / 16),
                    o,
                );
            }
            out
        } else {
            ch.samples.iter().map(|&v| Complex64::new(v, 0.0)).collect()
        };
        let ybar = r.cvec(x.len() * z.len());
        let loss = |c: f64, p: f64| {
            let d = make(c, p);
            let mut out = vec![Complex64::new(0.0, 0.0); ybar.len()];
            d.forward(&data, &mut out);
            cdot(&out, &ybar)
        };
        let g = make(1540.0, 0.3e-3).calibration_vjp(&data, &ybar);
        // Steps small against a sample period (dτ ≈ 1e-6 of a 50 ns sample) so that few
        // interpolation kinks are crossed.
        let (hc, hp) = (1e-5, 1e-11);
        let fdc = (loss(1540.0 + hc, 0.3e-3) - loss(1540.0 - hc, 0.3e-3)) / (2.0 * hc);
        let fdp = (loss(1540.0, 0.3e-3 + hp) - loss(1540.0, 0.3e-3 - hp)) / (2.0 * hp);
        eprintln!(
            "rotate {rotate}: dL/dc fd {fdc:.6e} an {:.6e}; dL/dpitch fd {fdp:.6e} an {:.6e}",
            g.d_sound_speed, g.d_pitch
        );
        assert!(
            rel(fdc, g.d_sound_speed) < 1e-4,
            "c: fd {fdc} an {}",
            g.d_sound_speed
        );
        assert!(
            rel(fdp, g.d_pitch) < 1e-4,
            "pitch: fd {fdp} an {}",
            g.d_pitch
        );
    }
}

#[test]
fn bmode_calibration_gradients_match_fd() {
    check_bmode_calibration(synthetic(2, 12));
}

#[test]
fn bmode_calibration_gradients_match_fd_multi_frame() {
    check_bmode_calibration(with_frames(synthetic(3, 13), &[0, 1, 0]));
}

fn check_bmode_calibration(ch: ChannelData) {
    let mut s = ImagingSettings::new([-1e-3, 1e-3], [2.5e-3, 5.5e-3], 0.25e-3);
    s.f_number = 0.0;
    s.dynamic_range_db = 300.0;
    let [(fdc, anc), (fdp, anp)] = calibration_against_fd(&ch, &s);
    eprintln!(
        "B: dL/dc fd {fdc:.6e} an {:.6e}; dL/dpitch fd {fdp:.6e} an {:.6e}",
        anc, anp
    );
    assert!(rel(fdc, anc) < 1e-4, "c: fd {fdc} an {}", anc);
    assert!(rel(fdp, anp) < 1e-4, "pitch: fd {fdp} an {}", anp);
}

#[test]
fn pulse_is_generic_and_its_derivative_is_exact() {
    use usray_ad::Dual;
    use usray_signal::pulse::{pulse, pulse_dt, pulse_sigma};
    let (fc, cycles) = (5e6, 3.0);
    // σ definition: envelope at ±cycles/(2 f_c) is exactly 1/2.
    let half = cycles / (2.0 * fc);
    assert!(((-(half * half) / pulse_sigma(fc, cycles)).exp() - 0.5).abs() < 1e-15);
    for k in -40..=40 {
        let t = k as f64 * 13e-9;
        let d = pulse(
            Dual::<1>::variable(t, 0),
            Dual::from_f64(fc),
            Dual::from_f64(cycles),
        );
        assert_eq!(d.re, pulse(t, fc, cycles));
        assert!(
            (d.eps[0] - pulse_dt(t, fc, cycles)).abs() <= 1e-9 * 2.0 * core::f64::consts::PI * fc
        );
    }
}
