//! Effects switched on by scene keys: attenuation, depth gain, volume scattering
//! (speckle) and an imaging sound speed that differs from the medium's.

mod common;
use common::{das_envelope, header};
use usray_transport::{render, trace_all, RenderOptions, Scene};

fn plane_text(extra_medium: &str, extra_acq: &str) -> String {
    let mut h = header(16, 0.27e-3, "[0.0]", 300, 2).replace(
        "impedance_mrayl = 1.5\n",
        &format!("impedance_mrayl = 1.5\n{extra_medium}\n"),
    );
    if extra_acq.contains("emission") {
        h = h.replace("emission = \"cosine\"\n", "");
    }
    let h = h.replace("seed = 1\n", &format!("seed = 1\n{extra_acq}\n"));
    format!(
        "{h}\n[materials.m]\nimpedance_mrayl = 4.5\nsound_speed_m_s = 1540.0\n\n\
         [[objects]]\nname = \"floor\"\nshape = \"plane\"\ncenter_m = [0.0, 0.0, 0.01]\nmaterial = \"m\"\n"
    )
}

/// Per-deposit ratio against the same paths without the effect (common random
/// numbers make the deposit lists correspond one to one).
/// Also each deposit's spectral shift ([`usray_transport::Deposit::shift`]).
fn ratios(with: &str) -> Vec<(f64, f64, f64)> {
    let a = Scene::from_toml_str(with, "<with>", ".").unwrap();
    let b = Scene::from_toml_str(&plane_text("", ""), "<without>", ".").unwrap();
    let opts = RenderOptions::default();
    let (da, _, _) = trace_all(&a, &a.lift_const::<f64>().unwrap(), &opts);
    let (db, _, _) = trace_all(&b, &b.lift_const::<f64>().unwrap(), &opts);
    let mut out = Vec::new();
    for (ca, cb) in da.iter().zip(&db) {
        assert_eq!(ca.len(), cb.len());
        for (x, y) in ca.iter().zip(cb) {
            assert_eq!(x.time, y.time);
            assert_eq!(y.shift, 0.0);
            out.push((x.time, x.amplitude / y.amplitude, x.shift));
        }
    }
    assert!(out.len() > 10);
    out
}

#[test]
fn attenuation_follows_db_per_cm_per_mhz() {
    // α = 0.5 dB/(cm·MHz) over the whole path length d = c·τ (0° transmit: τ
    // is the path time). Exponent β = α·d_cm·(ln 10/20)/1 MHz in Np/Hz; the
    // echo of a Gaussian pulse (σ_f = 0.6246 MHz for 3 cycles at 5 MHz) has
    // amplitude e^{−β f_c + β²σ_f²/2} and carrier shift x = −βσ_f spectral
    // standard deviations (Kuc 1984; `usray_transport::downshift`).
    let sigma_f = usray_signal::pulse::pulse_bandwidth_hz(5e6_f64, 3.0);
    for (tau, r, x) in ratios(&plane_text("attenuation_db_cm_mhz = 0.5", "")) {
        let d_cm = 1540.0 * tau * 100.0;
        let beta = 0.5 * d_cm * std::f64::consts::LN_10 / 20.0 / 1e6;
        let expected = (-beta * 5e6 + 0.5 * (beta * sigma_f).powi(2)).exp();
        assert!((r / expected - 1.0).abs() < 1e-9, "ratio {r} vs {expected}");
        assert!(
            (x + beta * sigma_f).abs() < 1e-9,
            "shift {x} vs {}",
            -beta * sigma_f
        );
    }
}

