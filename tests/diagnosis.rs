//! The sim-to-real diagnosis (issue 6) at CI size, the blind benchmark's draws of
//! the default master seed on a 32-element cylinder: the paper's case — a thick
//! ring diagnosed against a zero-thickness (solid) cylinder — must name
//! `wall_thickness`, find the wall and shrink the radius bias; attenuation, volume
//! scattering, sound speed and pulse length draws must name their effect; a draw
//! with no effect must not name one, nor an unmodelled wire; a depth gain must be named with the paired loss, and a gain
//! down with depth images as attenuation (why the catalogue's gain only goes up).

use usray::optim::blind::{
    draw, measured_image, verdict_is_false_effect, BlindOptions, Draw, KINDS,
};
use usray::optim::{
    catalogue, diagnose, parameter_candidates, score_candidate, Candidate, DiagnoseOptions,
    Diagnosis, Journal, LossSetup, Objective, Score,
};
use usray::signal::ChannelData;
use usray::transport::scene::Owner;
use usray::transport::{ParamKey, RenderOptions, Scene};

/// The key of a dotted parameter path (the tests name parameters by path).
fn key(path: &str) -> ParamKey {
    path.parse().unwrap()
}

mod common;

/// The diagnoses of this file run one at a time: each renders on every core
/// already, and the paper's case compares the time of its scoring with its
/// refits', which another test's load would disturb unevenly.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    // A test that panicked while holding the lock has reported its failure.
    ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The CI-size cylinder on a 0.25 mm grid.
fn base() -> Scene {
    common::ci_cylinder(0.25e-3)
}

fn options(rays: usize, iters: usize) -> (BlindOptions, DiagnoseOptions) {
    let render = RenderOptions {
        rays_per_element: Some(rays),
        ..Default::default()
    };
    (
        BlindOptions {
            render: render.clone(),
            ..Default::default()
        },
        DiagnoseOptions {
            calibration_iters: iters,
            refit_iters: iters,
            // Two refits instead of three: CI time.
            confirm_top: 2,
            render,
            ..Default::default()
        },
    )
}

/// Blind draw `i` of `kind` from the CI base scene (12 rays/element, 20
/// iterations) and its diagnosis against the base scene.
fn diagnose_draw(i: usize, kind: &str) -> (Scene, Draw, Diagnosis) {
    diagnose_draw_with(i, kind, |d| d)
}

/// [`diagnose_draw`] with the diagnosis options changed by `change`.
fn diagnose_draw_with(
    i: usize,
    kind: &str,
    change: impl FnOnce(DiagnoseOptions) -> DiagnoseOptions,
) -> (Scene, Draw, Diagnosis) {
    let _serial = one_at_a_time();
    let base = base();
    let (b, d) = options(12, 20);
    let drawn = draw(&base, i, &b).unwrap();
    assert_eq!(drawn.kind, kind);
    let measured = measured_image(&drawn, &b).unwrap();
    let r = diagnose(&base, &measured, &change(d), |_| {}).unwrap();
    (base, drawn, r)
}

/// What scoring a candidate against `data` needs: the measured image (the blind
/// benchmark's noise, CI size), the base scene's render options and its loss.
fn scoring_setup(base: &Scene, data: &Draw) -> (Vec<f64>, RenderOptions, f64) {
    let (b, d) = options(12, 20);
    let measured = measured_image(data, &b).unwrap();
    let render = RenderOptions {
        seed: Some(base.acquisition.seed),
        ..d.render
    };
    let base_loss = Objective::new(base.clone(), measured.clone(), vec![], render.clone())
        .unwrap()
        .value(&[])
        .unwrap()
        .loss;
    (measured, render, base_loss)
}

/// `c` scored at `base` against `measured` ([`scoring_setup`]'s outputs) with the
/// default loss.
fn score_at(
    c: &Candidate,
    base: &Scene,
    measured: &[f64],
    base_loss: f64,
    render: &RenderOptions,
) -> Score {
    score_candidate(c, base, measured, base_loss, render, &LossSetup::default()).unwrap()
}

