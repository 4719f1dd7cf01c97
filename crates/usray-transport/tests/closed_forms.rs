//! Closed-form checks of the transport: flat-interface echo time and amplitude,
//! refraction delay through a slab (Snell/Fermat), and the energy balance.

mod common;
use common::{header, mean_se};
use proptest::prelude::*;
use usray_transport::fresnel::{energy_transmission_factor, fresnel};
use usray_transport::{render, trace_all, RenderOptions, Scene};

const C: f64 = 1540.0;
const FS: f64 = 40.0e6;

fn plane_scene(depth: f64, z2: f64) -> Scene {
    let text = format!(
        "{}\n[materials.m]\nimpedance_mrayl = {z2}\nsound_speed_m_s = 1540.0\n\n\
         [[objects]]\nname = \"floor\"\nshape = \"plane\"\ncenter_m = [0.0, 0.0, {depth}]\nmaterial = \"m\"\n",
        header(32, 0.27e-3, "[0.0]", 2000, 2)
    );
    Scene::from_toml_str(&text, "<plane>", ".").unwrap()
}

/// Sum of every deposit amplitude (the impulse data sums to Σ a_k) and the time
/// of the first non-zero sample over all records.
fn echo(scene: &Scene, seed: u64) -> (f64, usize) {
    let opts = RenderOptions {
        seed: Some(seed),
        impulse_only: true,
        ..Default::default()
    };
    let (d, _) = render(scene, &opts).unwrap();
    let total: f64 = d.samples.iter().sum();
    let n = d.n_samples;
    let first = (0..d.samples.len())
        .filter(|&i| d.samples[i] != 0.0)
        .map(|i| i % n)
        .min()
        .unwrap_or(usize::MAX);
    (total, first)
}

#[test]
fn flat_interface_echo_time_and_reflection_coefficient() {
    let depth = 0.010;
    let (z1, z2, z_ref) = (1.5, 4.5, 1.0e4);
    let r = (z2 - z1) / (z2 + z1);
    let r_ref = (z_ref - z1) / (z_ref + z1);
    let (s, s_ref) = (plane_scene(depth, z2), plane_scene(depth, z_ref));
    let seeds: Vec<u64> = (1..=8).collect();
    let mut a = Vec::new();
    let mut b = Vec::new();
    for &seed in &seeds {
        let (x, k) = echo(&s, seed);
        let (y, k_ref) = echo(&s_ref, seed);
        // Echo time: the earliest arrival is the normal-incidence path, 2d/c.
        let k0 = 2.0 * depth / C * FS;
        for kk in [k, k_ref] {
            assert!(
                (kk as f64) >= k0 - 1.0 && (kk as f64) <= k0 + 2.0,
                "first echo sample {kk}, expected 2d/c·fs = {k0}"
            );
        }
        a.push(x);
        b.push(y);
    }
    // Ratio of means with a delta-method standard error from the per-seed spread.
    let (ma, sa) = mean_se(&a);
    let (mb, sb) = mean_se(&b);
    let ratio = ma / mb;
    let se = ratio * ((sa / ma).powi(2) + (sb / mb).powi(2)).sqrt();
    let expected = r / r_ref;
    eprintln!("flat interface: ratio {ratio:.4} ± {se:.4} (1σ), expected {expected:.4}");
    assert!(
        (ratio - expected).abs() < 4.0 * se,
        "ratio {ratio} vs {expected} ± 4·{se}"
    );
    assert!(
        se < 0.05 * expected,
        "Monte Carlo error too large to be a test: {se}"
    );
}

