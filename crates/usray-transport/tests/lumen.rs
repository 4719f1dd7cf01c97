//! Scatterers in a hollow cylinder's lumen (`objects.NAME.lumen_scatterer_*`):
//! where they are, how bright, in which medium, and what the scene accepts.

mod common;
use common::header;
use usray_signal::ChannelData;
use usray_transport::{render, RenderOptions, Scene};

/// A scene of 64 elements, one 0° plane wave (collimated emission), `rays`
/// per element, 4 bounces (enough to reach a lumen inside another object), a
/// medium at 1540 m/s and 1.5 MRayl, then `objects`.
fn scene(objects: &str, rays: usize) -> Scene {
    let text = format!(
        "{}\n[materials.matched]\nimpedance_mrayl = 1.5\nsound_speed_m_s = 1540.0\n\n{objects}",
        header(64, 0.27e-3, "[0.0]", rays, 4)
            .replace("emission = \"cosine\"", "emission = \"plane_wave\"")
    );
    Scene::from_toml_str(&text, "<lumen>", ".").unwrap()
}

/// A tube of the medium's own impedance and speed (no echo from its wall) at
/// 12 mm depth, outer radius 3 mm, wall 0.5 mm: the lumen is `ρ < 2.5 mm`.
fn tube(lumen: &str) -> String {
    format!(
        "[[objects]]\nname = \"tube\"\nshape = \"cylinder\"\ncenter_m = [0.0, 0.0, 0.012]\n\
         radius_m = 0.003\nthickness_m = 0.5e-3\nmaterial = \"matched\"\n{lumen}\n"
    )
}

const SPECKLE: &str = "lumen_scatterer_density_per_mm3 = 2.0\nlumen_scatterer_strength = 0.5";

/// Channel energy (all elements) in round-trip windows to depths `z0 … z0 + dz`
/// (m, at 1540 m/s), one per start in `z0s`.
fn energies(d: &ChannelData, z0s: &[f64], dz: f64) -> Vec<f64> {
    let (fs, t0, n_t) = (d.meta.sampling_frequency_hz, d.meta.t0_s, d.n_samples);
    let index = |z: f64| (((2.0 * z / 1540.0 - t0) * fs).max(0.0) as usize).min(n_t);
    z0s.iter()
        .map(|&z0| {
            let (i0, i1) = (index(z0), index(z0 + dz));
            d.samples
                .chunks(n_t)
                .map(|ch| ch[i0..i1].iter().map(|v| v * v).sum::<f64>())
                .sum()
        })
        .collect()
}

fn rendered(s: &Scene) -> ChannelData {
    render(s, &RenderOptions::default()).unwrap().0
}

#[test]
fn lumen_speckle_fills_the_lumen_and_nothing_else() {
    let d = rendered(&scene(&tube(SPECKLE), 50));
    // The lumen on the axis spans 9.5–14.5 mm; the tube 9–15 mm. A scatterer
    // lies within a cell (0.79 mm at 2 per mm³) of the point that selected it.
    let inside = energies(&d, &[10.5e-3], 3e-3)[0];
    // The earliest: a scatterer a cell diagonal above the lumen's top (8.1 mm)
    // under an element, less the pulse's half-support: nothing before 7.0 mm.
    let above = energies(&d, &[4e-3], 2.5e-3)[0];
    // The latest echo: a scatterer up to a cell diagonal (1.4 mm) below the
    // lumen's bottom, at 15.9 mm, heard 12.1 mm off to the side by the array's
    // end element — round trip (15.9 + √(12.1² + 15.9²))/2 = 18.0 mm of depth —
    // plus the pulse's half-support (4√σ = 1.44 µs, 1.1 mm): nothing past 19.1 mm.
    let below = energies(&d, &[19.5e-3], 5e-3)[0];
    eprintln!("lumen speckle energy: inside {inside:.3e}, above {above:.3e}, below {below:.3e}");
    assert!(inside > 0.0);
    assert_eq!(above, 0.0, "echo above the tube");
    assert_eq!(below, 0.0, "echo below the tube");
    // Without the keys, or at zero strength, the matched tube is silent, and the
    // zero strength renders the scene without the keys bit for bit.
    let none = rendered(&scene(&tube(""), 50));
    assert!(none.samples.iter().all(|v| *v == 0.0));
    let zero = rendered(&scene(
        &tube("lumen_scatterer_density_per_mm3 = 2.0\nlumen_scatterer_strength = 0.0"),
        50,
    ));
    assert_eq!(zero.samples, none.samples);
}

