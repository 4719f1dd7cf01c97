//! `channel_gradient` against central finite differences of one Monte Carlo
//! realization (fixed seed, same rays), loss `L = Σ w·P` with fixed random `w`.
//!
//! The transport differentiates every continuous step of a path, sampling
//! included (microfacet normals are smooth functions of the parameters for fixed
//! uniforms, MIS weights are differentiated, interactions split into both
//! continuations instead of making a parameter-dependent choice), so the AD
//! gradient *is* the derivative of the realization: every parameter, geometric,
//! material or acquisition, is asserted tight. Only visibility changes (a ray
//! starting or ceasing to hit a surface or an element) are not differentiated;
//! at these steps none occurs.
//!
//! FD step: `h = rel·|θ|` from a measured convergence (example `grad_check`): for
//! translations rel 1e-9 (error 3e-8 … 4e-7; at 1e-7 it is 3e-4, the curvature of
//! grazing hits), for attenuation and pulse parameters rel 1e-7 (linear in θ
//! over the step; error ≤ 1e-7 there, roundoff-limited below).

mod common;
use common::{ad_and_fd, key, scene_path, weights};
use usray_transport::{channel_gradient, render, RenderOptions, Scene};

/// A shipped scene at 0° steering only, with extra replacements.
fn scene_0deg(name: &str, angles: &str, extra: &[(&str, &str)]) -> Scene {
    let mut text = std::fs::read_to_string(scene_path(name))
        .unwrap()
        .replace(angles, "angles_deg = [0.0]");
    for (a, b) in extra {
        assert!(text.contains(a), "{a}");
        text = text.replace(a, b);
    }
    Scene::from_toml_str(&text, name, scene_path("")).unwrap()
}

/// (AD, FD, relative difference) for each parameter, the step given relative
/// to the parameter's value.
fn check(scene: &Scene, params: &[(&str, f64)]) -> Vec<(f64, f64, f64)> {
    let steps: Vec<(&str, f64)> = params
        .iter()
        .map(|&(p, rel)| (p, rel * scene.get(&key(p)).unwrap().abs()))
        .collect();
    ad_and_fd(scene, &steps)
}

const CYL_ANGLES: &str = "angles_deg = [-10.0, -5.0, 0.0, 5.0, 10.0]";

#[test]
fn cylinder_translation_attenuation_and_pulse_match_finite_differences() {
    let scene = scene_0deg(
        "cylinder.toml",
        CYL_ANGLES,
        &[
            ("attenuation_db_cm_mhz = 0.0", "attenuation_db_cm_mhz = 0.5"),
            (
                "roughness = 0.3",
                "roughness = 0.3\nattenuation_db_cm_mhz = 0.7",
            ),
        ],
    );
    let r = check(
        &scene,
        &[
            ("objects.cylinder.center_m.2", 1e-9),
            ("medium.attenuation_db_cm_mhz", 1e-7),
            ("materials.target.attenuation_db_cm_mhz", 1e-7),
            ("probe.center_frequency_hz", 1e-7),
            ("probe.cycles", 1e-7),
        ],
    );
    // Stated tolerances: 1e-5 (measured ≤ 5e-6 with these steps; FD roundoff
    // ε·|L|/h dominates).
    for (i, (ad, fd, rel)) in r.iter().enumerate() {
        assert!(*rel < 1e-5, "parameter {i}: AD {ad} FD {fd} rel {rel}");
    }
}

