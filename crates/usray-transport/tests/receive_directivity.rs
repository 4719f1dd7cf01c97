//! The element's own receive directivity in the rendered data: a thin rough
//! rod's echo on each element, rendered with `receive_directivity = "element"`
//! against the same render (same seed, same paths) with a lobe that is 1 up to
//! 89.9°, is `sinc(π w sin α / λ)` of the angle `α` from the element's normal
//! to the rod, element by element, through its first zero and into the
//! negative side lobe.

mod common;
use common::header;
use usray_transport::{render, RenderOptions, Scene};

/// The rod's depth and lateral position (under element 16's centre, so that
/// its rays meet it), m; the probe's centre frequency, Hz (λ = 0.154 mm: a
/// 0.27 mm element's first zero at sin α = 0.57).
const ROD_Z: f64 = 5e-3;
const ROD_X: f64 = 0.15e-3;
const F_C: f64 = 10e6;

/// 32 elements of 0.27 mm at 10 MHz, one 0° plane wave, a rough rod of radius
/// 0.01 mm; `lobe` replaces the lobe lines (empty: the element's own).
fn scene(planar: bool, lobe: &str) -> Scene {
    let mut text = header(32, 0.27e-3, "[0.0]", 2000, 3)
        .replace("emission = \"cosine\"", "")
        .replace(
            "center_frequency_hz = 5.0e6",
            &format!("center_frequency_hz = {F_C:e}"),
        )
        .replace("main_lobe_deg = 5.0\ncutoff_deg = 60.0\n", lobe)
        .replace("elevation_m = 4.0e-3", "elevation_m = 0.1e-3");
    if planar {
        text = text.replace(
            "sampler = \"independent\"",
            "sampler = \"independent\"\ndimensions = 2",
        );
    }
    let body = format!(
        "[materials.m]\nimpedance_mrayl = 3.0\nsound_speed_m_s = 1540.0\nroughness = 1.0\n\n\
         [[objects]]\nname = \"rod\"\nshape = \"cylinder\"\ncenter_m = [{ROD_X}, 0.0, {ROD_Z}]\n\
         radius_m = 0.01e-3\nmaterial = \"m\"\n"
    );
    Scene::from_toml_str(&format!("{text}\n{body}"), "<directivity>", ".").unwrap()
}

/// Σ of every deposit amplitude on each element (impulse data).
fn echoes(s: &Scene) -> Vec<f64> {
    let opts = RenderOptions {
        seed: Some(3),
        impulse_only: true,
        threads: Some(2),
        ..Default::default()
    };
    let (d, _) = render(s, &opts).unwrap();
    (0..32).map(|e| d.record(0, e).iter().sum()).collect()
}

#[test]
fn a_rods_echo_on_each_element_follows_the_elements_sinc() {
    let w_over_lambda = 0.27e-3 * F_C / 1540.0;
    for planar in [true, false] {
        let flat = echoes(&scene(planar, "main_lobe_deg = 89.9\ncutoff_deg = 90.0\n"));
        let sinc = echoes(&scene(planar, ""));
        let mut below_zero = 0;
        for e in 0..32 {
            let x_e = (e as f64 - 15.5) * 0.3e-3;
            let sin_a = (x_e - ROD_X) / (x_e - ROD_X).hypot(ROD_Z);
            let x = std::f64::consts::PI * w_over_lambda * sin_a;
            let want = if x == 0.0 { 1.0 } else { x.sin() / x };
            let got = sinc[e] / flat[e];
            // The echo leaves the rod's surface, up to 0.01 mm from its axis:
            // sin α within ±0.002 of the axis's, |d sinc/d sin α| ≤ 2.4.
            assert!(
                (got - want).abs() < 0.01,
                "planar {planar}, element {e}: {got} against sinc {want}"
            );
            below_zero += usize::from(want < -0.05);
        }
        assert!(below_zero >= 4, "the test should reach the side lobe");
    }
}