/// Kuc's closed form (*IEEE Trans. Sonics Ultrason.* 31, 1984): a Gaussian
/// pulse through a frequency-linear attenuation with exponent `β` (Np/Hz) comes
/// back with its spectrum's centre moved down by `βσ_f²`. The echo of a flat
/// interface 10.01 mm deep through α = 3 dB/(cm·MHz) (β = 6.91·10⁻⁷ Np/Hz:
/// 270 kHz), measured as the power-weighted mean frequency of the centre element's
/// record against the same scene without attenuation. The only approximation
/// between the two is the pulse's interpolation between the down-shift nodes,
/// below 5·10⁻⁴ of the pulse in L2 (`downshift` unit test); a relative pulse
/// error `ε` moves a spectral mean by at most about `2εσ_f` (≈ 0.6 kHz), so
/// the test allows 1 kHz.
#[test]
fn attenuation_moves_the_echo_spectrum_down_by_beta_sigma_f_squared() {
    let centroid = |medium: &str| {
        // A collimated bundle and a floor 10.01 mm deep: every deposit on the
        // centre element arrives at 2d/c = 13 µs, on a sample (no echo pairs,
        // no splat filter to tilt the spectrum).
        let text = plane_text(medium, "emission = \"plane_wave\"").replace(
            "center_m = [0.0, 0.0, 0.01]",
            "center_m = [0.0, 0.0, 0.01001]",
        );
        let s = Scene::from_toml_str(&text, "<plane>", ".").unwrap();
        let (d, _) = render(&s, &RenderOptions::default()).unwrap();
        let rec = &d.samples[8 * d.n_samples..9 * d.n_samples];
        let n = rec.len();
        let fs = d.meta.sampling_frequency_hz;
        let (mut num, mut den) = (0.0, 0.0);
        for k in 1..n / 2 {
            let w = -2.0 * std::f64::consts::PI * k as f64 / n as f64;
            let (mut re, mut im) = (0.0, 0.0);
            for (j, v) in rec.iter().enumerate() {
                re += v * (w * j as f64).cos();
                im += v * (w * j as f64).sin();
            }
            let p = re * re + im * im;
            num += p * k as f64 * fs / n as f64;
            den += p;
        }
        num / den
    };
    let f0 = centroid("");
    let f1 = centroid("attenuation_db_cm_mhz = 3.0");
    let sigma_f = usray_signal::pulse::pulse_bandwidth_hz(5e6_f64, 3.0);
    let beta = 3.0 * 2.002 * std::f64::consts::LN_10 / 20.0 / 1e6;
    let expected = -beta * sigma_f * sigma_f;
    eprintln!(
        "mean frequency {f0:.1} Hz → {f1:.1} Hz: shift {:.1} Hz, Kuc {expected:.1} Hz",
        f1 - f0
    );
    assert!((f0 - 5e6).abs() < 1e3, "unattenuated mean frequency {f0}");
    assert!(
        ((f1 - f0) - expected).abs() < 1e3,
        "shift {} vs {expected}",
        f1 - f0
    );
}

#[test]
fn depth_gain_follows_db_per_cm_of_depth() {
    for (tau, r, x) in ratios(&plane_text("", "depth_gain_db_per_cm = 1.5")) {
        assert_eq!(x, 0.0);
        let depth_cm = 1540.0 * tau / 2.0 * 100.0;
        let expected = 10f64.powf(1.5 * depth_cm / 20.0);
        assert!((r / expected - 1.0).abs() < 1e-9, "ratio {r} vs {expected}");
    }
}

fn speckle_text(density: f64, strength: f64) -> String {
    format!(
        "{}\n[materials.tissue]\nimpedance_mrayl = 1.5\nsound_speed_m_s = 1540.0\n\
         scatterer_density_per_mm3 = {density}\nscatterer_strength = {strength}\n\n\
         [[objects]]\nname = \"block\"\nshape = \"slab\"\nz_top_m = 0.008\nz_bottom_m = 0.016\nmaterial = \"tissue\"\n",
        header(64, 0.27e-3, "[0.0]", 50, 2)
    )
}

