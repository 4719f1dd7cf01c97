//! Sector imaging with convex and phased arrays, diverging and focused waves:
//! the scan conversion against its closed form and by the dot-product identity,
//! the whole `B` (delay-and-sum on the sector, envelope, scan conversion, log)
//! and the calibration gradients against central finite differences.
//!
//! Tolerances: steps chosen so truncation and round-off are ≲ 1e-7 relative;
//! relative tolerance 1e-6 (measured: 7e-8–9e-8 for `B`'s VJP, 1e-8 and 7e-9
//! for the sound-speed and pitch gradients), far below the O(1) error of a
//! wrong derivative.

mod common;
use common::*;
use usray_signal::array::ArrayGeometry;
use usray_signal::bmode::GridKind;
use usray_signal::das::linspace;
use usray_signal::grid::{PolarGrid, ScanConversion};
use usray_signal::transmit::TransmitWave;
use usray_signal::{post, BMode, ChannelData, ChannelMeta, ImagingSettings};

const PTS: [(f64, f64); 3] = [(0.0, 3.5e-3), (-0.5e-3, 4.2e-3), (0.6e-3, 5.0e-3)];

/// 16 elements; `convex`: on an arc of 4 mm radius. Transmits: two diverging
/// waves and one focused; records by the time models of `transmit` plus noise.
fn synthetic(convex: bool, seed: u64) -> ChannelData {
    let (fs, fc, ns) = (20e6, 5e6, 200);
    let mut probe = serde_json::json!({"kind": if convex { "convex" } else { "phased" },
        "n_elements": 16, "pitch_m": 0.3e-3, "element_width_m": 0.27e-3});
    if convex {
        probe["radius_m"] = 4e-3.into();
    }
    let meta: ChannelMeta = serde_json::from_value(serde_json::json!({
        "format": "usray-channels/1", "sampling_frequency_hz": fs, "t0_s": 0.0,
        "sound_speed_m_s": 1540.0, "center_frequency_hz": fc, "probe": probe,
        "transmits": [
            {"kind": "diverging", "virtual_source_m": [0.0, -3e-3], "t0_s": 0.3e-6},
            {"kind": "diverging", "virtual_source_m": [1e-3, -4e-3], "t0_s": 0.2e-6},
            {"kind": "focused", "focus_m": [0.0, 4e-3], "t0_s": -0.4e-6}
        ]
    }))
    .unwrap();
    meta.validate().unwrap();
    let els = ArrayGeometry::from_meta(&meta.probe).unwrap().elements();
    let mut r = Rng(seed);
    let mut samples = vec![0.0; 3 * 16 * ns];
    for (t, tx) in meta.transmits.iter().enumerate() {
        let w = TransmitWave::from_meta(t, tx).unwrap();
        for (e, el) in els.iter().enumerate() {
            for k in 0..ns {
                let tk = meta.t0_for(t) + k as f64 / fs;
                let mut v = 0.05 * r.next();
                for &(x, z) in &PTS {
                    let [ex, ez] = el.centre_m;
                    let tof = w.arrival_time_s([x, z], 1540.0) + (x - ex).hypot(z - ez) / 1540.0;
                    v += usray_signal::pulse::pulse(tk - tof, fc, 2.0);
                }
                samples[(t * 16 + e) * ns + k] = v;
            }
        }
    }
    ChannelData {
        meta,
        n_samples: ns,
        samples,
    }
}

fn settings() -> ImagingSettings {
    let mut s = ImagingSettings::new([-1.5e-3, 1.5e-3], [2.5e-3, 5.5e-3], 0.1e-3);
    s.f_number = 0.0;
    s.dynamic_range_db = 300.0;
    s
}

/// Bilinear interpolation reproduces `a + b·r + c·θ + d·r·θ` exactly.
#[test]
fn scan_conversion_is_exact_on_bilinear_images() {
    let g = PolarGrid::new(
        [0.0, -3e-3],
        linspace(3e-3, 9e-3, 31),
        linspace(-0.5, 0.4, 23),
    )
    .unwrap();
    let f = |r: f64, th: f64| 0.3 + 100.0 * r - 0.7 * th + 250.0 * r * th;
    let mut u = Vec::new();
    for &r in &g.r_m {
        for &th in &g.theta_rad {
            u.push(f(r, th));
        }
    }
    let (x, z) = (linspace(-4e-3, 4e-3, 41), linspace(0.0, 6e-3, 31));
    let sc = ScanConversion::new(&g, &x, &z);
    let mut out = vec![0.0; x.len() * z.len()];
    sc.forward(&u, &mut out);
    let (mut inside, mut outside) = (0, 0);
    for (iz, &zz) in z.iter().enumerate() {
        for (ix, &xx) in x.iter().enumerate() {
            let (r, th) = (xx.hypot(zz + 3e-3), xx.atan2(zz + 3e-3));
            let v = out[iz * x.len() + ix];
            if (3e-3..=9e-3).contains(&r) && (-0.5..=0.4).contains(&th) {
                assert!(
                    (v - f(r, th)).abs() < 1e-12,
                    "({xx}, {zz}): {v} vs {}",
                    f(r, th)
                );
                inside += 1;
            } else {
                assert_eq!(v, 0.0);
                outside += 1;
            }
        }
    }
    assert!(inside > 300 && outside > 100, "{inside} {outside}");
}

