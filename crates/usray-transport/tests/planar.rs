//! 2-D transport (`acquisition.dimensions = 2`): every ray stays in the `xz`
//! plane, a thin rod's echo falls as ray theory's pressure (`≈ 1/√r`; 3-D
//! spreads energy: `1/r²`), a smooth plane's echo is the same as in 3-D, and a
//! bad value of the key is refused with its name.

mod common;
use common::{element_echoes, for_each_cast, header, mean_se, plane_wave_scene as scene};
use usray_signal::io::declared_dimensions_of;
use usray_transport::plan::AcquisitionPlan;
use usray_transport::scene::Dimensions;
use usray_transport::{render, RenderOptions, Scene};

/// A thin rough cylinder of radius 0.05 mm on the axis at `depth` m.
fn rough_rod(depth: f64) -> String {
    format!(
        "[materials.m]\nimpedance_mrayl = 3.0\nsound_speed_m_s = 1540.0\nroughness = 1.0\n\n\
         [[objects]]\nname = \"rod\"\nshape = \"cylinder\"\ncenter_m = [0.0, 0.0, {depth}]\n\
         radius_m = 0.05e-3\nmaterial = \"m\"\n"
    )
}

/// `s` with elements 0.1 mm high: in 3-D the rays then leave within ±0.05 mm
/// of the plane, so that the distance and lobe from a point to an element's
/// centre are those in the plane (with the default 4 mm they are up to 2%
/// longer at 10 mm than at 20, and the ratio below 4% lower).
fn thin_elements(mut s: Scene) -> Scene {
    s.probe.elevation_m = 0.1e-3;
    s
}

/// Σ of every deposit amplitude on the two central elements (15, 16) of a
/// render of `s` with `seed` (the impulse data sums to Σ a_k).
fn central_echo(s: &Scene, seed: u64) -> f64 {
    element_echoes(s, seed)[15..=16].iter().sum()
}

/// Ratio of the mean central echo at `near` to that at `far`, with its
/// delta-method standard error over 8 seeds.
fn echo_ratio(planar: bool, near: f64, far: f64) -> (f64, f64) {
    let (a, b): (Vec<f64>, Vec<f64>) = (1..=8)
        .map(|seed| {
            (
                central_echo(&thin_elements(scene(planar, 6000, &rough_rod(near))), seed),
                central_echo(&thin_elements(scene(planar, 6000, &rough_rod(far))), seed),
            )
        })
        .unzip();
    let ((ma, sa), (mb, sb)) = (mean_se(&a), mean_se(&b));
    let ratio = ma / mb;
    (
        ratio,
        ratio * ((sa / ma).powi(2) + (sb / mb).powi(2)).sqrt(),
    )
}

#[test]
fn a_thin_rods_echo_falls_as_ray_theorys_pressure_in_2d_and_as_energy_in_3d() {
    // A collimated plane wave meets the rod with the same width at any depth.
    // Ray theory (2-D): a convex cylinder of radius a returns a line source's
    // pressure √(f/(D + f)), f = a/2 its focal length, D the distance from its
    // front; from 10 to 20 mm the echo falls by √((a + 2D_far)/(a + 2D_near)),
    // ≈ 1/√r. The 2-D transport carries that (its ray tube; module
    // `integrator::spreading`). The 3-D transport spreads energy: a receiver
    // connection carries the element's solid angle w·h·cosθ/r², so the echo
    // falls by ((D_far)/(D_near))². The rod is thin so that the directions
    // from its surface to the central elements, on which its rough lobe
    // depends, change by < 0.5°.
    let (near, far, a): (f64, f64, f64) = (0.010, 0.020, 0.05e-3);
    let (d_near, d_far) = (near - a, far - a);
    let pressure_2d = ((a + 2.0 * d_far) / (a + 2.0 * d_near)).sqrt();
    let energy_3d = (d_far / d_near).powi(2);
    for (planar, want) in [(false, energy_3d), (true, pressure_2d)] {
        let (ratio, se) = echo_ratio(planar, near, far);
        eprintln!("planar {planar}: near/far {ratio:.4} ± {se:.4}, expected {want:.4}");
        // The rod's surface spans ±0.05 mm of depth around its front: 1%
        // allowance on the closed form.
        assert!(
            (ratio - want).abs() < 4.0 * se + 0.01 * want,
            "planar {planar}: ratio {ratio} vs {want}"
        );
        assert!(
            se < 0.02 * want,
            "Monte Carlo error too large to be a test: {se}"
        );
    }
}

