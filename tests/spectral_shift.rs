//! The spectral-shift estimate of attenuation (`usray_signal::spectral_shift`)
//! on full-wave data nobody here rendered: k-Wave's disk of tier (b)
//! (`bench/kwave/data/g4_*`, its scene `bench/kwave/g4.toml`), with and
//! without an attenuation of 0.5 dB/(cm·MHz) in water and disk.
//!
//! The diagnosis uses it to tell a lower centre frequency, which shifts every
//! echo's spectrum alike, from an attenuation, which shifts them the more the
//! longer their path (`usray_optim::VerdictRule::min_spectral_z`). k-Wave's
//! grid centres the disk's echoes about 0.1 MHz below the model's whatever
//! the attenuation (docs/diagnosis.md, "Known limits"): that is the offset,
//! and the test asserts that it does not pass for an attenuation.

use std::path::Path;
use usray::optim::follow_declared_dimensions;
use usray::signal::{read_channels, spectral_shift, SpectralShift, SpectralShiftOptions};
use usray::transport::{render, RenderOptions, Scene};

/// The spectral shift of k-Wave's `case` against the disk's scene as given
/// (its true 1.76 MRayl, no attenuation), traced in 2-D as the data declare,
/// at the diagnosis's 20 rays.
fn shift_of(case: &str) -> SpectralShift {
    let data = format!("bench/kwave/data/{case}.json");
    let mut scene = Scene::load("bench/kwave/g4.toml").unwrap();
    follow_declared_dimensions(&mut scene, Path::new(&data)).unwrap();
    let (model, _) = render(
        &scene,
        &RenderOptions {
            rays_per_element: Some(20),
            ..Default::default()
        },
    )
    .unwrap();
    let measured = read_channels(&data).unwrap();
    spectral_shift(
        &measured,
        &model,
        scene.medium.sound_speed_m_s,
        scene.probe.center_frequency_hz,
        &SpectralShiftOptions::default(),
    )
    .unwrap()
}

#[test]
fn kwave_disk_attenuation_is_measured_and_its_grid_offset_is_not_taken_for_one() {
    let with = shift_of("g4_atten");
    let without = shift_of("g4_none");
    let (a, se) = (with.attenuation_db_cm_mhz, with.attenuation_std.unwrap());
    // The disk's top and bottom echoes on each of three transmits.
    assert_eq!(with.echoes.len(), 6, "{with:?}");
    // The hidden 0.5 dB/(cm·MHz), within three of the estimate's standard
    // errors, and told from none by more than three.
    assert!((a - 0.5).abs() < 3.0 * se, "{a} ± {se}");
    assert!(a > 3.0 * se, "{a} ± {se}");
    // Without attenuation the echoes sit lower than the model's alike (k-Wave's
    // grid: an offset of about −0.1 MHz), with no attenuation told.
    let (a0, se0) = (
        without.attenuation_db_cm_mhz,
        without.attenuation_std.unwrap(),
    );
    assert!(a0.abs() < 3.0 * se0, "{a0} ± {se0}");
    assert!(
        without.offset_hz < -0.05e6,
        "offset {} Hz",
        without.offset_hz
    );
}
