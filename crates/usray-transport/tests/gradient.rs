//! `channel_gradient`: errors, forward-dual vs reverse agreement, thread-count
//! independence, agreement with a dual render.

mod common;
use common::{key, keys, scene_path, weights};
use usray_transport::{channel_gradient, render, render_lifted, RenderOptions, Scene};

fn opts(rays: usize, threads: usize) -> RenderOptions {
    RenderOptions {
        rays_per_element: Some(rays),
        threads: Some(threads),
        ..Default::default()
    }
}

/// The cylinder scene with one transmit (keeps the tests fast).
fn cylinder() -> Scene {
    let text = std::fs::read_to_string(scene_path("cylinder.toml"))
        .unwrap()
        .replace(
            "angles_deg = [-10.0, -5.0, 0.0, 5.0, 10.0]",
            "angles_deg = [5.0]",
        );
    Scene::from_toml_str(&text, "cylinder-1tx", scene_path("")).unwrap()
}

const PARAMS: [&str; 12] = [
    "objects.cylinder.radius_m",
    "objects.cylinder.center_m.0",
    "objects.cylinder.center_m.2",
    "materials.target.impedance_mrayl",
    "materials.target.sound_speed_m_s",
    "materials.target.roughness",
    "materials.target.attenuation_db_cm_mhz",
    "medium.sound_speed_m_s",
    "medium.impedance_mrayl",
    "probe.pitch_m",
    "probe.center_frequency_hz",
    "probe.cycles",
];

#[test]
fn errors_name_the_problem() {
    let scene = cylinder();
    let o = opts(1, 2);
    let (d, _) = render(&scene, &o).unwrap();
    let e = channel_gradient(
        &scene,
        &keys(&["objects.cylinder.radius_m"]),
        &d.samples[1..],
        &o,
    )
    .unwrap_err();
    assert_eq!(e.key, "d_channels", "{e}");
    assert!(e.to_string().contains(&d.samples.len().to_string()), "{e}");
    let e = scene.key("objects.cylinder.nope").unwrap_err();
    assert_eq!(e.key, "objects.cylinder.nope", "{e}");
    let e =
        channel_gradient(&scene, &keys(&["objects.nope.radius_m"]), &d.samples, &o).unwrap_err();
    assert_eq!(e.key, "objects.nope.radius_m", "{e}");
    // Parameters the transport does not read get 0.
    let g = channel_gradient(&scene, &keys(&["imaging.f_number"]), &d.samples, &o).unwrap();
    assert_eq!(g, vec![0.0]);
}

#[test]
fn equals_the_derivative_of_a_dual_render() {
    // Σ w·∂P/∂θ from a Dual<1> render (splat + convolution in the dual) against
    // the replay with correlated adjoints: the same numbers up to rounding.
    // (Pulse-shape parameters are not in this comparison: the dual render
    // convolves with f64 taps; they are checked against finite differences.)
    let scene = cylinder();
    let o = opts(2, 2);
    let (d, _) = render(&scene, &o).unwrap();
    let w = weights(d.samples.len(), 7);
    for p in [
        "objects.cylinder.radius_m",
        "materials.target.impedance_mrayl",
        "materials.target.attenuation_db_cm_mhz",
        "probe.pitch_m",
    ] {
        let st = scene.lift_dual::<1>(&keys(&[p])).unwrap();
        let (pd, _, _) = render_lifted(&scene, &st, &o);
        let want: f64 = pd.iter().zip(&w).map(|(v, w)| v.eps[0] * w).sum();
        let got = channel_gradient(&scene, &keys(&[p]), &w, &o).unwrap()[0];
        eprintln!("{p}: dual render {want:.9e}, channel_gradient {got:.9e}");
        assert!(
            (got - want).abs() <= 1e-9 * want.abs(),
            "{p}: {got} vs {want}"
        );
    }
}

#[test]
fn forward_and_reverse_modes_agree_and_threads_do_not_matter() {
    modes_agree(&cylinder());
}

/// The same with attenuation in the medium and the cylinder: every deposit is
/// placed through the down-shift nodes, and its shift carries a derivative.
#[test]
fn forward_and_reverse_modes_agree_with_attenuation() {
    let mut scene = cylinder();
    scene
        .set(&key("medium.attenuation_db_cm_mhz"), 0.5)
        .unwrap();
    scene
        .set(&key("materials.target.attenuation_db_cm_mhz"), 0.7)
        .unwrap();
    assert!(
        usray_transport::AcquisitionPlan::new(&scene)
            .pulse
            .nodes(false)
            >= 2
    );
    modes_agree(&scene);
}

/// The same traced in 2-D (`acquisition.dimensions = 2`): the planar
/// microfacet sample and densities, and the connections' 1/r measure, recorded
/// on the reverse tape.
#[test]
fn forward_and_reverse_modes_agree_in_2d() {
    let mut scene = cylinder();
    scene.acquisition.dimensions = Some(usray_transport::scene::Dimensions::Two);
    modes_agree(&scene);
}

/// The same with speckle in the cylinder, in 3-D and 2-D: forward passes
/// reuse each scatterer's receiver responses within a chunk of paths, the
/// reverse replay traces every one on its tape (`integrator::Responses`).
#[test]
fn forward_and_reverse_modes_agree_with_speckle() {
    for dimensions in [None, Some(usray_transport::scene::Dimensions::Two)] {
        let mut scene = cylinder();
        scene.acquisition.dimensions = dimensions;
        scene
            .set(&key("materials.target.scatterer_density_per_mm3"), 4.0)
            .unwrap();
        scene
            .set(&key("materials.target.scatterer_strength"), 0.3)
            .unwrap();
        modes_agree(&scene);
    }
}

/// Reverse mode (12 parameters) against two forward calls of 6, and the bits
/// of both with 1 and 2 threads.
fn modes_agree(scene: &Scene) {
    let scene = scene.clone();
    let o = opts(2, 2);
    let (d, _) = render(&scene, &o).unwrap();
    let w = weights(d.samples.len(), 11);
    let params = keys(&PARAMS);
    // 12 parameters: per-path reverse mode.
    let rev = channel_gradient(&scene, &params, &w, &o).unwrap();
    // The same in two forward calls of 6 (Dual<6> passes).
    let mut fwd = channel_gradient(&scene, &params[..6], &w, &o).unwrap();
    fwd.extend(channel_gradient(&scene, &params[6..], &w, &o).unwrap());
    for (j, p) in PARAMS.iter().enumerate() {
        let scale = rev[j].abs().max(fwd[j].abs());
        eprintln!("{p}: reverse {:.12e}, forward {:.12e}", rev[j], fwd[j]);
        assert!(
            (rev[j] - fwd[j]).abs() <= 1e-10 * scale,
            "{p}: reverse {} forward {}",
            rev[j],
            fwd[j]
        );
    }
    assert!(rev.iter().all(|v| v.is_finite()));
    assert!(rev.iter().filter(|v| **v != 0.0).count() >= 10);
    // Bit-identical with 1 thread, in both modes.
    let rev1 = channel_gradient(&scene, &params, &w, &opts(2, 1)).unwrap();
    let fwd1 = channel_gradient(&scene, &params[..6], &w, &opts(2, 1)).unwrap();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&rev), bits(&rev1));
    assert_eq!(bits(&fwd[..6]), bits(&fwd1));
}