/// Every candidate of the catalogue is a model extension whose parameter at its
/// null gives back the base model (issue 6): switched on at [`Candidate::null`],
/// the scene renders the base scene's channel data bit for bit (same seed). A
/// wall has no null thickness (its null is the solid cylinder), and says so.
#[test]
fn every_candidate_at_its_null_renders_the_base_model() {
    let base = base();
    let opts = RenderOptions {
        rays_per_element: Some(4),
        ..Default::default()
    };
    let render = |scene: &Scene| usray::transport::render(scene, &opts).unwrap().0;
    let reference = render(&base);
    assert!(reference.samples.iter().any(|v| *v != 0.0));
    // Samples of `scene`'s render that differ in their bits from `reference`'s.
    let differing = |reference: &ChannelData, scene: &Scene| {
        render(scene)
            .samples
            .iter()
            .zip(&reference.samples)
            .filter(|(a, b)| a.to_bits() != b.to_bits())
            .count()
    };
    let differing_samples = |scene: &Scene| differing(&reference, scene);
    let mut candidates = catalogue(&base);
    assert!(candidates.len() >= 6, "{candidates:?}");
    // The parameter candidates too, each of them (none calibrated): each one's
    // null is the scene's own value.
    let parameters = parameter_candidates(&base, &[]);
    assert!(parameters.len() >= 3, "{parameters:?}");
    candidates.extend(parameters);
    for c in &candidates {
        let Some(null) = c.null else {
            assert_eq!(c.effect, "wall_thickness", "only a wall lacks a null");
            continue;
        };
        let at_null = differing_samples(&c.switched_on(&base, null).unwrap());
        assert_eq!(
            at_null, 0,
            "{} ({} = {null}): {at_null} samples differ from the base model",
            c.effect, c.key
        );
        // The control: a tenth of the range away from the null, it does differ.
        let away = null + 0.1 * (c.range.1 - c.range.0);
        let switched = differing_samples(&c.switched_on(&base, away).unwrap());
        assert!(switched > 0, "{} = {away} renders as the base model", c.key);
    }
    // A hollow cylinder has one more: scatterers in its lumen.
    let wall = candidates
        .iter()
        .find(|c| c.effect == "wall_thickness")
        .unwrap();
    let hollow = wall.switched_on(&base, wall.onsets[0]).unwrap();
    let hollow_reference = render(&hollow);
    let lumen = catalogue(&hollow)
        .into_iter()
        .find(|c| c.key.to_string() == "objects.cylinder.lumen_scatterer_strength")
        .expect("a lumen candidate for the hollow cylinder");
    let null = lumen.null.unwrap();
    for (value, renders_as_base) in [(null, true), (0.1 * lumen.range.1, false)] {
        let on = lumen.switched_on(&hollow, value).unwrap();
        let same = differing(&hollow_reference, &on) == 0;
        assert_eq!(same, renders_as_base, "lumen scatterers at {value}");
    }
}

