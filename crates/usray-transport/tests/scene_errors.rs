//! Bad scene input gives an error naming the file and the key; nothing panics.

mod common;
use common::scene_path;
use usray_transport::{Scene, SceneError};

fn base() -> String {
    std::fs::read_to_string(scene_path("cylinder.toml")).unwrap()
}

fn err(text: &str) -> SceneError {
    Scene::from_toml_str(text, "bad.toml", scene_path("")).unwrap_err()
}

#[test]
fn unknown_key_names_file_and_key() {
    let e = err(&base().replace("pitch_m = 0.3e-3", "pitch_m = 0.3e-3\npitch_mm = 0.3"));
    assert_eq!(e.file, "bad.toml");
    assert!(e.key.contains("probe.pitch_mm"), "{e}");
    assert!(e.message.contains("unknown field"), "{e}");
}

#[test]
fn misspelt_sampler_names_key_and_choices() {
    let e = err(&base().replace(
        "emission = \"plane_wave\"",
        "emission = \"plane_wave\"\nsampler = \"stratifed\"",
    ));
    assert_eq!(e.key, "acquisition.sampler", "{e}");
    assert!(e.message.contains("`stratified` or `independent`"), "{e}");
    let ok = Scene::from_toml_str(
        &base().replace(
            "emission = \"plane_wave\"",
            "emission = \"plane_wave\"\nsampler = \"stratified\"",
        ),
        "ok.toml",
        scene_path(""),
    )
    .unwrap();
    assert_eq!(
        ok.acquisition.sampler,
        usray_transport::scene::Sampler::Stratified
    );
}

#[test]
fn wrong_type_names_key() {
    let e = err(&base().replace("radius_m = 0.005", "radius_m = \"five\""));
    assert!(
        e.key.contains("objects.radius_m") || e.key.contains("radius_m"),
        "{e}"
    );
}

#[test]
fn nan_and_negative_values_name_the_parameter() {
    let e = err(&base().replace("radius_m = 0.005", "radius_m = nan"));
    assert_eq!(e.key, "objects.cylinder.radius_m", "{e}");
    assert!(e.message.contains("finite"));
    let e = err(&base().replace("radius_m = 0.005", "radius_m = -0.005"));
    assert_eq!(e.key, "objects.cylinder.radius_m", "{e}");
    assert!(e.message.contains("positive"));
    let e = err(&base().replace("sound_speed_m_s = 1570.0", "sound_speed_m_s = inf"));
    assert_eq!(e.key, "materials.target.sound_speed_m_s", "{e}");
}

#[test]
fn unknown_material_and_missing_mesh() {
    let e = err(&base().replace("material = \"target\"", "material = \"steel\""));
    assert_eq!(e.key, "objects.cylinder.material", "{e}");
    let mesh = base().replace(
        "shape = \"cylinder\"\ncenter_m = [0.0, 0.0, 0.015]\nradius_m = 0.005",
        "shape = \"mesh\"\npath = \"meshes/nope.obj\"",
    );
    let e = err(&mesh);
    assert_eq!(e.key, "objects.cylinder.path", "{e}");
    assert!(e.message.contains("not found"), "{e}");
    let e = Scene::load("/nonexistent/scene.toml").unwrap_err();
    assert!(e.file.contains("/nonexistent/scene.toml"));
}

#[test]
fn set_checks_paths_and_values() {
    let mut s = Scene::from_toml_str(&base(), "ok.toml", ".").unwrap();
    let radius = s.key("objects.cylinder.radius_m").unwrap();
    assert!(s.set(&radius, -1.0).is_err());
    assert_eq!(s.get(&radius).unwrap(), 0.005);
    let e = s.key("objects.cylinder.radius").unwrap_err();
    assert_eq!(e.key, "objects.cylinder.radius");
    let e = s
        .set(&common::key("objects.tube.radius_m"), 1.0)
        .unwrap_err();
    assert_eq!(e.key, "objects.tube.radius_m");
    let paths: Vec<String> = s.params().into_iter().map(|(p, _)| p.to_string()).collect();
    for p in [
        "objects.cylinder.radius_m",
        "materials.target.impedance_mrayl",
        "materials.target.roughness",
        "probe.pitch_m",
        "probe.center_frequency_hz",
        "medium.sound_speed_m_s",
        "objects.cylinder.center_m.2",
    ] {
        assert!(paths.iter().any(|q| q == p), "missing {p}");
    }
    for (p, v) in s.params() {
        assert_eq!(s.get(&p).unwrap(), v);
    }
}

