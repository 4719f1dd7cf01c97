//! The diagnosis on data its own model did not render, at CI size (the full-size
//! tiers and their results: `bench/README.md`, `docs/diagnosis.md`).
//!
//! Tier (a): the base scenes of `bench/tier_a/` reduced to 32 elements, their
//! "measured" data rendered unlike the model — 10× its rays, the independent
//! sampler (the model: stratified), 8 bounces (the model: 4, or 6 where a solid
//! cylinder is a wall candidate), a seed of another family and white noise at
//! −50 dB of the largest channel sample.
//!
//! Tier (b): full-wave k-Wave channel data committed in `bench/kwave/data/`
//! (made by `bench/kwave/make_all.sh`), diagnosed against `bench/kwave/g1.toml`
//! with fewer rays and iterations.

use std::path::Path;
use usray::optim::blind::{measured_image, BlindOptions, Draw};
use usray::optim::{
    catalogue, diagnose, diagnosis_bounces, follow_declared_dimensions, load_reference,
    mean_and_se, names_an_effect, DiagnoseOptions, Diagnosis, MeasuredChannels, Objective,
    VerdictRule,
};
use usray::transport::scene::Sampler;
use usray::transport::{RenderOptions, Scene};

/// The model's rays per element, and the data's (10×).
const MODEL_RAYS: usize = 12;
const DATA_RAYS: usize = 120;

/// The diagnoses of this file run one at a time: each renders on every core.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A tier (a) base scene reduced for CI: 32 elements and 0.25 mm pixels.
fn ci_scene(text: &str, name: &str) -> Scene {
    let mut s = Scene::from_toml_str(text, name, ".").unwrap();
    s.probe.n_elements = 32;
    s.imaging.pixel_m = 0.25e-3;
    s.validate().unwrap();
    s
}

/// The B-mode of `truth` rendered unlike the model: 10× its rays, the
/// independent sampler, 8 bounces, white noise at −50 dB.
fn measured_unlike(mut truth: Scene, seed: u64) -> Vec<f64> {
    truth.acquisition.sampler = Sampler::Independent;
    truth.acquisition.max_bounces = 8;
    truth.validate().unwrap();
    let data = BlindOptions {
        noise_db: 50.0,
        render: RenderOptions {
            rays_per_element: Some(DATA_RAYS),
            ..Default::default()
        },
        ..Default::default()
    };
    measured_image(
        &Draw {
            kind: "tier_a",
            strength: 0.0,
            scene: truth,
            seed,
        },
        &data,
    )
    .unwrap()
}

/// Diagnoses `base` against data rendered from `truth` unlike the model.
fn diagnose_unlike(base: &Scene, truth: Scene, seed: u64) -> Diagnosis {
    let _serial = ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let measured = measured_unlike(truth, seed);
    let render = RenderOptions {
        rays_per_element: Some(MODEL_RAYS),
        ..Default::default()
    };
    let opts = DiagnoseOptions {
        calibration_iters: 20,
        refit_iters: 20,
        confirm_top: 2,
        render,
        ..Default::default()
    };
    let d = diagnose(base, &measured, &opts, |_| {}).unwrap();
    eprintln!(
        "verdict {} (shrink {:.2}); held-out {:.3e}, noise {:.3e}, share {:.2}; {:?}",
        d.verdict.effect,
        d.verdict.shrink,
        d.calibrated.loss_held_out,
        d.noise_loss,
        d.noise_check.share,
        d.effects
            .iter()
            .filter(|e| e.shrink.is_some())
            .map(|e| (e.effect.as_str(), e.excess, e.excess_std, e.gap_explained))
            .collect::<Vec<_>>()
    );
    d
}

/// The value of `path` in the refit of the effect the verdict named.
fn named_value(d: &Diagnosis, path: &str) -> f64 {
    let named = d
        .effects
        .iter()
        .find(|e| Some(&e.path) == d.verdict.path.as_ref())
        .expect("the verdict names a refitted effect");
    named.params[path]
}