#[test]
fn a_smooth_planes_echo_is_the_same_in_2d_and_3d() {
    // A plane reflects a plane wave back as a plane wave: no spreading in either
    // model, so the impulse data sum to the same R per emitted amplitude.
    let body = "[materials.m]\nimpedance_mrayl = 4.5\nsound_speed_m_s = 1540.0\n\n\
                [[objects]]\nname = \"floor\"\nshape = \"plane\"\ncenter_m = [0.0, 0.0, 0.01]\nmaterial = \"m\"\n";
    let total = |planar: bool| {
        let s = scene(planar, 200, body);
        let opts = RenderOptions {
            impulse_only: true,
            ..Default::default()
        };
        render(&s, &opts).unwrap().0.samples.iter().sum::<f64>()
    };
    let (two, three) = (total(true), total(false));
    eprintln!("plane echo: 2-D {two:.6}, 3-D {three:.6}");
    assert!((two - three).abs() < 1e-9 * three.abs(), "{two} vs {three}");
}

#[test]
fn every_ray_and_connection_of_a_2d_scene_stays_in_the_plane() {
    // Rough walls (reflection and transmission lobes), a sphere cut at y = 0,
    // volume scatterers in a wall and a lumen, and the cosine emission: every
    // segment cast starts at y = 0 and runs in the plane.
    let body =
        "[materials.wall]\nimpedance_mrayl = 2.0\nsound_speed_m_s = 1600.0\nroughness = 0.4\n\
                scatterer_density_per_mm3 = 5.0\nscatterer_strength = 0.3\n\n\
                [[objects]]\nname = \"tube\"\nshape = \"cylinder\"\ncenter_m = [0.0, 0.0, 0.012]\n\
                radius_m = 4.0e-3\nthickness_m = 1.0e-3\nmaterial = \"wall\"\n\
                lumen_scatterer_density_per_mm3 = 5.0\nlumen_scatterer_strength = 0.3\n\n\
                [[objects]]\nname = \"ball\"\nshape = \"sphere\"\ncenter_m = [0.003, 0.0, 0.022]\n\
                radius_m = 2.0e-3\nmaterial = \"wall\"\n";
    let mut s = scene(true, 8, body);
    s.acquisition.emission = usray_transport::scene::Emission::Cosine;
    let mut casts = 0usize;
    let deposits = for_each_cast(&s, |r| {
        casts += 1;
        assert!(
            r.origin.y.abs() < 1e-15 && r.dir.y.abs() < 1e-12,
            "a ray left the plane: {r:?}"
        );
    });
    eprintln!("{casts} casts, {deposits} deposits");
    assert!(
        casts > 10_000 && deposits > 10_000,
        "{casts} casts, {deposits} deposits"
    );
}

#[test]
fn dimensions_other_than_2_or_3_are_refused_by_name() {
    let text = header(8, 0.27e-3, "[0.0]", 4, 2).replace("seed = 1", "seed = 1\ndimensions = 1");
    let e = Scene::from_toml_str(&text, "<dims>", ".")
        .unwrap_err()
        .to_string();
    assert!(e.contains("dimensions") && e.contains("2 or 3"), "{e}");
    // A scene that leaves the key out is written without it; a 2-D one keeps it.
    let three = Scene::from_toml_str(&header(8, 0.27e-3, "[0.0]", 4, 2), "<3d>", ".").unwrap();
    assert!(!three.to_toml_string().contains("dimensions"));
    let two = scene(true, 4, "");
    let back = Scene::from_toml_str(&two.to_toml_string(), "<2d>", ".").unwrap();
    assert_eq!(back.acquisition.dimensions, Some(Dimensions::Two));
    // A 2-D render's channel data declare it; a 3-D one's say nothing.
    let meta = |s: &Scene| serde_json::to_value(AcquisitionPlan::new(s).channel_meta()).unwrap();
    let declared = declared_dimensions_of(&meta(&two)).unwrap().unwrap();
    assert_eq!(declared.dimensions, 2);
    assert!(declared_dimensions_of(&meta(&three)).unwrap().is_none());
}