#[test]
fn lumen_speckle_has_the_power_of_the_same_field_in_a_material() {
    // The same density and strength filling a disc of radius 2.5 mm, once as a
    // lumen (the tube above) and once as the material of a matched solid
    // cylinder of that radius: different scatterers (the fields are keyed
    // apart), the same expected echo power ρ·s² per volume (ScattererField).
    // Statistic: the log-ratio of the channel energies in 0.5 mm depth windows
    // across the disc (8 windows of nearly independent speckle); the error bar
    // is its standard error over the windows.
    let solid = "[materials.tissue]\nimpedance_mrayl = 1.5\nsound_speed_m_s = 1540.0\n\
                 scatterer_density_per_mm3 = 2.0\nscatterer_strength = 0.5\n\n\
                 [[objects]]\nname = \"rod\"\nshape = \"cylinder\"\ncenter_m = [0.0, 0.0, 0.012]\n\
                 radius_m = 0.0025\nmaterial = \"tissue\"\n";
    let z0s: Vec<f64> = (0..8).map(|w| 10e-3 + 0.5e-3 * w as f64).collect();
    let a = energies(&rendered(&scene(&tube(SPECKLE), 200)), &z0s, 0.5e-3);
    let b = energies(&rendered(&scene(solid, 200)), &z0s, 0.5e-3);
    let (m, se) = log_ratio(&a, &b);
    eprintln!(
        "lumen / material speckle power: {:.3}, log ± {se:.3}",
        m.exp()
    );
    assert!(m.abs() < 3.0 * se, "log ratio {m} ± {se}");
    // The test can fail: a lumen at twice or half the power lies outside it.
    assert!(3.0 * se < 2f64.ln(), "se {se}");
}

/// Mean and standard error over the windows of `ln(a/b)`.
fn log_ratio(a: &[f64], b: &[f64]) -> (f64, f64) {
    let logs: Vec<f64> = a.iter().zip(b).map(|(x, y)| (x / y).ln()).collect();
    let n = logs.len() as f64;
    let m = logs.iter().sum::<f64>() / n;
    let se = (logs.iter().map(|l| (l - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    (m, se)
}

#[test]
fn lumen_scatterers_sit_in_the_medium_that_fills_the_lumen() {
    // The tube inside a larger matched cylinder ("later is inside"): the lumen
    // holds the host's material, and its scatterers are traced there. The same
    // field in the same acoustic medium: the same expected power, though not
    // the same realization (crossing the host's face is one more bounce, so
    // the events draw other random numbers). Statistic as in the test above.
    let host = "[[objects]]\nname = \"host\"\nshape = \"cylinder\"\ncenter_m = [0.0, 0.0, 0.012]\n\
                radius_m = 0.006\nmaterial = \"matched\"\n";
    let z0s: Vec<f64> = (0..8).map(|w| 10e-3 + 0.5e-3 * w as f64).collect();
    let free = energies(&rendered(&scene(&tube(SPECKLE), 200)), &z0s, 0.5e-3);
    let hosted = rendered(&scene(&format!("{host}{}", tube(SPECKLE)), 200));
    let hosted = energies(&hosted, &z0s, 0.5e-3);
    let (m, se) = log_ratio(&hosted, &free);
    eprintln!(
        "lumen power in a host / in the background: {:.3}, log ± {se:.3}",
        m.exp()
    );
    assert!(
        m.abs() < 3.0 * se && 3.0 * se < 2f64.ln(),
        "log ratio {m} ± {se}"
    );
    // A rod filling the lumen (up to 0.05 mm) displaces its medium, and with it
    // the scatterers.
    let rod = "[[objects]]\nname = \"rod\"\nshape = \"cylinder\"\ncenter_m = [0.0, 0.0, 0.012]\n\
               radius_m = 0.00245\nmaterial = \"matched\"\n";
    let filled = rendered(&scene(&format!("{}{rod}", tube(SPECKLE)), 200));
    let filled: f64 = energies(&filled, &z0s, 0.5e-3).iter().sum();
    let free: f64 = free.iter().sum();
    eprintln!("lumen energy with a rod in it: {filled:.3e} (without: {free:.3e})");
    assert!(filled < 0.05 * free, "{filled} vs {free}");
}

#[test]
fn lumen_keys_need_a_hollow_cylinder() {
    let err = |objects: &str| {
        let text = format!(
            "{}\n[materials.matched]\nimpedance_mrayl = 1.5\nsound_speed_m_s = 1540.0\n\n{objects}",
            header(16, 0.27e-3, "[0.0]", 10, 2)
        );
        Scene::from_toml_str(&text, "<lumen>", ".")
            .unwrap_err()
            .to_string()
    };
    let solid = "[[objects]]\nname = \"rod\"\nshape = \"cylinder\"\ncenter_m = [0.0, 0.0, 0.012]\n\
                 radius_m = 0.003\nmaterial = \"matched\"\nlumen_scatterer_strength = 0.1\n";
    let e = err(solid);
    assert!(
        e.contains("objects.rod.lumen_scatterer_strength") && e.contains("hollow cylinder"),
        "{e}"
    );
    let negative = tube("lumen_scatterer_density_per_mm3 = -1.0");
    let e = err(&negative);
    assert!(
        e.contains("objects.tube.lumen_scatterer_density_per_mm3"),
        "{e}"
    );
    let slab =
        "[[objects]]\nname = \"layer\"\nshape = \"slab\"\nz_top_m = 0.01\nz_bottom_m = 0.02\n\
                material = \"matched\"\nlumen_scatterer_strength = 0.1\n";
    let e = err(slab);
    assert!(e.contains("objects.layer.lumen_scatterer_strength"), "{e}");
}
