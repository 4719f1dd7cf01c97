//! Absolute levels against full-wave data (`usray_optim::compare_absolute_levels`).
//!
//! k-Wave's channel data declare `amplitude_unit = "Pa per 1 Pa source
//! pressure"`, the unit of usray's 2-D renders with the collimated emission
//! (ray theory's pressure per unit pressure on the emitting faces). The
//! diagnosis then compares every image against the measured image's maximum.
//! That rests on the two agreeing in level, checked here on the committed
//! tier (b) ring (`bench/kwave/data/g1_none`, its scene `bench/kwave/g1.toml`).
//!
//! The gap measured: the model's image at the true ring peaks 1.05 dB above
//! k-Wave's, the same to 0.01 dB over seeds at 40 rays (a systematic gap, not
//! Monte Carlo noise). Part of it is k-Wave's grid: its wall echo is 1.0–2.0 dB
//! stronger on a grid twice as fine (`bench/kwave/grid_check.py`).
//! Both share the array's fill factor: k-Wave's plane wave carries 0.898 of
//! its source pressure (its free-field probes, `bench/kwave/edge_waves.py`),
//! the kerfs emitting nothing (`w/pitch` = 0.9), and the model's beamlets over
//! a curved wall land on the faces in the same proportion. The bound, 1.5 dB,
//! leaves 0.45 dB above the measured gap and fails on any unit error: energy
//! for pressure over a tube ratio of 2 is 3 dB, a factor 2 is 6 dB. A wall of
//! 2.69 MRayl for 1.76 renders 8.7 dB stronger (the Fresnel `R = (Z − Z₁)/(Z +
//! Z₁)` alone, 0.290 against 0.086, would give 10.6 dB; the thin wall's
//! back-face echo, of the opposite sign, takes part of it); asserted beyond
//! 8 dB: an image whose level did not follow the impedance, the relative
//! comparison, shows 0.

use std::path::Path;
use usray::optim::{
    compare_absolute_levels, follow_declared_dimensions, load_reference, AbsoluteLevels,
};
use usray::signal::BMode;
use usray::transport::{render, RenderOptions, Scene};

const DATA: &str = "bench/kwave/data/g1_none.json";

/// The scene of tier (b)'s ring as `usray diagnose` prepares it for `DATA`.
fn prepared() -> (Scene, AbsoluteLevels) {
    let mut scene = Scene::load("bench/kwave/g1.toml").unwrap();
    follow_declared_dimensions(&mut scene, Path::new(DATA)).unwrap();
    let done = compare_absolute_levels(&mut scene, Path::new(DATA)).unwrap();
    (scene, done)
}

/// Whether the levels were left relative, and why.
fn relative(scene: &mut Scene, data: &Path) -> Option<String> {
    match compare_absolute_levels(scene, data).unwrap() {
        AbsoluteLevels::Set(_) => None,
        AbsoluteLevels::NotApplicable(why) => Some(why),
    }
}

/// The maximum envelope of `scene` rendered at `rays` rays per element.
fn rendered_peak(scene: &Scene, rays: usize) -> f64 {
    let opts = RenderOptions {
        rays_per_element: Some(rays),
        ..Default::default()
    };
    let (ch, _) = render(scene, &opts).unwrap();
    let op = BMode::new(&scene.imaging_settings(), &ch.meta, ch.n_samples).unwrap();
    let mut ws = op.workspace();
    op.forward(&ch, &mut ws).unwrap();
    ws.envelope().iter().copied().fold(0.0, f64::max)
}

#[test]
fn kwave_data_are_compared_at_absolute_levels_and_agree_with_the_model() {
    let (scene, done) = prepared();
    let reference = scene.imaging.reference_amplitude.expect("absolute levels");
    assert!(matches!(done, AbsoluteLevels::Set(s) if s.contains("amplitude_unit")));
    // The measured image, on that reference, peaks at 0 dB (grey 1).
    let measured = load_reference(Path::new(DATA), &scene).unwrap();
    let top = measured.iter().copied().fold(0.0, f64::max);
    assert!((top - 1.0).abs() < 1e-12, "measured peak grey {top}");
    // The model at the data's true ring agrees in level within 1.5 dB (0.9
    // expected, module docs) ...
    let gap_db = |s: &Scene| 20.0 * (rendered_peak(s, 40) / reference).log10();
    let at_truth = gap_db(&scene);
    eprintln!("model − k-Wave at the true ring: {at_truth:+.2} dB");
    assert!(at_truth.abs() < 1.5, "model − k-Wave: {at_truth:.2} dB");
    // ... and a wall of the impedance the image-normalised calibration chose
    // is many dB off.
    let mut stiff = scene.clone();
    stiff.materials.get_mut("wall").unwrap().impedance_mrayl = 2.69;
    let too_strong = gap_db(&stiff);
    eprintln!("model at 2.69 MRayl − k-Wave: {too_strong:+.2} dB");
    assert!(
        too_strong > at_truth + 8.0,
        "2.69 MRayl: {too_strong:.2} dB, 1.76: {at_truth:.2} dB"
    );
}

#[test]
fn levels_stay_relative_where_the_units_differ_or_are_not_pressure() {
    let data = Path::new(DATA);
    // Traced in 3-D: the renders keep the energy law, not pressure.
    let mut s3 = Scene::load("bench/kwave/g1.toml").unwrap();
    s3.acquisition.dimensions = Some(usray::transport::scene::Dimensions::Three);
    assert!(relative(&mut s3, data).unwrap().contains("3-D"));
    assert!(s3.imaging.reference_amplitude.is_none());
    // The paper's cosine lobe: not a pressure either.
    let mut cosine = Scene::load("bench/kwave/g1.toml").unwrap();
    follow_declared_dimensions(&mut cosine, data).unwrap();
    cosine.acquisition.emission = usray::transport::scene::Emission::Cosine;
    assert!(relative(&mut cosine, data).unwrap().contains("cosine"));
    // A reference the scene sets itself is kept.
    let (mut own, _) = prepared();
    own.imaging.reference_amplitude = Some(2.0);
    assert!(relative(&mut own, data).is_some());
    assert_eq!(own.imaging.reference_amplitude, Some(2.0));
    // Data that declare no unit (or another): a copy of the ring's data
    // without the key.
    let dir = tempfile::tempdir().unwrap();
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(DATA).unwrap()).unwrap();
    meta.as_object_mut().unwrap().remove("amplitude_unit");
    let copy = dir.path().join("g1_none.json");
    std::fs::write(&copy, meta.to_string()).unwrap();
    std::fs::copy(data.with_extension("npy"), copy.with_extension("npy")).unwrap();
    let mut plain = Scene::load("bench/kwave/g1.toml").unwrap();
    follow_declared_dimensions(&mut plain, &copy).unwrap();
    assert!(relative(&mut plain, &copy).unwrap().contains("no unit"));
    meta["amplitude_unit"] = "arbitrary (scanner ADC counts)".into();
    std::fs::write(&copy, meta.to_string()).unwrap();
    assert!(relative(&mut plain, &copy).unwrap().contains("scanner ADC"));
    // The same unit with other spacing and case is recognised.
    meta["amplitude_unit"] = "pa  per 1 PA source pressure".into();
    std::fs::write(&copy, meta.to_string()).unwrap();
    assert_eq!(relative(&mut plain, &copy), None);
    // A B-mode has no unit.
    let mut bmode = Scene::load("bench/kwave/g1.toml").unwrap();
    follow_declared_dimensions(&mut bmode, data).unwrap();
    assert!(relative(&mut bmode, &dir.path().join("b.npy"))
        .unwrap()
        .contains("B-mode"));
}
