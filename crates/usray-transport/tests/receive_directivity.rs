//! The element's own receive directivity in the rendered data: a thin rough
//! rod's echo on each element, rendered with `receive_directivity = "element"`
//! against the same render (same seed, same paths) with a lobe that is 1 up to
//! 89.9°, is `sinc(π w sin α / λ)` of the angle `α` from the element's normal
//! to the rod, element by element, through its first zero and into the
//! negative side lobe, within error bars the test computes over seeds.

mod common;
use common::{element_echoes, header, mean_se};
use usray_transport::Scene;

/// The rod's depth and lateral position (under element 16's centre, so that
/// its rays meet it), m; the probe's centre frequency, Hz (λ = 0.154 mm: a
/// 0.27 mm element's first zero at sin α = 0.57).
const ROD_Z: f64 = 5e-3;
const ROD_X: f64 = 0.15e-3;
const F_C: f64 = 10e6;

/// 32 elements of 0.27 mm at 10 MHz, one 0° plane wave, a rough rod of radius
/// 0.002 mm; `lobe` replaces the lobe lines (empty: the element's own).
fn scene(planar: bool, lobe: &str) -> Scene {
    let mut text = header(32, 0.27e-3, "[0.0]", 20000, 3)
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
         radius_m = 0.002e-3\nmaterial = \"m\"\n"
    );
    Scene::from_toml_str(&format!("{text}\n{body}"), "<directivity>", ".").unwrap()
}

/// Per seed (1 to 8) and element, the rod's echo in `other` over its echo in
/// `base`: the same paths, weighed by the two receivers.
fn seed_ratios(base: &Scene, other: &Scene) -> Vec<Vec<f64>> {
    (1..=8)
        .map(|seed| {
            let (b, o) = (element_echoes(base, seed), element_echoes(other, seed));
            b.iter().zip(&o).map(|(b, o)| o / b).collect()
        })
        .collect()
}

#[test]
fn a_rods_echo_on_each_element_follows_the_elements_sinc() {
    let w_over_lambda = 0.27e-3 * F_C / 1540.0;
    for planar in [true, false] {
        let (flat_scene, sinc_scene) = (
            scene(planar, "main_lobe_deg = 89.9\ncutoff_deg = 90.0\n"),
            scene(planar, ""),
        );
        let ratios = seed_ratios(&flat_scene, &sinc_scene);
        let mut below_zero = 0;
        for e in 0..32 {
            let x_e = (e as f64 - 15.5) * 0.3e-3;
            let sin_a = (x_e - ROD_X) / (x_e - ROD_X).hypot(ROD_Z);
            let x = std::f64::consts::PI * w_over_lambda * sin_a;
            let want = if x == 0.0 { 1.0 } else { x.sin() / x };
            let (got, se) = mean_se(&ratios.iter().map(|r| r[e]).collect::<Vec<_>>());
            // Systematic allowance: the echo leaves the rod's surface, within
            // its 0.002 mm radius of the axis (sin α off by ≤ 0.002/5 = 4e-4,
            // × |d sinc/d sin α| ≤ 2.4: 0.001), and a direct hit lands
            // anywhere on the 0.27 mm face (±0.027 in sin α, symmetric: second
            // order, ½ |sinc''| (π w/λ)² ⟨Δs²⟩ ≤ ½ · ⅓ · 30 · 2.4e-4 = 0.0012).
            // (A rod of 0.01 mm came out up to 0.007 below the sinc on the
            // flanks, more than its size explains; not yet understood.)
            assert!(
                (got - want).abs() < 4.0 * se + 0.0022,
                "planar {planar}, element {e}: {got} ± {se} against sinc {want}"
            );
            assert!(
                se < 0.005,
                "element {e}: Monte Carlo error {se} too large to test"
            );
            below_zero += usize::from(want < -0.05);
        }
        assert!(below_zero >= 4, "the test should reach the side lobe");
    }
}

/// In a rigid baffle (`probe.receive_baffle = "rigid"`) the element receives
/// its sinc without the obliquity `cos α`: the same renders (same seeds, same
/// paths) against the soft baffle's are `1/cos α` element by element, within
/// error bars over seeds, and a rigid baffle with the paper's lobe is refused.
#[test]
fn a_rigid_baffle_drops_the_obliquity_element_by_element() {
    for planar in [true, false] {
        let (soft_scene, rigid_scene) = (
            scene(planar, ""),
            scene(planar, "receive_baffle = \"rigid\"\n"),
        );
        let ratios = seed_ratios(&soft_scene, &rigid_scene);
        let mut oblique = 0;
        for e in 0..32 {
            let x_e = (e as f64 - 15.5) * 0.3e-3;
            let cos_a = ROD_Z / (x_e - ROD_X).hypot(ROD_Z);
            // Past the sinc's first zero the echo is too faint for a ratio.
            let sin_a = (1.0 - cos_a * cos_a).sqrt();
            if sin_a > 0.5 {
                continue;
            }
            let want = 1.0 / cos_a;
            let (got, se) = mean_se(&ratios.iter().map(|r| r[e]).collect::<Vec<_>>());
            // The allowance of the sinc test above, relative: the echo leaves
            // within the rod's radius and a direct hit lands anywhere on the
            // face, where 1/cos α moves by at most (sin α/cos² α)·0.027.
            let allowance = 0.0022 + sin_a / (cos_a * cos_a) * 0.027;
            assert!(
                (got - want).abs() < 4.0 * se + allowance * want,
                "planar {planar}, element {e}: {got} ± {se} against 1/cos α = {want}"
            );
            oblique += usize::from(want > 1.1);
        }
        assert!(oblique >= 4, "the test should reach oblique elements");
    }
    let lobe = Scene::from_toml_str(
        &scene(false, "").to_toml_string().replace(
            "[probe]\n",
            "[probe]\nreceive_baffle = \"rigid\"\nmain_lobe_deg = 5.0\n",
        ),
        "<lobe>",
        ".",
    );
    let err = lobe.unwrap_err().to_string();
    assert!(err.contains("probe.receive_baffle"), "{err}");
}
