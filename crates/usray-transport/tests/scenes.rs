//! Every scene shipped in `scenes/` loads, lists its parameters and renders a
//! few rays without a non-finite sample; the mesh scene has echoes.

mod common;
use common::scene_path;
use usray_signal::ImagingSettings;
use usray_transport::{render, RenderOptions, Scene};

#[test]
fn shipped_scenes_load_and_render() {
    let dir = scene_path("");
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    names.sort();
    for want in [
        "cylinder.toml",
        "ring.toml",
        "valve.toml",
        "phantom.toml",
        "valve_phased.toml",
    ] {
        assert!(
            names.iter().any(|p| p.ends_with(want)),
            "missing scene {want}"
        );
    }
    for p in names {
        let scene = Scene::load(&p).unwrap_or_else(|e| panic!("{e}"));
        assert!(!scene.params().is_empty());
        let opts = RenderOptions {
            rays_per_element: Some(3),
            ..Default::default()
        };
        let (d, stats) = render(&scene, &opts).unwrap();
        let energy: f64 = d.samples.iter().map(|v| v * v).sum();
        eprintln!(
            "{}: {} rays, energy {energy:.3e}",
            p.display(),
            stats.rays_traced
        );
        assert!(d.samples.iter().all(|v| v.is_finite()));
        assert!(energy > 0.0, "{}: no echo", p.display());
    }
}

/// A scene that leaves out the receive directivity gets the shipped scenes'
/// 5° main lobe and 60° cutoff: `scenes/cylinder.toml` without those two lines
/// is the same scene.
#[test]
fn receive_directivity_defaults_to_the_shipped_values() {
    let path = scene_path("cylinder.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let trimmed: String = text
        .lines()
        .filter(|l| !l.starts_with("main_lobe_deg") && !l.starts_with("cutoff_deg"))
        .map(|l| format!("{l}\n"))
        .collect();
    assert_ne!(trimmed, text, "the lines were not there to remove");
    let full = Scene::load(&path).unwrap();
    let bare = Scene::from_toml_str(&trimmed, "cylinder.toml", scene_path("")).unwrap();
    assert_eq!(bare.probe.main_lobe_deg, 5.0);
    assert_eq!(bare.probe.cutoff_deg, 60.0);
    assert_eq!(bare.probe, full.probe);
}

/// A scene that leaves out `[imaging]` images with the beamformer's defaults
/// (`ImagingSettings::default()`, usray-signal), the sound speed aside: the
/// scene's is the medium's. `scenes/cylinder.toml` without its `[imaging]`
/// table is checked field by field against them.
#[test]
fn imaging_defaults_are_the_beamformers() {
    let path = scene_path("cylinder.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut in_imaging = false;
    let trimmed: String = text
        .lines()
        .filter(|l| {
            if l.starts_with('[') {
                in_imaging = l.trim() == "[imaging]";
            }
            !in_imaging
        })
        .map(|l| format!("{l}\n"))
        .collect();
    assert!(text.contains("[imaging]") && !trimmed.contains("[imaging]"));
    let bare = Scene::from_toml_str(&trimmed, "cylinder.toml", scene_path("")).unwrap();
    let defaults = ImagingSettings::default();
    assert_eq!(defaults.sound_speed_m_s, None);
    assert_eq!(bare.imaging.sound_speed_m_s, None);
    assert_eq!(
        bare.imaging_settings(),
        ImagingSettings {
            sound_speed_m_s: Some(bare.medium.sound_speed_m_s),
            ..defaults
        }
    );
}