/// At an attenuation's null (α = 0, where the diagnosis scores it) the data's
/// derivative includes the echo's spectral down-shift, `∂p/∂s·∂s/∂α`
/// (`usray_transport::downshift`); here that term is 13% of the derivative. α
/// cannot go below 0, so the check is one-sided: Richardson's
/// `2·D(h/2) − D(h)` of forward differences `D(h) = (L(h) − L(0))/h`, error
/// O(h²) (`L` is smooth in α ≥ 0), at h = 10⁻⁴ dB/(cm·MHz).
#[test]
fn attenuation_at_its_null_matches_one_sided_differences() {
    let scene = scene_0deg("cylinder.toml", CYL_ANGLES, &[]);
    let p = "materials.target.attenuation_db_cm_mhz";
    let k = key(p);
    assert_eq!(scene.get(&k).unwrap(), 0.0);
    let opts = RenderOptions {
        rays_per_element: Some(4),
        threads: Some(2),
        ..Default::default()
    };
    let (d, _) = render(&scene, &opts).unwrap();
    let w = weights(d.samples.len(), 12345);
    let loss = |a: f64| -> f64 {
        let mut s = scene.clone();
        s.set(&k, a).unwrap();
        let (d, _) = render(&s, &opts).unwrap();
        d.samples.iter().zip(&w).map(|(p, w)| p * w).sum()
    };
    let h = 1e-4;
    let l0 = loss(0.0);
    let (d1, d2) = ((loss(h) - l0) / h, (loss(0.5 * h) - l0) / (0.5 * h));
    let fd = 2.0 * d2 - d1;
    let ad = channel_gradient(&scene, &[k], &w, &opts).unwrap()[0];
    let r = (ad - fd).abs() / fd.abs();
    eprintln!("{p} at 0: AD {ad:.9e}, Richardson FD {fd:.9e} (forward {d1:.9e}), relative difference {r:.2e}");
    assert!(r < 1e-5, "AD {ad} FD {fd} rel {r}");
}

#[test]
fn mesh_translation_matches_finite_differences() {
    let scene = scene_0deg("valve.toml", "angles_deg = [-5.0, 0.0, 5.0]", &[]);
    let r = check(&scene, &[("objects.valve.center_m.2", 1e-9)]);
    assert!(r[0].2 < 1e-5, "{:?}", r[0]);
}

#[test]
fn ring_translation_and_wall_thickness() {
    let scene = scene_0deg("ring.toml", CYL_ANGLES, &[]);
    let r = check(
        &scene,
        &[
            ("objects.tube.center_m.2", 1e-9),
            ("objects.tube.thickness_m", 1e-9),
        ],
    );
    assert!(r[0].2 < 1e-5, "{:?}", r[0]);
    assert!(r[1].2 < 1e-5, "{:?}", r[1]);
}

#[test]
fn sampling_dependent_parameters_match_finite_differences() {
    // Parameters that change sampling densities, microfacet samples, Fresnel
    // coefficients and MIS weights. Steps as above (rel 1e-9, translations and
    // speeds; the FD error was measured below 4e-7 for each).
    let scene = scene_0deg("cylinder.toml", CYL_ANGLES, &[]);
    assert_tight("3-D cylinder", &check(&scene, SAMPLING_PARAMS));
}

/// The cylinder's parameters that change sampling densities, microfacet
/// samples, Fresnel coefficients and MIS weights, with their relative steps.
const SAMPLING_PARAMS: &[(&str, f64)] = &[
    ("objects.cylinder.radius_m", 1e-9),
    ("materials.target.impedance_mrayl", 1e-9),
    ("materials.target.roughness", 1e-7),
    ("probe.pitch_m", 1e-9),
    ("medium.sound_speed_m_s", 1e-9),
    ("materials.target.sound_speed_m_s", 1e-9),
];

/// Every (AD, FD, relative difference) of `r` non-zero and within 1e-5.
fn assert_tight(what: &str, r: &[(f64, f64, f64)]) {
    for (i, (ad, fd, rel)) in r.iter().enumerate() {
        assert!(*ad != 0.0, "{what} parameter {i}: zero gradient");
        assert!(
            *rel < 1e-5,
            "{what} parameter {i}: AD {ad} FD {fd} rel {rel}"
        );
    }
}

