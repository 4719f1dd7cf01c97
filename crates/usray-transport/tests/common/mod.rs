//! Shared helpers for the transport tests: scene text builders and a plain
//! plane-wave delay-and-sum used only by tests.
#![allow(dead_code)]

use usray_signal::ChannelData;
use usray_transport::ParamKey;

/// A scene from the tests' header with plane-wave emission (the default),
/// 2-D when `planar`, with `body` appended. The 2-D scene leaves out the
/// aperture's edge waves, which 3-D does not model (`tests/edge_waves.rs`).
pub fn plane_wave_scene(planar: bool, rays: usize, body: &str) -> usray_transport::Scene {
    let mut text = header(32, 0.27e-3, "[0.0]", rays, 3).replace("emission = \"cosine\"", "");
    if planar {
        text = text.replace(
            "sampler = \"independent\"",
            "sampler = \"independent\"\ndimensions = 2\nedge_waves = false",
        );
    }
    usray_transport::Scene::from_toml_str(&format!("{text}\n{body}"), "<planar>", ".").unwrap()
}

/// Traces every primary path of transmit 0 of `s` (its rays per element,
/// seed and sampler; `max_bounces` 4, every receiver per event) in `f64`,
/// calling `cast` on every ray the paths cast (segments and receiver
/// connections); returns the number of deposits.
pub fn for_each_cast(
    s: &usray_transport::Scene,
    mut cast: impl FnMut(&usray_geometry::Ray<f64>),
) -> usize {
    use usray_transport::integrator::{element_stack, trace_path_casts, TraceSettings};
    let st = s.lift_const::<f64>().unwrap();
    let a = &s.acquisition;
    let settings = TraceSettings {
        seed: a.seed,
        max_bounces: 4,
        rays_per_element: a.rays_per_element,
        receivers_per_event: 0,
        sampler: a.sampler,
    };
    let mut deposits = 0;
    for el in 0..s.probe.n_elements {
        for ray in 0..a.rays_per_element as u32 {
            let stack = element_stack(&st, el);
            let count = |_| deposits += 1;
            trace_path_casts(&st, &settings, 0, el, ray, stack, count, |r, _, _| cast(r));
        }
    }
    deposits
}

/// The key of a dotted parameter path (the tests name parameters by path).
pub fn key(path: &str) -> ParamKey {
    path.parse().unwrap_or_else(|e| panic!("{e}"))
}

/// The keys of dotted parameter paths.
pub fn keys(paths: &[&str]) -> Vec<ParamKey> {
    paths.iter().map(|p| key(p)).collect()
}

/// A scene header (medium, probe, acquisition) for tests.
pub fn header(n_elements: usize, width: f64, angles: &str, rays: usize, bounces: u32) -> String {
    format!(
        r#"
[medium]
sound_speed_m_s = 1540.0
impedance_mrayl = 1.5

[probe]
kind = "linear"
n_elements = {n_elements}
pitch_m = 0.3e-3
element_width_m = {width}
center_frequency_hz = 5.0e6
cycles = 3.0
main_lobe_deg = 5.0
cutoff_deg = 60.0
elevation_m = 4.0e-3

[acquisition]
angles_deg = {angles}
sampling_frequency_hz = 40.0e6
max_depth_m = 0.03
rays_per_element = {rays}
max_bounces = {bounces}
seed = 1
emission = "cosine"
sampler = "independent"
"#
    )
}

/// Σ of every deposit amplitude on each element of transmit 0 (the
/// impulse data of a render of `s` with `seed` sums to Σ a_k).
pub fn element_echoes(s: &usray_transport::Scene, seed: u64) -> Vec<f64> {
    let opts = usray_transport::RenderOptions {
        seed: Some(seed),
        impulse_only: true,
        threads: Some(2),
        ..Default::default()
    };
    let (d, _) = usray_transport::render(s, &opts).unwrap();
    (0..d.n_elements())
        .map(|e| d.record(0, e).iter().sum())
        .collect()
}