/// The paper's case: data from a ring whose wall is a draw of 0.25–0.4 × the
/// radius, diagnosed against the plain cylinder (at 7 bounces, the scene's 5 and
/// two for the wall). Measured: verdict `wall_thickness`, held-out shrink 0.78,
/// wall 1.867 mm found for 1.893 mm (z −3.9 in noise-only spreads), radius
/// 5.081 mm calibrated and 5.001 mm with the wall (true 5). (Step times are
/// reported, not asserted: docs/diagnosis.md has them at full size.)
#[test]
fn thick_ring_against_a_solid_cylinder_names_wall_thickness() {
    let (base, wall, r) = diagnose_draw(0, KINDS[0]);
    let refit = r.effects.iter().find(|e| e.effect == "wall_thickness");
    let found = refit.and_then(|e| e.params.get("objects.cylinder.thickness_m").copied());
    let radius_after = refit.and_then(|e| e.params.get("objects.cylinder.radius_m").copied());
    eprintln!(
        "thick ring {:.3e} m: verdict {} (shrink {:.2}), found {found:?}, radius calibrated {:?} → with the wall {radius_after:?}, timings {:?}",
        wall.strength, r.verdict.effect, r.verdict.shrink,
        r.calibrated.params.get("objects.cylinder.radius_m"), r.timings
    );
    assert_eq!(r.verdict.effect, "wall_thickness");
    let t = found.expect("the wall_thickness refit reports the thickness");
    assert!(
        (t / wall.strength - 1.0).abs() < 0.5,
        "thickness {t} vs true {}",
        wall.strength
    );
    // How well the wall is determined: the refit reports its Monte Carlo
    // spread, a small fraction of the wall, and the truth lies within a few
    // spreads of the value found (this spread counts noise, not bias; see
    // docs/diagnosis.md for how it compares with the true error over blind draws).
    let std = refit
        .and_then(|e| e.params_std.get("objects.cylinder.thickness_m").copied())
        .flatten()
        .expect("the wall_thickness refit reports how well the thickness is determined");
    let z = (t - wall.strength) / std;
    eprintln!(
        "thickness {t:.4e} ± {std:.2e} m, true {:.4e} (z {z:+.2})",
        wall.strength
    );
    assert!(
        std > 0.0 && std < 0.1 * wall.strength,
        "spread {std} of a {t} wall"
    );
    assert!(z.abs() < 4.0, "found {t} ± {std}, true {}", wall.strength);
    // The paper's point: the base model's radius is biased by the wall it
    // lacks; once the wall is added, the bias shrinks (measured: +1.6% →
    // +0.03%).
    let r_true = base.get(&key("objects.cylinder.radius_m")).unwrap();
    let r_cal = r.calibrated.params["objects.cylinder.radius_m"];
    let r_after = radius_after.expect("the wall_thickness refit reports the radius");
    assert!(
        (r_after - r_true).abs() < (r_cal - r_true).abs(),
        "radius bias did not shrink: calibrated {r_cal}, with the wall {r_after}, true {r_true}"
    );
    // The shrink is measured on several held-out seeds and carries its standard
    // error; the wall beats the null refit (the base parameters refitted alone)
    // by more than the naming threshold, by several standard errors, and removes
    // most of the gap above the noise level.
    let named = r
        .effects
        .iter()
        .find(|e| e.effect == "wall_thickness")
        .unwrap();
    let (excess, se) = (
        named.excess.unwrap(),
        named
            .excess_std
            .expect("an excess on several held-out seeds has a standard error"),
    );
    let defaults = DiagnoseOptions::default();
    eprintln!(
        "wall shrink {:.3} ± {:.3}, null refit {:.3}, excess {excess:.3} ± {se:.3}, gap explained {:?}",
        r.verdict.shrink,
        named.shrink_std.unwrap(),
        r.null_refit.shrink,
        named.gap_explained
    );
    let spatial = named
        .excess_spatial_std
        .expect("a refit's excess has a standard error over the image");
    assert!(se > 0.0 && excess > defaults.rule.min_excess_z * se);
    assert!(spatial > 0.0 && excess > defaults.rule.min_spatial_z * spatial);
    assert!(named.gap_explained.unwrap() > 0.5);
}

/// Settings that would leave a step without data are refused, naming the setting.
#[test]
fn zero_held_out_seeds_or_spread_pairs_are_refused() {
    let base = base();
    let (nz, nx) = usray::optim::grid_shape(&base).unwrap();
    let measured = vec![0.0; nz * nx];
    for (opts, what) in [
        (
            DiagnoseOptions {
                held_out_seeds: 0,
                ..Default::default()
            },
            "held_out_seeds",
        ),
        (
            DiagnoseOptions {
                spread_pairs: 0,
                ..Default::default()
            },
            "spread_pairs",
        ),
    ] {
        let t = std::time::Instant::now();
        let err = diagnose(&base, &measured, &opts, |_| {})
            .unwrap_err()
            .to_string();
        assert!(err.contains(what), "{err}");
        assert!(t.elapsed().as_secs_f64() < 1.0, "refused only after work");
    }
}