/// `⟨S u, y⟩ = ⟨u, Sᵀ y⟩`.
#[test]
fn scan_conversion_adjoint_dot_product() {
    let g = PolarGrid::new(
        [0.0, 0.0],
        linspace(1e-3, 8e-3, 40),
        linspace(-0.7, 0.7, 50),
    )
    .unwrap();
    let (x, z) = (linspace(-5e-3, 5e-3, 57), linspace(0.5e-3, 8e-3, 43));
    let sc = ScanConversion::new(&g, &x, &z);
    let mut r = Rng(3);
    let (u, y) = (r.vec(sc.polar_len()), r.vec(sc.cartesian_len()));
    let mut su = vec![0.0; sc.cartesian_len()];
    sc.forward(&u, &mut su);
    let mut sty = vec![0.0; sc.polar_len()];
    sc.vjp(&y, &mut sty);
    let (lhs, rhs) = (dot(&su, &y), dot(&u, &sty));
    assert!(rel(lhs, rhs) < 1e-13, "{lhs} vs {rhs}");
}

/// Each point target is the brightest pixel of its neighbourhood on the
/// scan-converted sector image (within one 0.1 mm pixel).
#[test]
fn sector_bmode_images_the_points_where_they_are() {
    for convex in [false, true] {
        let ch = synthetic(convex, 1);
        let b = BMode::new(&settings(), &ch.meta, ch.n_samples).unwrap();
        assert!(
            b.sector().is_some(),
            "phased and convex default to a sector"
        );
        let mut ws = b.workspace();
        let img = b.forward(&ch, &mut ws).unwrap();
        for &(xt, zt) in &PTS {
            let mut best = (f64::NEG_INFINITY, 0.0, 0.0);
            for (iz, &z) in img.z_m.iter().enumerate() {
                for (ix, &x) in img.x_m.iter().enumerate() {
                    if (x - xt).abs() < 0.4e-3 && (z - zt).abs() < 0.4e-3 {
                        let v = ws.envelope()[iz * img.nx + ix];
                        if v > best.0 {
                            best = (v, x, z);
                        }
                    }
                }
            }
            let err = (best.1 - xt).hypot(best.2 - zt);
            assert!(
                err <= 0.1e-3 * 1.5,
                "convex {convex}: ({xt}, {zt}) peak at ({}, {})",
                best.1,
                best.2
            );
        }
    }
}

/// FD check of the whole `B` on a sector along a random direction. Step
/// 1e-6 × the largest sample: measured relative errors 7.9e-4, 8.0e-6, 7.4e-8
/// at steps 1e-4, 1e-5, 1e-6 (phased), the h² decay of truncation; round-off
/// at 1e-6 is ~1e-10.
#[test]
fn sector_bmode_vjp_matches_fd() {
    for convex in [false, true] {
        let ch = synthetic(convex, 5);
        let b = BMode::new(&settings(), &ch.meta, ch.n_samples).unwrap();
        let mut ws = b.workspace();
        b.forward(&ch, &mut ws).unwrap();
        let q = post::argmax(ws.envelope());
        let emax = ws.envelope()[q];
        let mut r = Rng(9);
        // Weights on pixels with a healthy envelope only (log is smooth there).
        let w: Vec<f64> = ws
            .envelope()
            .iter()
            .map(|&e| if e > 1e-3 * emax { r.next() } else { 0.0 })
            .collect();
        let g = b.vjp(&mut ws, &w).unwrap();
        let v = r.vec(ch.samples.len());
        let h = 1e-6 * ch.samples.iter().fold(0.0f64, |a, b| a.max(b.abs()));
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
            "sector B (convex {convex}): fd {fd:.9e} vjp {an:.9e} rel {:.2e}",
            rel(fd, an)
        );
        assert!(rel(fd, an) < 1e-6, "fd {fd} vjp {an}");
    }
}

/// Calibration gradients (sound speed; pitch through the convex element
/// positions, by dual numbers) against central differences, on a Cartesian
/// grid (a sector's own geometry moves with the pitch).
#[test]
fn convex_calibration_gradients_match_fd() {
    let ch = synthetic(true, 12);
    let mut s = settings();
    s.grid = GridKind::Cartesian;
    s.pixel_m = 0.25e-3;
    let [(fdc, anc), (fdp, anp)] = calibration_against_fd(&ch, &s);
    eprintln!(
        "convex B: dL/dc fd {fdc:.6e} an {:.6e} (rel {:.1e}); dL/dpitch fd {fdp:.6e} an {:.6e} (rel {:.1e})",
        anc,
        rel(fdc, anc),
        anp,
        rel(fdp, anp)
    );
    assert!(rel(fdc, anc) < 1e-6, "c: fd {fdc} an {}", anc);
    assert!(rel(fdp, anp) < 1e-6, "pitch: fd {fdp} an {}", anp);
}