#[test]
fn scatterer_density_and_strength_match_finite_differences() {
    // Volume scattering inside the cylinder at 5 per mm³ (grid 8 per mm³, each
    // amplitude ×√(5/8)), and in the ring's lumen (ρ < 4 mm, in the water: the
    // same estimator on the chord of each segment through the lumen). The
    // density enters through that weight, smoothly between powers of two. Both
    // are linear or square-root in θ over the step: rel 1e-7 as for attenuation.
    let cases = [
        (
            "cylinder.toml",
            CYL_ANGLES,
            "roughness = 0.3",
            "roughness = 0.3\nscatterer_density_per_mm3 = 5.0\nscatterer_strength = 0.3",
            "materials.target.",
        ),
        (
            "ring.toml",
            "angles_deg = [-10.0, -5.0, 0.0, 5.0, 10.0]",
            "material = \"wall\"",
            "material = \"wall\"\nlumen_scatterer_density_per_mm3 = 5.0\nlumen_scatterer_strength = 0.3",
            "objects.tube.lumen_",
        ),
    ];
    for (name, angles, key, with, prefix) in cases {
        let scene = scene_0deg(name, angles, &[(key, with)]);
        let density = format!("{prefix}scatterer_density_per_mm3");
        let strength = format!("{prefix}scatterer_strength");
        let r = check(&scene, &[(&density, 1e-7), (&strength, 1e-7)]);
        for (i, (ad, fd, rel)) in r.iter().enumerate() {
            assert!(*ad != 0.0, "{name} parameter {i}: zero gradient");
            assert!(
                *rel < 1e-5,
                "{name} parameter {i}: AD {ad} FD {fd} rel {rel}"
            );
        }
    }
}

#[test]
fn planar_transport_matches_finite_differences() {
    // The same checks in 2-D (`acquisition.dimensions = 2`): the in-plane
    // microfacet sample, its densities per radian, the connections' 1/r
    // measure, the planar scatterer field and the aperture's edge waves
    // (their samples and weights) are differentiated like the 3-D ones.
    // Steps and tolerances as above.
    let planar = (
        "emission = \"plane_wave\"",
        "emission = \"plane_wave\"\ndimensions = 2\nedge_waves = true",
    );
    let scene = scene_0deg("cylinder.toml", CYL_ANGLES, &[planar]);
    assert_tight("2-D cylinder", &check(&scene, SAMPLING_PARAMS));
    let lumen = (
        "material = \"wall\"",
        "material = \"wall\"\nlumen_scatterer_density_per_mm3 = 5.0\nlumen_scatterer_strength = 0.3",
    );
    let scene = scene_0deg("ring.toml", CYL_ANGLES, &[planar, lumen]);
    // The thickness's step is rel 1e-8: with the aperture's edge waves the
    // 2-D ring's FD at 1e-9 (0.15 pm) carried 1.2e-5 of roundoff, at 1e-7
    // 6e-5 of truncation.
    let r = check(
        &scene,
        &[
            ("objects.tube.thickness_m", 1e-8),
            ("objects.tube.lumen_scatterer_density_per_mm3", 1e-7),
            ("objects.tube.lumen_scatterer_strength", 1e-7),
        ],
    );
    assert_tight("2-D ring", &r);
}