/// Why a diagnosis renders at [`diagnosis_bounces`]: at the rod scene's own
/// limit (4) the rod hollowed to its true 1 mm wall loses its far wall and fits
/// tier (a)'s data worse than the solid rod; at the diagnosis's limit (6) it
/// fits them better. Each side is the mean over seeds of the loss difference,
/// with its standard error. At full size: loss 0.0539 (hollow) against 0.0501
/// (solid) at 4 bounces, 0.0332 against 0.0500 at 6.
#[test]
fn a_hollowed_rod_needs_the_diagnosis_bounce_limit() {
    let text = include_str!("../bench/tier_a/a3_layered.toml");
    let base = ci_scene(text, "a3_layered.toml");
    // The rod hollowed to its true wall, as the wall candidate does it.
    let wall = catalogue(&base)
        .into_iter()
        .find(|c| c.effect == "wall_thickness")
        .unwrap();
    let hollowed = |s: &Scene| wall.switched_on(s, 1e-3).unwrap();
    let measured = {
        let _serial = ONE_AT_A_TIME
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        measured_unlike(hollowed(&base), 90_011)
    };
    let scene_limit = base.acquisition.max_bounces;
    let limit = diagnosis_bounces(&base);
    assert_eq!(limit, scene_limit + 2);
    let loss = |s: &Scene, bounces: u32, seed: u64| {
        let mut s = s.clone();
        s.acquisition.max_bounces = bounces;
        let render = RenderOptions {
            rays_per_element: Some(MODEL_RAYS),
            seed: Some(seed),
            ..Default::default()
        };
        Objective::new(s, measured.clone(), vec![], render)
            .unwrap()
            .value(&[])
            .unwrap()
            .loss
    };
    // Hollow minus solid, over seeds: mean and standard error.
    let gain = |bounces: u32| {
        let d: Vec<f64> = (1..=6u64)
            .map(|seed| loss(&hollowed(&base), bounces, seed) - loss(&base, bounces, seed))
            .collect();
        let (mean, se) = mean_and_se(&d);
        (mean, se.unwrap())
    };
    let (at_scene, se_scene) = gain(scene_limit);
    let (at_limit, se_limit) = gain(limit);
    eprintln!(
        "hollow − solid loss: {at_scene:+.3e} ± {se_scene:.1e} at {scene_limit} bounces, \
         {at_limit:+.3e} ± {se_limit:.1e} at {limit}"
    );
    assert!(
        at_scene > 3.0 * se_scene,
        "at the scene's limit the wall should not help"
    );
    assert!(
        at_limit < -3.0 * se_limit,
        "at the diagnosis's limit the wall should help"
    );
}

/// An off-axis tube whose wall is twice as thick as modelled (1.6 mm against
/// 0.8): the hollow cylinder's thickness is a parameter candidate, and it must
/// be named, its refit nearer the truth than the model's value.
#[test]
fn tier_a_tube_with_a_thicker_wall_names_wall_thickness() {
    let text = include_str!("../bench/tier_a/a1_tube.toml");
    let base = ci_scene(text, "a1_tube.toml");
    let truth = ci_scene(
        &text.replace("thickness_m = 0.8e-3", "thickness_m = 1.6e-3"),
        "a1_wall.toml",
    );
    let d = diagnose_unlike(&base, truth, 90_002);
    assert_eq!(d.verdict.effect, "wall_thickness");
    let found = named_value(&d, "objects.tube.thickness_m");
    assert!(
        (found - 1.6e-3).abs() < (0.8e-3f64 - 1.6e-3).abs() / 2.0,
        "wall found {found:.3e} m for 1.6e-3"
    );
    // Verdict test 9: the named wall was rendered again with the control at
    // four times the rays, and its gain holds without the simulation's noise.
    let wall = d
        .effects
        .iter()
        .find(|e| e.effect == "wall_thickness")
        .unwrap();
    let m = wall.more_rays.as_ref().expect("looked at with more rays");
    eprintln!(
        "wall: {:+.4} at {MODEL_RAYS} rays, {:+.4} at {}, without noise {:+.4} ± {:?} (p {:.2})",
        wall.excess.unwrap(),
        m.excess,
        m.rays,
        m.noise_free_excess,
        m.noise_free_std,
        m.noise_exponent
    );
    assert_eq!(m.rays, 4 * MODEL_RAYS);
    assert!(VerdictRule::default().holds_without_noise(Some(m)));
}