/// A draw with no effect (measurement noise only) must not name an effect.
/// Measured before the noise check (noise at −60 dB of the largest channel
/// sample): held-out loss 1.07e-2 against a Monte Carlo noise level of 8.1e-3, so
/// one simulated image's noise is 38% of the held-out loss: more than the 25% a
/// decision needs, and the verdict is `inconclusive`, not `none`.
///
/// With the paired loss (`DiagnoseOptions::paired`) the calibrated roughness must
/// lie nearer the truth (0.3) than the one-render loss's: the one-render
/// calibration smooths the wall to quiet the simulation.
///
/// With a budget too small to raise the rays (1 s), the diagnosis must go on at
/// the rays it has and, its noise above the target, end `inconclusive` and say
/// how many rays a decision would need.
#[test]
fn no_effect_names_no_false_effect() {
    let (base, _, r) = diagnose_draw_with(6, "none", |d| DiagnoseOptions {
        budget_s: Some(1.0),
        ..d
    });
    eprintln!(
        "no effect: verdict {} (shrink {:.2}); held-out {:.3e}, noise {:.3e}, share {:.2}",
        r.verdict.effect,
        r.verdict.shrink,
        r.calibrated.loss_held_out,
        r.noise_loss,
        r.noise_check.share
    );
    assert!(!verdict_is_false_effect("none", &r.verdict.effect));
    assert!(["none", "inconclusive"].contains(&r.verdict.effect.as_str()));
    // `none` only where the noise check passed.
    assert_eq!(r.verdict.effect == "none", r.noise_check.passed);
    // Too small a budget buys no rays: the diagnosis goes on at 12, and with
    // its noise above the target it cannot say `none`.
    assert_eq!(
        r.noise_check.history.len(),
        1,
        "rays raised past the budget"
    );
    assert_eq!(r.verdict.effect, "inconclusive");
    let needed = r.noise_check.rays_needed.expect("a gap above the noise");
    assert!(needed > 12 && r.noise_check.seconds_needed.unwrap() > 1.0);
    assert!(!r.noise_check.passed && r.noise_check.share > 0.25);
    let paired = {
        let _serial = one_at_a_time();
        let (b, mut d) = options(12, 20);
        d.paired = true;
        let measured = measured_image(&draw(&base, 6, &b).unwrap(), &b).unwrap();
        diagnose(&base, &measured, &d, |_| {}).unwrap()
    };
    let roughness = |d: &Diagnosis| d.calibrated.params["materials.target.roughness"];
    let truth = base.get(&key("materials.target.roughness")).unwrap();
    eprintln!(
        "paired: verdict {}; held-out {:.3e}, noise {:.3e}; roughness {:.3} (one render {:.3}, true {truth})",
        paired.verdict.effect,
        paired.calibrated.loss_held_out,
        paired.noise_loss,
        roughness(&paired),
        roughness(&r)
    );
    assert!(["none", "inconclusive"].contains(&paired.verdict.effect.as_str()));
    assert!((roughness(&paired) - truth).abs() < (roughness(&r) - truth).abs());
}

/// A draw whose effect is outside the catalogue — an unmodelled wire beside the
/// cylinder — must not be named as a catalogue effect, and no candidate may
/// explain its gap. Measured: held-out loss 2.4e-2 against a noise level of
/// 9.1e-3 (the noise 19% of the gap: the check passes), no refit significant:
/// verdict `none` — no candidate effect above its limit of detection, which is
/// what `none` states; the residual maps show the wire.
#[test]
fn unmodelled_wire_names_no_effect() {
    let (_, wire, r) = diagnose_draw(7, "outside");
    eprintln!(
        "wire at depth {:.2} mm: verdict {} (shrink {:.2}); held-out {:.3e}, noise {:.3e}; {:?}",
        wire.strength * 1e3,
        r.verdict.effect,
        r.verdict.shrink,
        r.calibrated.loss_held_out,
        r.noise_loss,
        r.effects
            .iter()
            .map(|e| (e.effect.as_str(), e.shrink, e.gap_explained))
            .collect::<Vec<_>>()
    );
    assert!(!verdict_is_false_effect("outside", &r.verdict.effect));
    // The wire leaves a real gap, and no candidate removes a quarter of it (the
    // catalogue's effects remove 0.63–1.13 of theirs on the blind benchmark).
    assert!(r.calibrated.loss_held_out > 1.5 * r.noise_loss);
    for e in r.effects.iter().filter(|e| e.shrink.is_some()) {
        let g = e.gap_explained.expect("a real gap has a share explained");
        assert!(g < 0.25, "{} explains {g:.2} of the wire's gap", e.effect);
    }
}