#[test]
fn volume_scattering_makes_a_fixed_speckle_pattern() {
    let render_env = |text: &str, seed: u64| {
        let s = Scene::from_toml_str(text, "<speckle>", ".").unwrap();
        let opts = RenderOptions {
            seed: Some(seed),
            ..Default::default()
        };
        let (d, _) = render(&s, &opts).unwrap();
        let xs: Vec<f64> = (0..41).map(|i| -2e-3 + i as f64 * 0.1e-3).collect();
        let zs: Vec<f64> = (0..121).map(|i| 6e-3 + i as f64 * 0.1e-3).collect();
        let env = das_envelope(&d, 1540.0, &xs, &zs, 1.5);
        (d, env)
    };
    // Impedance- and speed-matched block: without scatterers, no echo at all.
    let (d0, _) = render_env(&speckle_text(0.0, 0.0), 1);
    assert!(d0.samples.iter().all(|v| *v == 0.0));
    let text = speckle_text(2.0, 0.5);
    let (_, a) = render_env(&text, 1);
    let (_, b) = render_env(&text, 2);
    // Echo inside the block (z 8..16 mm, rows 20..100), none above it (rows < 18).
    let mean = |img: &Vec<Vec<f64>>, r: std::ops::Range<usize>| {
        let n = (r.len() * img[0].len()) as f64;
        img[r].iter().flatten().sum::<f64>() / n
    };
    let inside = mean(&a, 25..95);
    let above = mean(&a, 0..18);
    eprintln!("speckle: inside {inside:.3e}, above {above:.3e}");
    assert!(inside > 10.0 * above.max(1e-300));
    // Same pattern for another seed: correlation of the envelopes inside the block.
    // Measured, not asserted: with cosine-lobe emission the coherent part of each
    // scatterer's echo is a small share of its Monte Carlo sum (correlation 0.15
    // at 50 rays/element with every scatterer connected to every element), so
    // the pattern emerges only slowly with the ray count. The field itself is
    // fixed: see `scatterer_field_is_fixed`.
    let va: Vec<f64> = a[25..95].iter().flatten().cloned().collect();
    let vb: Vec<f64> = b[25..95].iter().flatten().cloned().collect();
    let corr = pearson(&va, &vb);
    eprintln!("speckle: envelope correlation between seeds = {corr:.3}");
    assert!(corr.is_finite());
    // With plane-wave emission every scatterer sees one coherent arrival, and the
    // pattern is fixed: stated threshold 0.8 on the envelope correlation
    // (measured 0.94 at 100 rays/element with all-receiver connections; with
    // one uniformly chosen receiver per event it was 0.46 at 200, 0.86 at 1000).
    let pw = text
        .replace("emission = \"cosine\"", "emission = \"plane_wave\"")
        .replace("rays_per_element = 50", "rays_per_element = 100");
    let (_, a) = render_env(&pw, 1);
    let (_, b) = render_env(&pw, 2);
    let va: Vec<f64> = a[25..95].iter().flatten().cloned().collect();
    let vb: Vec<f64> = b[25..95].iter().flatten().cloned().collect();
    let corr = pearson(&va, &vb);
    eprintln!("speckle (plane-wave emission): envelope correlation between seeds = {corr:.3}");
    assert!(corr > 0.8, "speckle not fixed: correlation {corr}");
}

#[test]
fn scatterer_field_is_fixed_and_has_the_stated_density() {
    use usray_transport::effects::ScattererField;
    let f = ScattererField::new(3, 2.0).unwrap();
    let g = ScattererField::new(3, 2.0).unwrap();
    let p = [1.2e-3, -0.4e-3, 9.7e-3];
    let (qa, ga) = f.scatterer_near::<f64>(p);
    let (qb, gb) = g.scatterer_near::<f64>(p);
    assert_eq!((qa.value(), ga), (qb.value(), gb));
    // One scatterer per cell of volume 1/ρ: ρ = 2 per mm³ → h³ = 0.5 mm³.
    assert!((f.cell_m.powi(3) * 1e9 - 0.5).abs() < 1e-12);
    // Amplitudes have zero mean and unit variance over many cells.
    let n = 20_000;
    let gs: Vec<f64> = (0..n)
        .map(|i| {
            f.scatterer_near::<f64>([i as f64 * f.cell_m * 1.01, 0.0, 0.0])
                .1
        })
        .collect();
    let m = gs.iter().sum::<f64>() / n as f64;
    let v = gs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n as f64;
    assert!(
        m.abs() < 4.0 / (n as f64).sqrt() && (v - 1.0).abs() < 0.05,
        "mean {m} var {v}"
    );
}

