//! The transmit aperture's edge waves in 2-D against their closed form: a
//! plane wave from a 32-element array onto a flat mirror 5 mm deep. Each
//! edge's wave returns from its image source, `R = √((x − x_edge)² + (2D)²)`
//! away, as `R_f E(ψ) cos θₑ sinc(π w sin θₑ/λ) / √(2πkR)` with
//! `E = −cos²θ u/(u² + ε²)`, `u = τ·(t − d)`, delayed by `1/(8 f_c)`
//! (`integrator::edge`): amplitude and time on every element, for both edges
//! and two steering angles, within error bars the test computes over seeds.

mod common;
use common::{header, mean_se};
use std::f64::consts::PI;
use usray_transport::{trace_all, RenderOptions, Scene};

const N_EL: usize = 32;
const PITCH: f64 = 0.3e-3;
const WIDTH: f64 = 0.27e-3;
const F_C: f64 = 5e6;
const C: f64 = 1540.0;
const DEPTH: f64 = 5e-3;
const MAX_DEPTH: f64 = 0.03;
const Z_WATER: f64 = 1.5;
const Z_MIRROR: f64 = 1.0e4;

fn scene(angle_deg: f64, edge_waves: bool) -> Scene {
    let text = header(N_EL, WIDTH, &format!("[{angle_deg}]"), 20000, 2)
        .replace(
            "emission = \"cosine\"",
            &format!("edge_waves = {edge_waves}"),
        )
        .replace("main_lobe_deg = 5.0\ncutoff_deg = 60.0\n", "")
        .replace("sampler = \"independent\"", "dimensions = 2");
    let body = format!(
        "[materials.mirror]\nimpedance_mrayl = {Z_MIRROR}\nsound_speed_m_s = {C}\n\n\
         [[objects]]\nname = \"mirror\"\nshape = \"plane\"\ncenter_m = [0.0, 0.0, {DEPTH}]\n\
         material = \"mirror\"\n"
    );
    Scene::from_toml_str(&format!("{text}\n{body}"), "<edge waves>", ".").unwrap()
}

/// The closed form's amplitude and time on the element centred at `x_e`
/// of the wave from the edge at `x_edge` (outward side `side`).
fn closed_form(angle_deg: f64, x_edge: f64, side: f64, x_e: f64) -> (f64, f64) {
    let th = angle_deg.to_radians();
    let k = 2.0 * PI * F_C / C;
    let eps = 1.0 / (2.0 * PI * k * 0.5 * MAX_DEPTH).sqrt();
    let r = (x_e - x_edge).hypot(2.0 * DEPTH);
    let sin_psi = (x_e - x_edge) / r;
    let u = side * (th.sin() - sin_psi);
    let e = -th.cos() * th.cos() * u / (u * u + eps * eps);
    // The element sees the image source at angle θₑ = ψ to its normal.
    let x = PI * WIDTH * F_C / C * sin_psi;
    let sinc = if x == 0.0 { 1.0 } else { x.sin() / x };
    let cos_e = (1.0 - sin_psi * sin_psi).sqrt();
    let r_f = (Z_MIRROR - Z_WATER) / (Z_MIRROR + Z_WATER);
    let amp = r_f * e * cos_e * sinc / (2.0 * PI * k * r).sqrt();
    let time = x_edge * th.sin() / C + r / C + 1.0 / (8.0 * F_C);
    (amp, time)
}

/// The two edges: emitting element, the edge's `x` (m), its outward side.
fn edges() -> [(usize, f64, f64); 2] {
    [
        (0, x_el(0) - WIDTH / 2.0, -1.0),
        (N_EL - 1, x_el(N_EL - 1) + WIDTH / 2.0, 1.0),
    ]
}

fn x_el(e: usize) -> f64 {
    (e as f64 - (N_EL as f64 - 1.0) / 2.0) * PITCH
}

/// For each edge's emitter, per receiving element, the summed amplitude and
/// the summed amplitude × time of the deposits that the emitter's paths leave
/// within 0.2 µs of the edge's closed-form time, seed `seed`.
fn window_sums(s: &Scene, angle_deg: f64, seed: u64) -> Vec<Vec<(f64, f64)>> {
    let st = s.lift_const::<f64>().unwrap();
    let opts = RenderOptions {
        seed: Some(seed),
        threads: Some(2),
        ..Default::default()
    };
    let (chunks, _, _) = trace_all(s, &st, &opts);
    edges()
        .iter()
        .map(|&(emitter, x_edge, side)| {
            let mut sums = vec![(0.0, 0.0); N_EL];
            for d in &chunks[emitter] {
                let e = d.element as usize;
                let t = closed_form(angle_deg, x_edge, side, x_el(e)).1;
                if (d.time - t).abs() < 0.2e-6 {
                    sums[e].0 += d.amplitude;
                    sums[e].1 += d.amplitude * d.time;
                }
            }
            sums
        })
        .collect()
}

