//! `acquisition.receivers_per_event`: the stratified-receiver estimators (K = 1,
//! the paper's uniform choice, and K = 8) have the same mean as the all-receiver
//! sum, per element.

mod common;
use common::scene_path;
use usray_transport::{render, RenderOptions, Scene};

#[test]
fn stratified_receivers_are_unbiased() {
    let text = std::fs::read_to_string(scene_path("cylinder.toml"))
        .unwrap()
        .replace(
            "angles_deg = [-10.0, -5.0, 0.0, 5.0, 10.0]",
            "angles_deg = [0.0]",
        );
    let scene = Scene::from_toml_str(&text, "cylinder-0", scene_path("")).unwrap();
    // Sums of the impulse data over the proximal-wall window (8–12 mm) per block
    // of 16 elements (single elements see too few K = 1 events for a normal
    // z-score), 32 seeds.
    let n_seeds = 32;
    let stats = |k: Option<usize>| -> (Vec<f64>, Vec<f64>) {
        let mut per_seed = Vec::new();
        for seed in 0..n_seeds {
            let opts = RenderOptions {
                rays_per_element: Some(4),
                seed: Some(seed),
                receivers_per_event: k,
                impulse_only: true,
                threads: Some(2),
                ..Default::default()
            };
            let (d, _) = render(&scene, &opts).unwrap();
            let fs = d.meta.sampling_frequency_hz;
            let (lo, hi) = (
                (2.0 * 8e-3 / 1540.0 * fs) as usize,
                (2.0 * 12e-3 / 1540.0 * fs) as usize,
            );
            let sums: Vec<f64> = (0..d.n_elements() / 16)
                .map(|b| {
                    (16 * b..16 * (b + 1))
                        .map(|e| d.record(0, e)[lo..hi].iter().sum::<f64>())
                        .sum()
                })
                .collect();
            per_seed.push(sums);
        }
        let n_el = per_seed[0].len();
        let mean: Vec<f64> = (0..n_el)
            .map(|e| per_seed.iter().map(|s| s[e]).sum::<f64>() / n_seeds as f64)
            .collect();
        let sem: Vec<f64> = (0..n_el)
            .map(|e| {
                let v = per_seed
                    .iter()
                    .map(|s| (s[e] - mean[e]).powi(2))
                    .sum::<f64>()
                    / (n_seeds as f64 - 1.0);
                (v / n_seeds as f64).sqrt()
            })
            .collect();
        (mean, sem)
    };
    let (m_all, s_all) = stats(None);
    for k in [1, 8] {
        let (m, s) = stats(Some(k));
        // Pooled over blocks: z-scores of the differences of the means.
        let z: Vec<f64> = (0..m.len())
            .filter(|&e| s[e] > 0.0)
            .map(|e| (m[e] - m_all[e]) / (s[e] * s[e] + s_all[e] * s_all[e]).sqrt())
            .collect();
        let mean_z = z.iter().sum::<f64>() / z.len() as f64;
        let rms_z = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
        let total: f64 = m.iter().sum();
        let total_all: f64 = m_all.iter().sum();
        eprintln!(
            "K = {k}: total {total:.4e} vs all {total_all:.4e}; z over {} blocks: mean {mean_z:.2}, rms {rms_z:.2}",
            z.len()
        );
        // Unbiased: each block's z-score is ≈ N(0, 1); with 6–8 blocks (the
        // outermost see no echo), |mean z| below 1.5 (≈ 4 standard errors of
        // 1/√6) and rms below 2.
        assert!(
            mean_z.abs() < 1.5 && rms_z < 2.0,
            "K = {k}: mean z {mean_z}, rms z {rms_z}"
        );
    }
}
