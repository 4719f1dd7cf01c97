//! The stratified sampler (`acquisition.sampler = "stratified"`, the default)
//! against the independent one on the blind benchmark's cylinder: the same
//! expectation, less variance.
//!
//! The statistic is linear in the channel data, so its expectation is the same
//! functional of the expected data for both samplers: `L(P) = Σ P·w`, with the
//! template `w` the mean of independent renders on seeds of their own (a
//! template made from the compared renders would correlate with them). Each
//! sampler renders `SEEDS` seeds; the means must agree within 4 standard errors
//! of their difference (computed from the two samples' spreads), and the
//! stratified variance must be lower by more than the 0.99 quantile of
//! `F(SEEDS − 1, SEEDS − 1)` — a one-sided F test that a sampler which only
//! reordered the same noise would fail 99 times in 100. (At this size the
//! variance ratio is about 5, measured on 96 seeds; the test's seeds are fixed,
//! so it is deterministic.)

mod common;
use common::scene_path;
use usray_transport::scene::Sampler;
use usray_transport::{render, RenderOptions, Scene};

const SEEDS: u64 = 48;

/// 0.99 quantile of F(47, 47) (scipy `f.ppf(0.99, 47, 47)` = 1.991).
const F_99_47_47: f64 = 1.991;

fn renders(scene: &Scene, sampler: Sampler, seeds: std::ops::Range<u64>) -> Vec<Vec<f64>> {
    let mut s = scene.clone();
    s.acquisition.sampler = sampler;
    seeds
        .map(|seed| {
            let opts = RenderOptions {
                seed: Some(seed),
                ..Default::default()
            };
            render(&s, &opts).unwrap().0.samples
        })
        .collect()
}

fn mean_var(v: &[f64]) -> (f64, f64) {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
    (m, var)
}

#[test]
fn stratified_keeps_the_expectation_and_lowers_the_variance() {
    let mut scene = Scene::load(scene_path("diagnose/blind_base.toml")).unwrap();
    // CI size: one transmit, 8 rays per element.
    scene.acquisition.angles_deg = vec![0.0];
    scene.acquisition.rays_per_element = 8;
    let template_runs = renders(&scene, Sampler::Independent, 500..500 + SEEDS);
    let n = template_runs[0].len();
    let w: Vec<f64> = (0..n)
        .map(|k| template_runs.iter().map(|r| r[k]).sum::<f64>() / SEEDS as f64)
        .collect();
    let functional = |runs: Vec<Vec<f64>>| -> Vec<f64> {
        runs.iter()
            .map(|r| r.iter().zip(&w).map(|(p, w)| p * w).sum())
            .collect()
    };
    let (m_i, v_i) = mean_var(&functional(renders(&scene, Sampler::Independent, 0..SEEDS)));
    let (m_s, v_s) = mean_var(&functional(renders(&scene, Sampler::Stratified, 0..SEEDS)));
    let se = ((v_i + v_s) / SEEDS as f64).sqrt();
    eprintln!(
        "L: independent {m_i:.5e} ± {:.2e} (sd), stratified {m_s:.5e} ± {:.2e}; difference {:.2} SE; variance ratio {:.1}",
        v_i.sqrt(),
        v_s.sqrt(),
        (m_i - m_s) / se,
        v_i / v_s
    );
    assert!(m_i > 0.0, "the template must match the data");
    assert!(
        (m_i - m_s).abs() < 4.0 * se,
        "means differ by {:.2} standard errors",
        (m_i - m_s) / se
    );
    assert!(
        v_i / v_s > F_99_47_47,
        "variance ratio {:.2} is not significantly above 1 (F 0.99 quantile {F_99_47_47})",
        v_i / v_s
    );
}