/// A sphere with no effect: the verdict must not name one (`none` where the
/// simulation's noise passed its check, else `inconclusive`).
#[test]
fn tier_a_sphere_without_an_effect_names_none() {
    let text = include_str!("../bench/tier_a/a2_sphere.toml");
    let base = ci_scene(text, "a2_sphere.toml");
    let d = diagnose_unlike(&base, base.clone(), 90_005);
    assert!(!names_an_effect(&d.verdict.effect), "{}", d.verdict.effect);
    assert_eq!(
        d.verdict.effect == "none",
        d.noise_check.passed,
        "{}",
        d.verdict.effect
    );
    assert_ne!(d.verdict.effect, "unexplained");
}

/// Two effects at once (tier (a)'s compound case `a2_pulse_scatter`): the
/// sphere filled with speckle and imaged with a pulse of 4.5 cycles for the
/// model's 3. The first round must name the speckle, which the calibration
/// (a faint, rough shell for the sphere) leaves matched by a faint speckle:
/// its refit starts from the screen's best point, past the loss's minimum
/// towards the null, and must not step onto the null and stay there. At this
/// size it refits to 0.029, +0.54 over the null refit; the full-size case
/// (`docs/diagnosis.md`, "Compound cases") to 0.0046, named by its
/// `absence_cost`.
#[test]
fn tier_a_compound_speckle_and_pulse_names_the_speckle_first() {
    let text = include_str!("../bench/tier_a/a2_sphere.toml");
    let base = ci_scene(text, "a2_sphere.toml");
    let truth = ci_scene(
        &text.replace("cycles = 3.0", "cycles = 4.5").replace(
            "roughness = 0.3\n",
            "roughness = 0.3\nscatterer_density_per_mm3 = 5.0\nscatterer_strength = 0.15\n",
        ),
        "a2_pulse_scatter.toml",
    );
    let d = diagnose_unlike(&base, truth, 90_014);
    assert_eq!(d.verdict.effect, "volume_scattering");
    let strength = named_value(&d, "materials.target.scatterer_strength");
    assert!(strength > 0.0, "speckle refitted to {strength}");
}

/// The 5 mm k-Wave ring whose wall is 0.9 mm, diagnosed against the modelled
/// k-Wave's `case` of the ring g1 diagnosed against `bench/kwave/g1.toml` at
/// CI size (12 rays, `iters` iterations, one refit), traced in 2-D as the data
/// declare, as `usray diagnose` does; with its channels beside the image
/// where `with_channels` (as `usray diagnose` passes a channel-data file).
fn diagnose_kwave_g1(case: &str, with_channels: bool, iters: usize) -> Diagnosis {
    let opts = DiagnoseOptions {
        calibration_iters: iters,
        refit_iters: iters,
        confirm_top: 1,
        render: RenderOptions {
            rays_per_element: Some(12),
            ..Default::default()
        },
        ..Default::default()
    };
    diagnose_kwave_g1_with(case, with_channels, opts)
}

/// k-Wave's `case` of the ring g1 diagnosed against `bench/kwave/g1.toml`
/// with `opts` (its measured channels set here where `with_channels`),
/// traced in 2-D as the data declare.
fn diagnose_kwave_g1_with(case: &str, with_channels: bool, opts: DiagnoseOptions) -> Diagnosis {
    let mut base = Scene::load("bench/kwave/g1.toml").unwrap();
    let data = format!("bench/kwave/data/{case}.json");
    let data = Path::new(&data);
    assert!(follow_declared_dimensions(&mut base, data)
        .unwrap()
        .is_some());
    let measured = load_reference(data, &base).unwrap();
    let measured_channels = with_channels.then(|| {
        MeasuredChannels(std::sync::Arc::new(
            usray::signal::read_channels(data).unwrap(),
        ))
    });
    let _serial = ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let opts = DiagnoseOptions {
        measured_channels,
        ..opts
    };
    diagnose(&base, &measured, &opts, |_| {}).unwrap()
}