/// Path of a file in the workspace `scenes/` directory.
pub fn scene_path(name: &str) -> std::path::PathBuf {
    usray_testdata::workspace_file("scenes").join(name)
}

/// Plane-wave delay-and-sum (test-only, f64): envelope image `[nz][nx]` from the
/// RF data, by beamforming the RF and its quarter-period-delayed copy (a
/// narrow-band quadrature pair). Full receive aperture within `f_number`.
pub fn das_envelope(
    data: &ChannelData,
    c: f64,
    xs: &[f64],
    zs: &[f64],
    f_number: f64,
) -> Vec<Vec<f64>> {
    let m = &data.meta;
    let fs = m.sampling_frequency_hz;
    let n_el = data.n_elements();
    let pitch = m.probe.pitch_m;
    let quarter = 1.0 / (4.0 * m.center_frequency_hz);
    let sample = |rec: &[f64], t: f64| -> f64 {
        let s = (t - m.t0_s) * fs;
        if s < 0.0 || s >= (rec.len() - 1) as f64 {
            return 0.0;
        }
        let i = s.floor() as usize;
        let f = s - i as f64;
        rec[i] * (1.0 - f) + rec[i + 1] * f
    };
    zs.iter()
        .map(|&z| {
            xs.iter()
                .map(|&x| {
                    let (mut i_sum, mut q_sum) = (0.0, 0.0);
                    for (tx, t) in m.transmits.iter().enumerate() {
                        let th = t.angle_rad;
                        let t_tx = (x * th.sin() + z * th.cos()) / c;
                        for e in 0..n_el {
                            let xe = (e as f64 - (n_el as f64 - 1.0) / 2.0) * pitch;
                            if f_number > 0.0 && (x - xe).abs() > z / (2.0 * f_number) {
                                continue;
                            }
                            let t_rx = ((x - xe).powi(2) + z * z).sqrt() / c;
                            let rec = data.record(tx, e);
                            i_sum += sample(rec, t_tx + t_rx);
                            q_sum += sample(rec, t_tx + t_rx + quarter);
                        }
                    }
                    (i_sum * i_sum + q_sum * q_sum).sqrt()
                })
                .collect()
        })
        .collect()
}

/// Mean and standard error of a sample.
pub fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// Fixed pseudo-random weights in [−0.5, 0.5) (xorshift), the loss L = Σ w·P.
pub fn weights(n: usize, seed: u64) -> Vec<f64> {
    let mut x = seed;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect()
}

/// (AD, FD, relative difference) of `L = Σ w·P` (`w` = [`weights`] seed 12345)
/// for each parameter: `channel_gradient` against central differences of the
/// same realisation (4 rays per element, 2 threads) with the absolute step given
/// with the parameter.
pub fn ad_and_fd(scene: &usray_transport::Scene, params: &[(&str, f64)]) -> Vec<(f64, f64, f64)> {
    use usray_transport::{channel_gradient, render, RenderOptions, Scene};
    let opts = RenderOptions {
        rays_per_element: Some(4),
        threads: Some(2),
        ..Default::default()
    };
    let (d, _) = render(scene, &opts).unwrap();
    let w = weights(d.samples.len(), 12345);
    let loss = |s: &Scene| -> f64 {
        let (d, _) = render(s, &opts).unwrap();
        d.samples.iter().zip(&w).map(|(p, w)| p * w).sum()
    };
    let names: Vec<&str> = params.iter().map(|p| p.0).collect();
    let g = channel_gradient(scene, &keys(&names), &w, &opts).unwrap();
    params
        .iter()
        .zip(&g)
        .map(|(&(p, h), &ad)| {
            let k = key(p);
            let v = scene.get(&k).unwrap();
            let (mut sp, mut sm) = (scene.clone(), scene.clone());
            sp.set(&k, v + h).unwrap();
            sm.set(&k, v - h).unwrap();
            let fd = (loss(&sp) - loss(&sm)) / (2.0 * h);
            let r = (ad - fd).abs() / fd.abs();
            eprintln!("{p}: AD {ad:.9e}, FD {fd:.9e}, relative difference {r:.2e}");
            (ad, fd, r)
        })
        .collect()
}