/// A sound-speed error past the pulse length: +4% moves the cylinder's far wall
/// (≈ 20 mm) by ≈ 0.8 mm, about the 3-cycle pulse's length, so the loss is far from
/// quadratic in the speed at the null. Scored from the best of the catalogue's five
/// onsets 2.5% apart, the candidate must find the speed and a real cut of the
/// loss; scored from the null alone (as before session 4, when blind draw 19 of
/// seed 7, +3.8%, was missed) it must do worse.
#[test]
fn sound_speed_error_past_the_pulse_length_is_scored_from_several_onsets() {
    let _serial = one_at_a_time();
    let base = base();
    let c0 = base.medium.sound_speed_m_s;
    let mut scene = base.clone();
    scene.imaging.sound_speed_m_s = Some(c0);
    scene.medium.sound_speed_m_s = 1.04 * c0;
    let data = Draw {
        kind: "sound_speed",
        strength: 0.04,
        scene,
        seed: 4242,
    };
    let (measured, render, base_loss) = scoring_setup(&base, &data);
    let speed = catalogue(&base)
        .into_iter()
        .find(|c| c.effect == "sound_speed")
        .unwrap();
    let score = |c: &Candidate| score_at(c, &base, &measured, base_loss, &render);
    let several = score(&speed);
    let one = score(&Candidate {
        onsets: vec![c0],
        ..speed.clone()
    });
    eprintln!(
        "sound speed +4%: five onsets score {:.3} from {:.1} m/s; null only {:.3} from {:.1} m/s (true {:.1})",
        several.score,
        several.start,
        one.score,
        one.start,
        1.04 * c0
    );
    assert!(
        (several.start / (1.04 * c0) - 1.0).abs() < 0.015,
        "refit would start at {} m/s for {} m/s",
        several.start,
        1.04 * c0
    );
    // A cut of a fifth of the loss (a real effect's, on the blind benchmark),
    // and one that exceeds the null-only score by more than the verdict's tie
    // margin (0.05: shrinks closer than that are reported as alternatives).
    let real_cut = 0.2;
    assert!(several.score > real_cut, "score {}", several.score);
    assert!(several.score > one.score + 0.05);

    // Scored from its null as well (as the centre frequency is where the
    // echoes' spectra add an onset): the better of the two scores, here the
    // onsets' (asserted above), with its onset and start, bit for bit (same
    // seed, same renders).
    let both = score(&Candidate {
        also_scored_from_null: true,
        ..speed.clone()
    });
    assert_eq!(both, several);
}

/// A candidate refitted whatever its score (the medium's sound speed) whose best
/// scored point is its null must start its refit elsewhere: at the null the loss
/// is at its minimum and the refit has no gradient to leave by, so it would
/// only ever repeat the null refit. On data rendered from the base scene itself
/// (another seed, the blind benchmark's noise) the speed's best onset is the
/// null; its refit must start from the better of its nearest onsets (2.5% either
/// side: a farther one moves the far wall by more than the pulse's length),
/// while the same candidate not refitted-always starts at its null.
#[test]
fn a_candidate_refitted_whatever_its_score_starts_away_from_its_null() {
    let _serial = one_at_a_time();
    let base = base();
    let c0 = base.medium.sound_speed_m_s;
    let data = Draw {
        kind: "none",
        strength: 0.0,
        scene: base.clone(),
        seed: 4243,
    };
    let (measured, render, base_loss) = scoring_setup(&base, &data);
    let speed = catalogue(&base)
        .into_iter()
        .find(|c| c.effect == "sound_speed")
        .unwrap();
    assert!(
        speed.refit_always,
        "the catalogue's speed is refitted always"
    );
    let score = |c: &Candidate| score_at(c, &base, &measured, base_loss, &render);
    let scored_only = score(&Candidate {
        refit_always: false,
        ..speed.clone()
    });
    let always = score(&speed);
    eprintln!(
        "no effect: speed onset {:.1} m/s, start {:.1} (scored only) and {:.1} (refitted always); null {c0:.1}",
        always.onset, scored_only.start, always.start
    );
    assert_eq!(always.onset, c0, "the data hold no speed error");
    assert_eq!(scored_only.start, c0);
    assert!(
        [0.975 * c0, 1.025 * c0].contains(&always.start),
        "refit would start at {} m/s",
        always.start
    );
    // The rest of the score does not depend on where the refit starts.
    assert_eq!(
        (always.score, always.gradient, always.loss_onset),
        (
            scored_only.score,
            scored_only.gradient,
            scored_only.loss_onset
        )
    );
}