/// Each edge's echo on each element, seed `seed`: the window sums with edge
/// waves less those of the same paths without them (the primary branches
/// draw the same numbers either way), as (amplitude, mean time).
fn edge_echoes(angle_deg: f64, seed: u64) -> Vec<Vec<(f64, f64)>> {
    let with = window_sums(&scene(angle_deg, true), angle_deg, seed);
    let without = window_sums(&scene(angle_deg, false), angle_deg, seed);
    with.iter()
        .zip(&without)
        .map(|(w, o)| {
            w.iter()
                .zip(o)
                .map(|(w, o)| {
                    let a = w.0 - o.0;
                    (a, (w.1 - o.1) / a)
                })
                .collect()
        })
        .collect()
}

#[test]
fn each_edges_wave_returns_from_a_mirror_as_its_closed_form() {
    for angle_deg in [0.0, 8.0] {
        let runs: Vec<Vec<Vec<(f64, f64)>>> =
            (1..=8).map(|seed| edge_echoes(angle_deg, seed)).collect();
        for (i, (_, x_edge, side)) in edges().into_iter().enumerate() {
            let mut tested = 0;
            for e in 0..N_EL {
                // Elements seeing the edge at |u| ≥ 0.15, away from the
                // insonified strip's boundary, where the element's face spans
                // u ± 0.004 and the coefficient's curvature there moves the
                // face's mean by ≤ (0.004/0.15)² ≈ 0.1%: allowed 0.5%.
                let th = f64::to_radians(angle_deg);
                let sin_psi = (x_el(e) - x_edge) / (x_el(e) - x_edge).hypot(2.0 * DEPTH);
                if (th.sin() - sin_psi).abs() < 0.15 {
                    continue;
                }
                tested += 1;
                let (want, t_want) = closed_form(angle_deg, x_edge, side, x_el(e));
                let (got, se) = mean_se(&runs.iter().map(|r| r[i][e].0).collect::<Vec<_>>());
                let (t_got, _) = mean_se(&runs.iter().map(|r| r[i][e].1).collect::<Vec<_>>());
                assert!(
                    (got - want).abs() < 4.0 * se + 0.005 * want.abs(),
                    "{angle_deg}°, edge {side}, element {e}: {got:.6} ± {se:.6}, closed form {want:.6}"
                );
                assert!(
                    se < 0.02 * want.abs(),
                    "element {e}: error {se} too large to test"
                );
                // Inverted inside the insonified strip, upright outside it.
                assert_eq!(got < 0.0, want < 0.0);
                // The time, to a fiftieth of a period.
                assert!(
                    (t_got - t_want).abs() < 0.02 / F_C,
                    "{angle_deg}°, edge {side}, element {e}: {t_got:.4e} s, closed form {t_want:.4e} s"
                );
            }
            assert!(
                tested >= 12,
                "{angle_deg}°, edge {side}: only {tested} elements tested"
            );
        }
    }
}

#[test]
fn only_the_end_elements_emit_edge_waves_and_only_when_asked() {
    // A 0° plane wave on a mirror returns every primary ray to the element
    // that emitted it: any deposit elsewhere is an edge wave's.
    for edge_waves in [false, true] {
        let s = scene(0.0, edge_waves);
        let st = s.lift_const::<f64>().unwrap();
        let opts = RenderOptions {
            seed: Some(1),
            threads: Some(1),
            rays_per_element: Some(200),
            ..Default::default()
        };
        let (chunks, _, _) = trace_all(&s, &st, &opts);
        for (emitter, chunk) in chunks.iter().enumerate() {
            let elsewhere = chunk
                .iter()
                .filter(|d| d.element as usize != emitter)
                .count();
            let is_end = emitter == 0 || emitter == N_EL - 1;
            assert_eq!(
                elsewhere > 0,
                edge_waves && is_end,
                "emitter {emitter}, edge waves {edge_waves}"
            );
        }
    }
}