#[test]
fn tunnelling_through_a_thin_wall_matches_finite_differences() {
    // A thin wall faster than the water (0.15 mm at 1700 m/s in 1540 m/s
    // water, critical angle 65°): rays meeting it beyond the critical angle
    // tunnel through in part (`thin_layer`, asked for), from outside into the lumen and
    // back out, with a weight that depends on the thickness, the wall's speed
    // and impedance, and the angle (so the radius). In 2-D, where every ray
    // stays in the plane of the ring's cut.
    let scene = scene_0deg(
        "ring.toml",
        CYL_ANGLES,
        &[
            (
                "emission = \"plane_wave\"",
                "emission = \"plane_wave\"\ndimensions = 2\nthin_layer_tunnelling = true",
            ),
            ("thickness_m = 0.001", "thickness_m = 0.15e-3"),
            ("sound_speed_m_s = 1570.0", "sound_speed_m_s = 1700.0"),
            ("roughness = 0.3", "roughness = 0.05"),
        ],
    );
    let r = check(
        &scene,
        &[
            ("objects.tube.thickness_m", 1e-8),
            ("materials.wall.sound_speed_m_s", 1e-8),
            ("materials.wall.impedance_mrayl", 1e-8),
            ("objects.tube.radius_m", 1e-9),
        ],
    );
    assert_tight("2-D thin fast wall", &r);
    // The scene does tunnel: without the setting its channels differ.
    let mut off = scene.clone();
    off.acquisition.thin_layer_tunnelling = false;
    let opts = RenderOptions {
        rays_per_element: Some(4),
        ..Default::default()
    };
    let (a, b) = (
        render(&scene, &opts).unwrap().0,
        render(&off, &opts).unwrap().0,
    );
    assert!(a.samples != b.samples, "no ray tunnelled");
}

#[test]
fn element_directivity_matches_finite_differences() {
    // The element's own receive directivity (the cylinder scene without its
    // lobe lines): `sinc(π w f_c s / c)` depends on the element width, the
    // centre frequency and the medium's speed, besides their other roles.
    // In 3-D and in 2-D; tolerances as above. The width's step is rel 1e-7
    // (the directivity is smooth in it; at 1e-9, 0.27 pm, FD roundoff gave
    // 8e-5, at 1e-7 4e-7).
    let params = [
        ("probe.element_width_m", 1e-7),
        ("probe.center_frequency_hz", 1e-7),
        ("medium.sound_speed_m_s", 1e-9),
    ];
    cylinder_in_3d_and_2d((LOBE_LINES, ""), |what, scene| {
        assert_eq!(
            scene.probe.receive_model(),
            usray_transport::scene::ReceiveDirectivity::Element
        );
        assert_tight(
            &format!("{what} element directivity"),
            &check(&scene, &params),
        );
    });
}

/// The cylinder scene's lines of the paper's receive lobe.
const LOBE_LINES: &str = "main_lobe_deg = 5.0\ncutoff_deg = 60.0\n";

/// `f(what, scene)` for the cylinder scene at 0° with `change`, in 3-D and
/// then in 2-D.
fn cylinder_in_3d_and_2d(change: (&str, &str), mut f: impl FnMut(&str, Scene)) {
    let planar = (
        "emission = \"plane_wave\"",
        "emission = \"plane_wave\"\ndimensions = 2",
    );
    for (what, extra) in [("3-D", vec![change]), ("2-D", vec![change, planar])] {
        f(what, scene_0deg("cylinder.toml", CYL_ANGLES, &extra));
    }
}

#[test]
fn rigid_baffle_matches_finite_differences() {
    // The rigid baffle divides each element's directivity by the cosine of
    // the arrival (`probe.receive_baffle = "rigid"`), which moves with the
    // element positions (the pitch) and the echo's origin (the radius). In
    // 3-D and in 2-D; the steps of `SAMPLING_PARAMS` and of the element's
    // directivity (at 1e-7 the pitch's FD error was 3.5e-3).
    let params = [
        ("probe.pitch_m", 1e-9),
        ("probe.element_width_m", 1e-7),
        ("objects.cylinder.radius_m", 1e-9),
    ];
    let rigid = (LOBE_LINES, "receive_baffle = \"rigid\"\n");
    cylinder_in_3d_and_2d(rigid, |what, scene| {
        assert_eq!(
            scene.probe.receive_baffle,
            Some(usray_transport::scene::ReceiveBaffle::Rigid)
        );
        assert_tight(&format!("{what} rigid baffle"), &check(&scene, &params));
    });
}
