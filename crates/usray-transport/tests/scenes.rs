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

/// A scene that leaves out the receive directivity gets the element's own
/// (`sinc(π w sin α / λ)`); one that gives the paper's lobe angles keeps the
/// lobe, with 5°/60° for an angle it leaves out; angles given beside
/// `receive_directivity = "element"` are refused, naming the key.
#[test]
fn receive_directivity_defaults_to_the_element() {
    use usray_transport::scene::ReceiveDirectivity;
    let path = scene_path("cylinder.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let without = |keys: &[&str]| -> String {
        text.lines()
            .filter(|l| !keys.iter().any(|k| l.starts_with(k)))
            .map(|l| format!("{l}\n"))
            .collect()
    };
    let load = |t: &str| Scene::from_toml_str(t, "cylinder.toml", scene_path(""));
    let full = Scene::load(&path).unwrap();
    assert_eq!(full.probe.receive_model(), ReceiveDirectivity::Lobe);
    let bare = load(&without(&["main_lobe_deg", "cutoff_deg"])).unwrap();
    assert_ne!(bare.probe, full.probe, "the lines were not there to remove");
    assert_eq!(bare.probe.receive_model(), ReceiveDirectivity::Element);
    let cutoff_only = load(&without(&["main_lobe_deg"])).unwrap();
    assert_eq!(cutoff_only.probe.receive_model(), ReceiveDirectivity::Lobe);
    assert_eq!(cutoff_only.probe.lobe_deg(), (5.0, full.probe.lobe_deg().1));
    let both = text.replace("[probe]\n", "[probe]\nreceive_directivity = \"element\"\n");
    assert_ne!(both, text);
    let e = load(&both).unwrap_err().to_string();
    assert!(
        e.contains("probe.main_lobe_deg") && e.contains("lobe"),
        "{e}"
    );
}

/// Edge waves are off unless asked for; asked for, a 2-D plane-wave scene
/// lifts them, and a 3-D or cosine-lobe scene is refused naming the key.
#[test]
fn edge_waves_are_asked_for_and_refused_where_not_modelled() {
    let path = scene_path("cylinder.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let load = |t: &str| Scene::from_toml_str(t, "cylinder.toml", scene_path(""));
    let with = |keys: &str| text.replace("[acquisition]\n", &format!("[acquisition]\n{keys}\n"));
    let planar = load(&with("dimensions = 2")).unwrap();
    assert!(planar.lift_const::<f64>().unwrap().edge_waves.is_none());
    let asked = load(&with("dimensions = 2\nedge_waves = true")).unwrap();
    assert!(asked.lift_const::<f64>().unwrap().edge_waves.is_some());
    // 3-D: the scene parses (the dimensions may come from the data) and its
    // lift refuses.
    let three_d = load(&with("edge_waves = true")).unwrap();
    let e = three_d.lift_const::<f64>().unwrap_err().to_string();
    assert!(
        e.contains("acquisition.edge_waves") && e.contains("2-D"),
        "{e}"
    );
    let cosine =
        with("edge_waves = true").replace("emission = \"plane_wave\"", "emission = \"cosine\"");
    let e = load(&cosine).unwrap_err().to_string();
    assert!(
        e.contains("acquisition.edge_waves") && e.contains("cosine"),
        "{e}"
    );
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