/// Upper-tail probability of χ² with `k` degrees of freedom by the
/// Wilson–Hilferty normal approximation (accurate to ~1e-3 for k ≥ 30).
pub fn chi2_pvalue(x: f64, k: f64) -> f64 {
    let z = ((x / k).powf(1.0 / 3.0) - (1.0 - 2.0 / (9.0 * k))) / (2.0 / (9.0 * k)).sqrt();
    0.5 * erfc(z / std::f64::consts::SQRT_2)
}

/// Complementary error function (Numerical Recipes erfcc, |error| < 1.2e-7):
/// `t·exp(−z² + P(t))` with `t = 1/(1 + z/2)` and the polynomial `P` by Horner's
/// rule from its highest coefficient.
fn erfc(x: f64) -> f64 {
    const P: [f64; 10] = [
        0.17087277,
        -0.82215223,
        1.48851587,
        -1.13520398,
        0.27886807,
        -0.18628806,
        0.09678418,
        0.37409196,
        1.00002368,
        -1.26551223,
    ];
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = P.iter().fold(0.0, |acc, c| acc * t + c);
    let r = t * (-z * z + poly).exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// χ² test of sampled `counts` against `expected` counts of the same bins
/// (`n` samples in all): bins expecting fewer than 5 are merged into one; the
/// expected counts must sum to `n` within 0.2% (the density integrates to 1)
/// and the p-value must exceed 1e-3.
pub fn assert_counts_follow(counts: &[f64], expected: &[f64], n: usize, what: &str) {
    let (mut chi2, mut dof, mut small_o, mut small_e) = (0.0, 0usize, 0.0, 0.0);
    for (o, e) in counts.iter().zip(expected) {
        if *e < 5.0 {
            small_o += o;
            small_e += e;
        } else {
            chi2 += (o - e).powi(2) / e;
            dof += 1;
        }
    }
    if small_e >= 5.0 {
        chi2 += (small_o - small_e).powi(2) / small_e;
        dof += 1;
    }
    let total = expected.iter().sum::<f64>() / n as f64;
    let p = chi2_pvalue(chi2, (dof - 1) as f64);
    eprintln!(
        "{what}: χ² = {chi2:.1}, dof {}, p = {p:.3}, Σexpected/N = {total:.5}",
        dof - 1
    );
    assert!(
        (total - 1.0).abs() < 2e-3,
        "{what}: density integrates to {total}"
    );
    assert!(p > 1e-3, "{what}: χ² test failed: p = {p}");
}

/// Mean and standard error, over `n` samples keyed by `PathSampler::new(5, 1,
/// 2, k)`, of the summed weight of both continuations of one split at `iface`
/// (`wi` incident, `normal` on its side): the Monte Carlo estimate of
/// `∫ f(wi, wo)|wo·n| dwo`.
pub fn mean_split_weight(
    iface: &usray_transport::ggx::Interface<f64>,
    wi: usray_geometry::Vec3<f64>,
    normal: usray_geometry::Vec3<f64>,
    n: usize,
) -> (f64, f64) {
    let (mut s1, mut s2) = (0.0, 0.0);
    for k in 0..n {
        let s = usray_transport::rng::PathSampler::new(5, 1, 2, k as u32);
        // Both continuations of the split: their weights add.
        let w = iface
            .scatter(wi, normal, s.uniform(1, 0), s.uniform(1, 1))
            .map(|x| {
                [x.reflected, x.transmitted]
                    .iter()
                    .flatten()
                    .map(|l| l.weight)
                    .sum::<f64>()
            })
            .unwrap_or(0.0);
        s1 += w;
        s2 += w * w;
    }
    let mean = s1 / n as f64;
    (mean, ((s2 / n as f64 - mean * mean) / n as f64).sqrt())
}