/// 0.15 mm wall: `wall_thickness` must be named with the wall refitted past half
/// way to the truth. Traced in 2-D, as the data declare: at full size (20 rays,
/// 40 iterations) the wall comes out 0.93 mm (excess over the null refit 0.34,
/// 0.38 of the gap explained); at this size 0.89 mm, excess 0.310 ± 0.007 (in
/// 3-D it was 0.53 mm, excess 0.201, the 0.2 threshold cleared by a hair).
#[test]
fn tier_b_kwave_ring_with_a_thicker_wall_names_wall_thickness() {
    let d = diagnose_kwave_g1("g1_wall", false, 24);
    let wall = d
        .effects
        .iter()
        .find(|e| e.effect == "wall_thickness")
        .and_then(|e| {
            Some((
                e.params.get("objects.ring.thickness_m").copied()?,
                e.excess,
                e.excess_std,
                e.gap_explained,
            ))
        });
    eprintln!(
        "k-Wave g1_wall: verdict {} (shrink {:.2}), wall (m, excess, se, gap) {wall:?}; held-out {:.3e}, noise {:.3e}",
        d.verdict.effect, d.verdict.shrink, d.calibrated.loss_held_out, d.noise_loss
    );
    assert_eq!(d.verdict.effect, "wall_thickness");
    let wall = wall.unwrap().0;
    assert!(
        wall > (0.15e-3 + 0.9e-3) / 2.0,
        "wall {wall:.3e} m for 0.9e-3"
    );
}

/// k-Wave's ring g1 sent with a 2.2 MHz burst, its data and scene declaring
/// 2.5 MHz: the echoes' spectra show a centre near 2.2 MHz alike along their
/// path, which widens the centre frequency's range below the nominal ±15%
/// (whose bound, 2.125 MHz, held the refit before, and the verdict was
/// `none`), and `center_frequency` is named inside it. At the diagnosis's own
/// size (20 rays, the default iterations and three refits; with `--budget
/// 180`, build 4a1f0e3: 2.152 MHz, excess 0.147 ± 0.003). Not at CI size: with
/// 12 rays and one refit the wall's thickness outranks the centre frequency,
/// is refitted alone, ends within its tolerance, and the verdict is `none`;
/// `tests/spectral_shift.rs` asserts the spectra's centre at CI cost.
#[test]
#[ignore = "diagnostic: one full-size k-Wave diagnosis, about 2 minutes"]
fn tier_b_kwave_ring_centre_frequency_is_named_inside_the_range_its_spectra_give() {
    let d = diagnose_kwave_g1_with(
        "g1_freq",
        true,
        DiagnoseOptions {
            render: RenderOptions {
                rays_per_element: Some(20),
                ..Default::default()
            },
            ..Default::default()
        },
    );
    let sc = d
        .spectral_centre
        .as_ref()
        .expect("the spectra show a centre");
    eprintln!(
        "k-Wave g1_freq: verdict {}, spectral centre {:?}",
        d.verdict.effect, sc
    );
    // k-Wave's grid lowers the echoes 2.4-5% ("Known limits"): within 0.15 MHz.
    assert!((sc.centre_hz - 2.2e6).abs() < 0.15e6, "{sc:?}");
    assert!(sc.range_hz[0] < 0.85 * 2.5e6, "{sc:?}");
    assert_eq!(d.verdict.effect, "center_frequency");
    let f = named_value(&d, "probe.center_frequency_hz");
    assert!(f > sc.range_hz[0] && f < sc.range_hz[1], "{f} in {sc:?}");
    assert!((f - 2.2e6).abs() < 0.15e6, "{f}");
}

/// k-Wave's ring g1 with 0.5 dB/(cm·MHz) in water and wall: the image names
/// no effect (the calibrated wall's impedance stands in for the darkening,
/// docs/diagnosis.md), and the echoes' spectra, against the scene as given,
/// name the medium's attenuation (verdict test 10) near its true value. At
/// full size (20 rays, 40 iterations): 0.499 ± 0.004 dB/(cm·MHz).
#[test]
fn tier_b_kwave_ring_attenuation_is_named_from_the_echoes_spectra() {
    let d = diagnose_kwave_g1("g1_atten", true, 12);
    let sa = d.spectral_attenuation.as_ref();
    eprintln!(
        "k-Wave g1_atten: verdict {}, spectra {:?}",
        d.verdict.effect,
        sa.map(|s| (
            s.named,
            s.shift.attenuation_db_cm_mhz,
            s.shift.attenuation_std
        ))
    );
    assert_eq!(d.verdict.effect, "attenuation");
    let sa = sa.expect("the spectral shift was measured");
    assert!(sa.named);
    let (a, se) = (
        sa.shift.attenuation_db_cm_mhz,
        sa.shift.attenuation_std.unwrap(),
    );
    // Named, and within 20% of the hidden value.
    assert!(a >= 3.0 * se, "{a} ± {se}");
    assert!((a - 0.5).abs() < 0.1, "{a} ± {se}");
    assert_eq!(named_value(&d, "medium.attenuation_db_cm_mhz"), a);
}