/// An attenuation inside the object: the loss falls almost linearly from the null
/// to its minimum near the true 0.66 dB/(cm·MHz) and rises beyond, so the Newton
/// step overshoots to the range's bound. Scoring must halve it back into the
/// basin: before it did (session 7), blind draw 9 of master seed 1 scored this
/// candidate 0.009 from a step to 2 dB/(cm·MHz) where the loss at 0.5 was half the
/// calibrated one, and the diagnosis named the depth gain instead.
#[test]
fn attenuation_inside_the_object_is_scored_inside_its_basin() {
    let _serial = one_at_a_time();
    let base = base();
    let alpha = 0.66;
    let mut scene = base.clone();
    scene.medium.attenuation_db_cm_mhz = alpha;
    for m in scene.materials.values_mut() {
        m.attenuation_db_cm_mhz = alpha;
    }
    let data = Draw {
        kind: "attenuation",
        strength: alpha,
        scene,
        seed: 4243,
    };
    let (measured, render, base_loss) = scoring_setup(&base, &data);
    let scores: Vec<(Candidate, f64, f64)> = catalogue(&base)
        .into_iter()
        .filter(|c| c.effect == "attenuation" || c.effect == "depth_gain")
        .map(|c| {
            let s = score_candidate(
                &c,
                &base,
                &measured,
                base_loss,
                &render,
                &LossSetup::default(),
            )
            .unwrap();
            (c, s.score, s.start)
        })
        .collect();
    for (c, score, start) in &scores {
        eprintln!("{}: score {score:.3}, refit from {start:.3}", c.key);
    }
    let inside = scores
        .iter()
        .find(|(c, ..)| matches!(c.key.owner, Owner::Material(_)))
        .unwrap();
    let (_, score, start) = inside;
    assert!(*score > 0.2, "score {score}");
    assert!(
        (0.5 * alpha..=2.0 * alpha).contains(start),
        "refit would start at {start} for {alpha}"
    );
    // It outscores the depth gain and the background's attenuation.
    for (c, other, _) in scores.iter().filter(|(c, ..)| c.key != inside.0.key) {
        assert!(score > other, "{} scores {other} ≥ {score}", c.key);
    }
}