#[test]
fn missing_scene_file_names_the_path_without_a_key() {
    let e = Scene::load("/nonexistent/dir/scene.toml").unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.starts_with("/nonexistent/dir/scene.toml: cannot read the scene file: "),
        "{msg}"
    );
    assert!(!msg.contains("key"), "{msg}");
}

/// Sizes past `scene::limits` are refused naming the key and the limit, before
/// anything is allocated (issue 23: these aborted or ran out of memory).
#[test]
fn sizes_past_the_limits_name_the_key() {
    for (old, new, key) in [
        (
            "n_elements = 128",
            "n_elements = 1000000000",
            "probe.n_elements",
        ),
        (
            "max_bounces = 5",
            "max_bounces = 4000000000",
            "acquisition.max_bounces",
        ),
        (
            "rays_per_element = 75",
            "rays_per_element = 1000000000000",
            "acquisition.rays_per_element",
        ),
        ("cycles = 3.0", "cycles = 1.0e9", "probe.cycles"),
        (
            "max_depth_m = 0.03",
            "max_depth_m = 1.0e6",
            "acquisition.max_depth_m",
        ),
        (
            "elevation_m = 4.0e-3",
            "elevation_m = 1e300",
            "probe.elevation_m",
        ),
        (
            "sampling_frequency_hz = 40.0e6",
            "sampling_frequency_hz = 1.0e15",
            "acquisition.sampling_frequency_hz",
        ),
        ("pixel_m = 0.1e-3", "pixel_m = 1.0e-9", "imaging.pixel_m"),
        (
            "center_frequency_hz = 5.0e6",
            "center_frequency_hz = 1.0e-6",
            "probe.center_frequency_hz",
        ),
        (
            "angles_deg = [-10.0, -5.0, 0.0, 5.0, 10.0]",
            &format!("angles_deg = [{}]", vec!["0.0"; 100_000].join(", ")),
            "acquisition.angles_deg",
        ),
        (
            "element_width_m = 0.27e-3",
            "element_width_m = 0.5e-3",
            "probe.element_width_m",
        ),
        (
            "z_range_m = [0.002, 0.028]",
            "z_range_m = [-0.02, -0.01]",
            "imaging.z_range_m",
        ),
    ] {
        let text = base();
        assert!(text.contains(old), "{old}");
        let e = err(&text.replace(old, new));
        assert_eq!(e.key, key, "{e}");
    }
}

/// A fixed-length list with more or fewer numbers than it holds is refused
/// naming the key (serde's arrays dropped extra numbers silently:
/// `x_range_m = [-0.01, 0.0, 0.01]` was read as `[-0.01, 0.0]`).
#[test]
fn lists_of_the_wrong_length_name_the_key() {
    for (old, new, key) in [
        (
            "x_range_m = [-0.015, 0.015]",
            "x_range_m = [-0.01, 0.0, 0.01]",
            "imaging.x_range_m",
        ),
        (
            "z_range_m = [0.002, 0.028]",
            "z_range_m = [0.002]",
            "imaging.z_range_m",
        ),
        (
            "center_m = [0.0, 0.0, 0.015]",
            "center_m = [0.0, 0.0, 0.015, 1.0]",
            "objects.cylinder.center_m",
        ),
    ] {
        let text = base();
        assert!(text.contains(old), "{old}");
        let e = err(&text.replace(old, new));
        assert_eq!(e.key, key, "{e}");
        assert!(e.to_string().contains("exactly"), "{e}");
    }
}