#[test]
fn speckle_power_is_linear_in_density_across_grid_sizes() {
    // Expected echo power of a scatterer field ∝ ρ·s² (incoherent sum of random
    // phasors). ρ = 3 per mm³ lives on a grid of 4 (weights √(3/4)), ρ = 9 on a
    // grid of 16 (√(9/16)): different scatterers, expected power ratio 3 (the
    // grids' ratio is 4).
    // Statistic: the channel energy in 0.5 mm depth windows through the block
    // (16 windows, nearly independent speckle); the test's error bar is the
    // standard error of the mean log-ratio over the windows. What is left of the
    // events' Monte Carlo noise biases the ratio up (its power goes as
    // μ·A² ∝ ρ·ρ_g^{2/3}): measured 3.48 at 100 rays/element, 3.17 at 400,
    // 3.13 at 1000, each ± 0.06 in the log.
    let energy = |density: f64| {
        // Plane-wave emission: each scatterer sees one coherent arrival, so the
        // energy is the speckle's, not the Monte Carlo noise of the events (with
        // the cosine lobe the noise dominates: its power goes as μ·A², not ρ·A²).
        let text = speckle_text(density, 0.5)
            .replace("emission = \"cosine\"", "emission = \"plane_wave\"")
            .replace("rays_per_element = 50", "rays_per_element = 400");
        let s = Scene::from_toml_str(&text, "<speckle>", ".").unwrap();
        let (d, _) = render(&s, &RenderOptions::default()).unwrap();
        let (fs, t0, n_t) = (d.meta.sampling_frequency_hz, d.meta.t0_s, d.n_samples);
        (0..16)
            .map(|w| {
                // Round trip to depths 8.25 + 0.5·w … 8.75 + 0.5·w mm (clear of
                // the block's faces).
                let z0 = 8.25e-3 + 0.5e-3 * w as f64;
                let (i0, i1) = (
                    ((2.0 * z0 / 1540.0 - t0) * fs) as usize,
                    ((2.0 * (z0 + 0.5e-3) / 1540.0 - t0) * fs) as usize,
                );
                d.samples
                    .chunks(n_t)
                    .map(|ch| ch[i0..i1].iter().map(|v| v * v).sum::<f64>())
                    .sum::<f64>()
            })
            .collect::<Vec<f64>>()
    };
    let (a, b) = (energy(3.0), energy(9.0));
    let logs: Vec<f64> = a.iter().zip(&b).map(|(x, y)| (y / x).ln()).collect();
    let n = logs.len() as f64;
    let m = logs.iter().sum::<f64>() / n;
    let se = (logs.iter().map(|l| (l - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    let expected = 3.0f64.ln();
    eprintln!(
        "power ratio ρ=9 / ρ=3: {:.3} (expected {:.3}), log ± {se:.3}",
        m.exp(),
        expected.exp()
    );
    assert!(
        (m - expected).abs() < 3.0 * se,
        "log ratio {m} vs {expected} ± {se}"
    );
    // The test can fail: a model whose power does not scale with ρ (ratio 1), or
    // scales with the grid (ratio 4), lies outside the error bar.
    assert!(
        3.0 * se < 4.0f64.ln() - expected && 3.0 * se < expected,
        "se {se}"
    );
}

fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

#[test]
fn imaging_sound_speed_only_moves_the_image() {
    // Medium 1540 m/s, beamformer assumes 1480 m/s: a wall at 10 mm appears at
    // 10·1480/1540 = 9.61 mm (the echo time is unchanged).
    let text = plane_text("", "").replace(
        "[materials.m]",
        "[imaging]\nx_range_m = [-0.002, 0.002]\nz_range_m = [0.005, 0.015]\npixel_m = 1e-4\nf_number = 1.5\ndynamic_range_db = 60.0\nsound_speed_m_s = 1480.0\n\n[materials.m]",
    );
    let s = Scene::from_toml_str(&text, "<c>", ".").unwrap();
    let (d, _) = render(&s, &RenderOptions::default()).unwrap();
    let zs: Vec<f64> = (0..400).map(|i| 8e-3 + i as f64 * 0.01e-3).collect();
    let img = das_envelope(&d, s.imaging_sound_speed(), &[0.0], &zs, 1.5);
    let iz = (0..zs.len())
        .max_by(|&a, &b| img[a][0].total_cmp(&img[b][0]))
        .unwrap();
    eprintln!("apparent wall depth {:.3} mm", zs[iz] * 1e3);
    assert!((zs[iz] - 0.010 * 1480.0 / 1540.0).abs() < 0.1e-3);
}

/// An extreme attenuation (300 dB/(cm·MHz); bone is 10–20) makes the
/// down-shift exceed its model's range (`downshift::max_shift`). On a rough
/// floor 1 cm deep, receiver connections carry paths of shift `s ≈ 43`, whose
/// factor `e^{s²/2}` alone overflows: the render stays finite, with a bounded
/// number of down-shift records, and the echo (−3000 dB) is gone.
#[test]
fn extreme_attenuation_renders_finite_data() {
    let text = plane_text("attenuation_db_cm_mhz = 300.0", "").replace(
        "sound_speed_m_s = 1540.0\n\n[[objects]]",
        "sound_speed_m_s = 1540.0\nroughness = 0.3\n\n[[objects]]",
    );
    assert!(text.contains("roughness = 0.3"));
    let s = Scene::from_toml_str(&text, "<extreme>", ".").unwrap();
    assert_eq!(
        usray_transport::AcquisitionPlan::new(&s).pulse.nodes(false),
        10
    );
    let (d, stats) = render(&s, &RenderOptions::default()).unwrap();
    assert!(stats.deposits > 0);
    assert!(d.samples.iter().all(|v| v.is_finite()));
    assert!(d.samples.iter().all(|v| v.abs() < 1e-30));
}