/// Two elements 12 mm apart over a layered medium: water 3 mm, a 6 mm layer at
/// 2000 m/s (same impedance), water, and a strong reflector at 12 mm. The
/// earliest echo from element 0 received on element 1 follows the Snell path.
#[test]
fn refracting_slab_delays_echo_as_snell_predicts() {
    let (h1, h2, zr, c2, x_sep) = (0.003, 0.006, 0.012, 2000.0, 0.012);
    let h3 = zr - h1 - h2;
    let width = 0.08e-3;
    let text = format!(
        r#"
[medium]
sound_speed_m_s = 1540.0
impedance_mrayl = 1.5
[probe]
kind = "linear"
n_elements = 2
pitch_m = {x_sep}
element_width_m = {width}
center_frequency_hz = 5.0e6
cycles = 3.0
main_lobe_deg = 5.0
cutoff_deg = 89.0
elevation_m = 4.0e-3
[acquisition]
angles_deg = [0.0]
sampling_frequency_hz = 40.0e6
max_depth_m = 0.03
rays_per_element = 150000
max_bounces = 6
seed = 3
emission = "cosine"
sampler = "independent"
[materials.layer]
impedance_mrayl = 1.5
sound_speed_m_s = {c2}
[materials.mirror]
impedance_mrayl = 1.0e4
sound_speed_m_s = 1540.0
[[objects]]
name = "layer"
shape = "slab"
z_top_m = {h1}
z_bottom_m = {zb}
material = "layer"
[[objects]]
name = "mirror"
shape = "plane"
center_m = [0.0, 0.0, {zr}]
material = "mirror"
"#,
        zb = h1 + h2
    );
    let scene = Scene::from_toml_str(&text, "<slab>", ".").unwrap();
    let st = scene.lift_const::<f64>().unwrap();
    let (chunks, _, _) = trace_all(&scene, &st, &RenderOptions::default());
    // Chunk 0 = transmit 0, emitter 0; keep its deposits on element 1 after the
    // layer echoes (which end before 14 µs).
    let t_min = chunks[0]
        .iter()
        .filter(|d| d.element == 1 && d.time > 14e-6)
        .map(|d| d.time)
        .fold(f64::INFINITY, f64::min);
    // Snell: horizontal offset 2(h1 tanθ1 + h2 tanθ2 + h3 tanθ1) = X with
    // sinθ2 = (c2/c1) sinθ1; solve by bisection, then the travel time.
    // Fermat time along the path obeying sinθ2 = k·sinθ1 (k = c2/c1 for Snell).
    let path_time = |k: f64| {
        let offset = |s1: f64| {
            let s2 = s1 * k;
            2.0 * ((h1 + h3) * s1 / (1.0 - s1 * s1).sqrt() + h2 * s2 / (1.0 - s2 * s2).sqrt())
        };
        let (mut lo, mut hi) = (0.0, (1.0f64).min(1.0 / k) - 1e-9);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if offset(mid) < x_sep {
                lo = mid
            } else {
                hi = mid
            }
        }
        let (s1, s2) = (lo, lo * k);
        let t = 2.0 * ((h1 + h3) / (1.0 - s1 * s1).sqrt() / C + h2 / (1.0 - s2 * s2).sqrt() / c2);
        (t, s1)
    };
    let (tau, s1) = path_time(c2 / C);
    // A wrong law (inverted speed ratio) gives a path of a different time:
    let (tau_straight, _) = path_time(C / c2);
    // The faces have width w: emission and landing points can be up to w closer,
    // which changes the time by at most w·sinθ1/c1 (first order) on each end.
    let tol = 2.0 * width * s1 / C + 2e-9;
    eprintln!(
        "slab: earliest {t_min:.4e} s, Snell {tau:.4e} s (inverted law {tau_straight:.4e}), tol {tol:.1e}"
    );
    assert!(t_min.is_finite(), "no echo received");
    assert!(
        (t_min - tau).abs() <= tol,
        "earliest {t_min} vs Snell {tau} (±{tol})"
    );
    assert!(
        (tau - tau_straight).abs() > 2.0 * tol,
        "test cannot distinguish Snell"
    );
}

proptest! {
    /// Kinsler §6.3: R² + T²·(Z1 cos θt)/(Z2 cos θi) = 1, and R² = 1 under TIR.
    #[test]
    fn energy_is_conserved(cos_i in 0.0f64..=1.0, c1 in 300.0f64..5000.0, c2 in 300.0f64..5000.0,
                           z1 in 0.1f64..10.0, z2 in 0.1f64..10.0) {
        let f = fresnel(cos_i, c1, c2, z1, z2);
        prop_assert!(f.r.is_finite() && f.t.is_finite() && f.cos_t.is_finite());
        if f.tir || cos_i == 0.0 {
            prop_assert!((f.r * f.r - 1.0).abs() < 1e-12);
        } else {
            let e = f.r * f.r + f.t * f.t * energy_transmission_factor(z1, z2, cos_i, f.cos_t);
            prop_assert!((e - 1.0).abs() < 1e-9, "energy {}", e);
        }
    }
}

#[test]
fn total_internal_reflection_reflects_everything() {
    // Critical angle for 1500 → 3000 m/s is 30°: incidence at 60° is beyond.
    let f = fresnel(60f64.to_radians().cos(), 1500.0, 3000.0, 1.5, 3.0);
    assert!(f.tir);
    assert_eq!(f.r * f.r, 1.0);
}