/// Why the catalogue's depth gain only goes up: a gain *down* with depth images
/// as attenuation. A tissue attenuation `α` dB/(cm·MHz) takes `α·f_c` dB per cm
/// of path at the centre frequency, `2α·f_c` per cm of depth there and back,
/// which is a depth gain of `g = −2α·f_c` dB/cm on every path (Szabo, *Diagnostic
/// Ultrasound Imaging*, §4; the spectral down-shift aside). Rendered with the
/// same rays, the two B-modes of the CI cylinder differ by less than one frame
/// of Monte Carlo noise (the same scene with another seed), and by a fraction
/// of what either changes in the base model's image (rms 0.006 against 0.035
/// and 0.032 of the grey scale).
#[test]
fn a_gain_down_with_depth_images_as_attenuation() {
    let _serial = one_at_a_time();
    let base = base();
    let alpha = 0.5;
    let g = -2.0 * alpha * base.probe.center_frequency_hz / 1e6;
    let mut gain = base.clone();
    gain.set(&key("acquisition.depth_gain_db_per_cm"), g)
        .unwrap();
    let mut attenuation = base.clone();
    attenuation.medium.attenuation_db_cm_mhz = alpha;
    for m in attenuation.materials.values_mut() {
        m.attenuation_db_cm_mhz = alpha;
    }
    // Noise-free B-modes (measurement noise 300 dB down) at 12 rays.
    let (b, _) = options(12, 0);
    let b = BlindOptions {
        noise_db: 300.0,
        ..b
    };
    let image = |scene: &Scene, seed: u64| {
        let d = Draw {
            kind: "none",
            strength: 0.0,
            scene: scene.clone(),
            seed,
        };
        measured_image(&d, &b).unwrap()
    };
    let rms = |a: &[f64], b: &[f64]| {
        (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
    };
    let with_gain = image(&gain, 4242);
    let as_attenuation = rms(&with_gain, &image(&attenuation, 4242));
    let noise = rms(&with_gain, &image(&gain, 4243));
    let effect = rms(&with_gain, &image(&base, 4242));
    eprintln!(
        "g = {g} dB/cm against α = {alpha} dB/(cm·MHz): rms {as_attenuation:.4}; \
         another seed {noise:.4}; the base model {effect:.4}"
    );
    assert!(as_attenuation < noise, "{as_attenuation} ≥ {noise}");
    assert!(
        effect > 3.0 * as_attenuation,
        "{effect} ≤ 3 × {as_attenuation}"
    );
}

/// The CI-size blind benchmark's other catalogue kinds: blind draws 1
/// (attenuation), 2 (volume scattering), 3 (sound speed) and 5 (pulse length) of
/// the default master seed must each name their effect (the depth gain, draw 4,
/// with the paired loss: [`blind_depth_gain_draw_is_named_with_the_paired_loss`]).
#[test]
fn blind_draws_of_four_more_kinds_name_their_effect() {
    for (i, kind) in [(1, KINDS[1]), (2, KINDS[2]), (3, KINDS[3]), (5, KINDS[5])] {
        let (_, d, r) = diagnose_draw(i, kind);
        eprintln!(
            "draw {i} {kind} {:+.3e}: verdict {} (shrink {:.2}), alternatives {:?}; scores {:?}",
            d.strength,
            r.verdict.effect,
            r.verdict.shrink,
            r.verdict.alternatives,
            r.effects
                .iter()
                .map(|e| (e.effect.as_str(), e.score, e.shrink))
                .collect::<Vec<_>>()
        );
        assert_eq!(r.verdict.effect, kind, "draw {i}");
    }
}

/// The CI-size blind benchmark's depth gain: draw 4 of the default master seed
/// (+3.95 dB/cm) is named by the paired loss (held-out excess 0.22 over the null
/// refit, two thirds of the gap). The one-render loss calls it `none` (excess
/// 0.12): its calibration absorbs part of a gain up with depth into a smoother
/// wall, which a pixel loss against noisy data rewards (`docs/diagnosis.md`).
#[test]
fn blind_depth_gain_draw_is_named_with_the_paired_loss() {
    let (_, drawn, r) =
        diagnose_draw_with(4, "depth_gain", |d| DiagnoseOptions { paired: true, ..d });
    let gain = r.effects.iter().find(|e| e.effect == "depth_gain").unwrap();
    eprintln!(
        "gain {:+.2} dB/cm: verdict {} (shrink {:.2}); found {:?}, excess {:?}, gap explained {:?}",
        drawn.strength,
        r.verdict.effect,
        r.verdict.shrink,
        gain.params.get(&gain.path),
        gain.excess,
        gain.gap_explained
    );
    assert_eq!(r.verdict.effect, "depth_gain");
}

/// A diagnosis killed midway and resumed from its journal ends with the same
/// results as one never interrupted (issue 23): the kill is the journal as it
/// stood when the null refit began (the calibration kept, no refit yet),
/// copied aside and resumed from. Small settings: what is tested is the
/// resume, not the verdict.
#[test]
fn a_diagnosis_resumed_from_its_journal_gives_the_same_results() {
    let _serial = one_at_a_time();
    let base = base();
    let (b, mut d) = options(6, 6);
    d.confirm_top = 1;
    d.held_out_seeds = 2;
    d.spread_pairs = 1;
    d.budget_s = Some(1.0);
    let measured = measured_image(&draw(&base, 0, &b).unwrap(), &b).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("diagnose.checkpoint.json");
    let killed = dir.path().join("killed.json");
    let full = diagnose(
        &base,
        &measured,
        &DiagnoseOptions {
            journal: Journal::open(&file, "draw 0", false).unwrap(),
            ..d.clone()
        },
        |msg| {
            if msg.starts_with("refitting the base parameters") {
                std::fs::copy(&file, &killed).unwrap();
            }
        },
    )
    .unwrap();
    let kept = Journal::open(&killed, "draw 0", true).unwrap();
    assert!(kept
        .get::<serde_json::Value>("calibration 0")
        .unwrap()
        .is_some());
    assert!(kept
        .get::<serde_json::Value>("null refit")
        .unwrap()
        .is_none());
    let resumed = diagnose(
        &base,
        &measured,
        &DiagnoseOptions {
            journal: kept,
            ..d.clone()
        },
        |_| {},
    )
    .unwrap();
    // Everything but the timings, compared as JSON (every f64 printed exactly).
    let results = |r: &Diagnosis| {
        let mut v = serde_json::to_value(r).unwrap();
        v.as_object_mut().unwrap().remove("timings");
        v
    };
    assert_eq!(results(&resumed), results(&full));
}