/// A value the shape does not use is refused naming it, not silently ignored
/// (and listed by `usray params`).
#[test]
fn values_a_shape_does_not_use_are_refused() {
    for extra in [
        "normal = [0.0, 0.0, 1.0]",
        "rotation_deg = [0.0, 0.0, 10.0]",
        "scale = 2.0",
        "z_top_m = 0.01",
    ] {
        let text = base().replace(
            "material = \"target\"",
            &format!("material = \"target\"\n{extra}"),
        );
        let e = err(&text);
        let leaf = extra.split(' ').next().unwrap();
        assert_eq!(e.key, format!("objects.cylinder.{leaf}"), "{e}");
        assert!(e.to_string().contains("not used by shape"), "{e}");
    }
}

use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Any number (huge, tiny, negative, NaN, infinite) in any numeric key of
    /// the shipped cylinder scene loads or is refused naming that key (as the
    /// key, or in the message of a consistency check between two keys): never a
    /// panic, and a scene that loads passes the size limits (its channel
    /// samples fit under `MAX_CHANNEL_SAMPLES`).
    #[test]
    fn any_number_in_any_key_loads_or_is_refused_naming_it(
        line in 0usize..200,
        value in prop_oneof![
            any::<f64>().prop_map(|v| format!("{v:e}")),
            prop::sample::select(vec![
                "nan".to_string(), "inf".into(), "-inf".into(), "0".into(), "-1".into(),
                "1e300".into(), "1e-300".into(), "4000000000".into(), "18446744073709551615".into(),
            ]),
        ],
    ) {
        let text = base();
        let lines: Vec<&str> = text.lines().collect();
        // The numeric `key = value` lines of the file.
        let numeric: Vec<usize> = lines
            .iter()
            .enumerate()
            .filter(|(_, l)| {
                l.split_once(" = ")
                    .is_some_and(|(_, v)| v.trim().parse::<f64>().is_ok())
            })
            .map(|(i, _)| i)
            .collect();
        let at = numeric[line % numeric.len()];
        let key = lines[at].split_once(" = ").unwrap().0.trim().to_string();
        let mut edited: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        // TOML integers cannot take a float: such a case is a type error, named too.
        edited[at] = format!("{key} = {value}");
        match Scene::from_toml_str(&edited.join("\n"), "gen.toml", ".") {
            Ok(s) => {
                let n = usray_transport::AcquisitionPlan::new(&s).grid.n_samples;
                let samples = n as f64
                    * s.probe.n_elements as f64
                    * s.acquisition.angles_deg.len() as f64;
                prop_assert!(samples <= usray_transport::scene::limits::MAX_CHANNEL_SAMPLES);
            }
            // The key itself, or (a consistency between two keys) its name in
            // the message.
            Err(e) => prop_assert!(
                e.key.ends_with(&key) || e.message.contains(&key),
                "{key} = {value}: {e}"
            ),
        }
    }
}

/// Values no physical set-up has are refused naming the key, not rendered
/// (a sweep of hostile values found each of these accepted).
#[test]
fn values_outside_their_physical_range_name_the_key() {
    for (old, new, key) in [
        (
            "radius_m = 0.005",
            "radius_m = 1e300",
            "objects.cylinder.radius_m",
        ),
        (
            "roughness = 0.3",
            "roughness = 1e9",
            "materials.target.roughness",
        ),
        ("f_number = 1.5", "f_number = 1e300", "imaging.f_number"),
        (
            "dynamic_range_db = 60.0",
            "dynamic_range_db = 1e300",
            "imaging.dynamic_range_db",
        ),
        ("pixel_m = 0.1e-3", "pixel_m = 1e300", "imaging.pixel_m"),
        ("cycles = 3.0", "cycles = 1e-300", "probe.cycles"),
        (
            "impedance_mrayl = 1.99",
            "impedance_mrayl = 1e300",
            "materials.target.impedance_mrayl",
        ),
        (
            "attenuation_db_cm_mhz = 0.0",
            "attenuation_db_cm_mhz = 1e9",
            "medium.attenuation_db_cm_mhz",
        ),
    ] {
        let text = base();
        assert!(text.contains(old), "{old}");
        let e = err(&text.replacen(old, new, 1));
        assert_eq!(e.key, key, "{e}");
    }
}
