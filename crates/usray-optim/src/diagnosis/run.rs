//! A diagnosis's steps in order ([`diagnose`]), and the compound-gap rounds
//! that switch a named effect on and diagnose again ([`diagnose_compound`]).

use super::calibration::{
    calibrate_within_budget, calibration_spec, default_free_params, FreeParam,
};
use super::catalogue::{catalogue, diagnosis_bounces, Candidate};
use super::confirmation::second_looks;
use super::more_rays::more_rays_looks;
use super::options::{DiagnoseOptions, FirstRound};
use super::parameter_candidates::parameter_candidates;
use super::refits::{null_refit, quarter_from_null, refit_leading, Control};
use super::residual::{analyse_residual, ResidualOptions};
use super::results::{Calibrated, Diagnosis, EffectResult, Timings};
use super::screening::{screen, Screening};
use super::spectral_check::{
    attenuation_from_spectra, check_centre_frequency, measured_shift, widen_centre_frequency,
};
use super::verdict::{name_effect, unnamed_verdict, Verdict};
use crate::spread::parameter_spread;
use crate::OptimError;
use std::time::Instant;
use usray_transport::{ParamKey, RenderOptions, Scene};

/// Runs the diagnosis of `scene` against the measured B-mode `measured` (`[nz, nx]`
/// on the scene's grid); `progress` receives one line per step.
///
/// A candidate whose scoring or refit fails (a render error at an extreme of
/// its range) is recorded with [`EffectResult::failed`] and the diagnosis goes
/// on without it.
///
/// # Errors
/// Settings it cannot run with (`spread_pairs` or `held_out_seeds` of 0, a
/// `noise_share` outside (0, 1), a budget that is not a positive number,
/// held-out data of another size), a parameter the scene does not have, a
/// measured image of the wrong shape, or a failing calibration.
pub fn diagnose(
    scene: &Scene,
    measured: &[f64],
    opts: &DiagnoseOptions,
    mut progress: impl FnMut(&str),
) -> Result<Diagnosis, OptimError> {
    let held_data = opts.held_out_data(measured)?;
    let started = Instant::now();
    // Every model renders at the bounce limit the candidates need.
    let mut scene = scene.clone();
    scene.acquisition.max_bounces = diagnosis_bounces(&scene);
    let scene = &scene;
    let max_bounces = scene.acquisition.max_bounces;
    let mut timings = Timings::default();
    let free: Vec<FreeParam> = if opts.free_params.is_empty() {
        default_free_params(scene)
            .into_iter()
            .map(FreeParam::new)
            .collect()
    } else {
        opts.free_params.clone()
    };
    let specs = free
        .iter()
        .map(|p| calibration_spec(scene, p))
        .collect::<Result<Vec<_>, OptimError>>()?;
    let calibrated_keys: Vec<_> = specs.iter().map(|s| s.key.clone()).collect();

    // Step 1: calibrate, and raise the rays while the simulation's noise holds
    // too large a share of the gap and the budget allows.
    let (stage, noise_check) = calibrate_within_budget(
        scene,
        measured,
        held_data,
        &specs,
        opts,
        started,
        &mut timings,
        &mut progress,
    )?;
    // A later round stops here when its time, estimated from its calibration
    // stage as the first round's whole time was from its own, is more than the
    // budget it was given: its scene (the named effect switched on) may render
    // far slower than the first round's. Decided on the wall clock, so kept
    // for a resumed run.
    if let (Some(first), Some(budget)) = (&opts.first_round, opts.budget_s) {
        let stage_s = timings.calibration_stage_s();
        let estimate_s = opts.journal.remember("round seconds estimated", || {
            Ok(stage_s * first.seconds_over_calibration)
        })?;
        if estimate_s > budget {
            return Err(OptimError::Budget {
                message: format!(
                    "its calibration took {stage_s:.0} s, so the round would take about {estimate_s:.0} s ({:.1} times its calibration, as the first round took), more than the {budget:.0} s left",
                    first.seconds_over_calibration
                ),
                estimate_s,
            });
        }
    }
    let t = Instant::now();
    let cal_std = parameter_spread(
        &stage.objective,
        &stage.params,
        &stage.eval.image.data,
        &stage.held[0].image.data,
        opts.spread_pairs,
    )?;
    timings.spread_s += t.elapsed().as_secs_f64();

    // Step 2: where.
    let residual = analyse_residual(
        &stage.scene,
        &stage.eval.image.data,
        measured,
        &ResidualOptions::default(),
    )?;

    // The measured echoes' spectra against the round's scene as given, where
    // the data are channels: the centre frequency they show widens its
    // candidate's range, and test 10 reads the attenuation they show.
    let t = Instant::now();
    let given_shift = if opts.measured_channels.is_some() {
        progress("measuring the echoes' spectra against the scene along their path");
        measured_shift(scene, &stage, opts, &mut progress)
    } else {
        None
    };
    let mut candidates = candidates(&stage.scene, &calibrated_keys);
    let spectral_centre = widen_centre_frequency(
        &mut candidates,
        given_shift.as_ref(),
        scene.probe.center_frequency_hz,
        &opts.rule,
    );
    timings.spectral_s = t.elapsed().as_secs_f64();

    // Step 3: score every candidate by one value + gradient at its onset.
    let t = Instant::now();
    let Screening {
        mut effects,
        starts,
        order,
    } = screen(&candidates, &stage, measured, &mut progress);
    timings.scoring_s = t.elapsed().as_secs_f64();

    // Step 4: the null refit, then the leading candidates' refits; held-out
    // shrinks.
    let t = Instant::now();
    progress("refitting the base parameters alone (the null refit)");
    let Control {
        null_refit,
        baseline,
        baseline_scene,
    } = null_refit(&stage, &specs, measured, held_data, opts)?;
    timings.null_refit_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (mut refits, refit_spread_s) = refit_leading(
        &candidates,
        &starts,
        &order,
        &mut effects,
        &stage,
        &specs,
        &baseline,
        measured,
        held_data,
        opts,
        &mut progress,
    );
    timings.refits_s = t.elapsed().as_secs_f64() - refit_spread_s;
    timings.spread_s += refit_spread_s;

    // In a later round: whether each refitted effect adds to the first round's.
    if let Some(first) = &opts.first_round {
        for r in &refits {
            let e = &mut effects[r.candidate];
            e.additivity = additivity(&e.path, e.excess, first, stage.held_loss);
        }
    }

    // A second look at a refit that would be named but for its standard
    // error over the seeds: it and the control on fresh seeds.
    let t = Instant::now();
    second_looks(
        &refits,
        &mut effects,
        &stage,
        &baseline_scene,
        held_data,
        opts,
        noise_check.passed,
        started,
        &mut progress,
    )?;
    timings.confirmation_s = t.elapsed().as_secs_f64();

    // Every refit that would be named, and the control, at more rays: a gain
    // that falls with the simulation's noise is the noise's, not the data's.
    timings.more_rays_s = more_rays_looks(
        &refits,
        &mut effects,
        &stage,
        &baseline_scene,
        held_data,
        opts,
        noise_check.passed,
        &mut progress,
    );

    // A centre frequency that would be named, checked against how the
    // measured echoes' spectra shift along their path.
    let t = Instant::now();
    let spectral_shift = check_centre_frequency(
        &refits,
        &mut effects,
        &stage,
        &baseline_scene,
        opts,
        noise_check.passed,
        &mut progress,
    );
    timings.spectral_s += t.elapsed().as_secs_f64();

    // Step 5: verdict.
    let refitted: Vec<EffectResult> = refits
        .iter()
        .map(|r| effects[r.candidate].clone())
        .collect();
    let named = name_effect(&refitted, noise_check.passed, &opts.rule).map(|(i, tied)| {
        let k = refits[i].candidate;
        let alternatives: Vec<String> = tied
            .iter()
            .map(|&j| effects[refits[j].candidate].effect.clone())
            .filter(|e| *e != effects[k].effect)
            .collect();
        (i, alternatives)
    });
    // The effect the image names; where it names nothing, the attenuation
    // the echoes' spectra show against the scene as given (test 10).
    let unnamed = unnamed_verdict(&refitted, &opts.rule, noise_check.passed);
    let mut spectral_attenuation = None;
    let named = match named {
        Some((i, alternatives)) => {
            let r = refits.swap_remove(i);
            Some((r.candidate, alternatives, r.image_s, r.scene))
        }
        None if unnamed == "none" => {
            let t = Instant::now();
            let (shown, from_spectra) = attenuation_from_spectra(
                scene,
                given_shift.as_ref(),
                &candidates,
                &mut effects,
                &stage,
                &baseline_scene,
                &baseline,
                measured,
                held_data,
                opts,
                &mut progress,
            );
            timings.spectral_s += t.elapsed().as_secs_f64();
            spectral_attenuation = shown;
            from_spectra.map(|n| (n.candidate, vec![], n.image_s, n.scene))
        }
        None => None,
    };
    let (verdict, after_image, after_scene) = match named {
        Some((k, alternatives, image_s, named_scene)) => {
            let e = &effects[k];
            (
                Verdict {
                    effect: e.effect.clone(),
                    path: Some(e.path.clone()),
                    shrink: e.shrink.unwrap_or(0.0),
                    alternatives,
                },
                image_s,
                Some(named_scene),
            )
        }
        None => (
            Verdict {
                effect: unnamed.into(),
                path: None,
                shrink: 0.0,
                alternatives: vec![],
            },
            stage.eval.image.data.clone(),
            None,
        ),
    };
    let ranked: Vec<EffectResult> = order.iter().map(|&k| effects[k].clone()).collect();
    timings.total_s = started.elapsed().as_secs_f64();
    Ok(Diagnosis {
        calibrated: Calibrated {
            params: specs
                .iter()
                .zip(&stage.params)
                .map(|(s, v)| (s.key.to_string(), *v))
                .collect(),
            params_std: specs
                .iter()
                .zip(cal_std)
                .map(|(s, v)| (s.key.to_string(), v))
                .collect(),
            loss: stage.eval.loss,
            loss_held_out: stage.held_loss,
            held_out_losses: stage.held_losses,
        },
        where_: residual.shares.clone(),
        effects: ranked,
        null_refit,
        rule: opts.rule,
        verdict,
        noise_loss: stage.noise_loss,
        noise_check,
        spread_pairs: opts.spread_pairs,
        held_out_seeds: opts.held_out_seeds,
        paired: opts.paired,
        comparison: stage.setup.comparison,
        held_out_frames: opts.held_out_measured.is_some(),
        max_bounces,
        timings,
        spectral_shift,
        spectral_attenuation,
        spectral_centre,
        next_round_stopped: None,
        residual,
        calibrated_image: stage.eval.image.data,
        after_image,
        after_scene,
    })
}

/// Every candidate of a diagnosis of `scene` whose `calibrated` parameters are
/// fitted: the structural catalogue, then the parameter candidates. A
/// parameter being calibrated (in a later round, the effect an earlier one
/// named) is no candidate.
fn candidates(scene: &Scene, calibrated: &[ParamKey]) -> Vec<Candidate> {
    let mut out = catalogue(scene);
    out.retain(|c| !calibrated.contains(&c.key));
    out.extend(parameter_candidates(scene, calibrated));
    out
}

/// [`EffectResult::additivity`] of the refitted effect on `path` with
/// [`EffectResult::excess`] `excess`, in a round whose calibrated held-out loss
/// is `loss_held_out`.
fn additivity(
    path: &str,
    excess: Option<f64>,
    first: &FirstRound,
    loss_held_out: f64,
) -> Option<f64> {
    let score_1 = *first.scores.get(path)?;
    let removed = excess.filter(|x| *x > 0.0)? * loss_held_out / first.loss_held_out;
    Some(score_1 / removed)
}

/// Compound gaps: diagnoses `scene`; while the verdict names an effect and
/// fewer than `rounds` rounds have run, switches the named effect on at its
/// refitted value, adds its parameter to the calibrated ones (within its
/// candidate range) and diagnoses again; a later round names an effect only if
/// it adds to the first round's ([`EffectResult::additivity`],
/// [`super::VerdictRule::min_additivity`]). Returns every round's diagnosis, in
/// order: the ranked list of effects, each with its shrink. With
/// [`DiagnoseOptions::budget_s`], a further round starts only where what is
/// left of the budget is at least the last round's time, receives that
/// remainder as its own, and stops after its calibration where its time,
/// estimated from that calibration as many times over as the first round's
/// whole time was over its own ([`FirstRound::seconds_over_calibration`]), is
/// more than the remainder: a round whose scene renders slower (a named wall
/// switched on) is caught there. Why no further round ran is kept in the last
/// round's [`Diagnosis::next_round_stopped`].
///
/// # Errors
/// As [`diagnose`], for the first round; a later round's error ends the list
/// (reported through `progress`).
pub fn diagnose_compound(
    scene: &Scene,
    measured: &[f64],
    opts: &DiagnoseOptions,
    rounds: usize,
    mut progress: impl FnMut(&str),
) -> Result<Vec<Diagnosis>, OptimError> {
    let started = Instant::now();
    let first = diagnose(scene, measured, opts, &mut progress)?;
    let mut out = vec![first];
    while out.len() < rounds {
        let last = out.last().expect("one round at least");
        let (Some(next_scene), Some(path)) = (&last.after_scene, &last.verdict.path) else {
            break;
        };
        let Some(named) = last.effects.iter().find(|e| &e.path == path) else {
            break;
        };
        // The calibrated parameters (in the report's order) with their default
        // ranges, and the named effect's parameter with its refit's range.
        let mut free = last
            .calibrated
            .params
            .keys()
            .map(|p| Ok(FreeParam::new(next_scene.key(p)?)))
            .collect::<Result<Vec<_>, OptimError>>()?;
        let named_key = next_scene.key(path)?;
        free.push(FreeParam {
            key: named_key.clone(),
            range: Some((named.range[0], named.range[1])),
        });
        // An effect found close to its null (a faint speckle) is calibrated
        // with steps of at most a quarter of its distance from it, so that no
        // first step lands on the null, where the clip map's derivative is
        // zero and the effect could not come back (as in its refit,
        // `refits::refit_learning_rate`).
        let mut fit = opts.fit.clone();
        let [lo, hi] = named.range;
        let quarter = match (named.null, named.params.get(path)) {
            (Some(null), Some(&found)) if null == lo || null == hi => {
                quarter_from_null((lo, hi), null, found)
            }
            _ => None,
        };
        if let Some(quarter) = quarter {
            let lr = quarter.min(fit.learning_rate_of(&named_key));
            fit.lr_overrides.insert(0, (named_key, lr));
        }
        let elapsed = started.elapsed().as_secs_f64();
        // Whether to go on and the budget left, decided on the wall clock and so
        // kept for a resumed run: a round starts only if the budget left pays
        // for one as long as the last.
        let round_no = out.len() + 1;
        let budget_s: Result<Option<f64>, String> = opts
            .journal
            .remember(&format!("round {round_no} budget left"), || {
                Ok(match opts.budget_s {
                    Some(b) if b - elapsed < last.timings.total_s => {
                        let advice = budget_that_would_do(elapsed + last.timings.total_s, "start");
                        Err(format!(
                            "the budget left, {:.0} s, is less than the last round took ({:.0} s); {advice}",
                            (b - elapsed).max(0.0),
                            last.timings.total_s,
                        ))
                    }
                    Some(b) => Ok(Some(b - elapsed)),
                    None => Ok(None),
                })
            })?;
        let budget_s = match budget_s {
            Ok(b) => b,
            Err(why) => {
                stop(&mut out, round_no, why, &mut progress);
                break;
            }
        };
        let first = &out[0];
        let round = DiagnoseOptions {
            first_round: Some(FirstRound {
                scores: first
                    .effects
                    .iter()
                    .map(|e| (e.path.clone(), e.score))
                    .collect(),
                loss_held_out: first.calibrated.loss_held_out,
                seconds_over_calibration: first.timings.over_calibration(),
            }),
            free_params: free,
            fit,
            budget_s,
            journal: opts.journal.scoped(&format!("round {round_no}")),
            render: RenderOptions {
                rays_per_element: Some(last.noise_check.rays),
                ..opts.render.clone()
            },
            ..opts.clone()
        };
        progress(&format!(
            "round {}: {} switched on, diagnosing again",
            out.len() + 1,
            last.verdict.effect
        ));
        match diagnose(next_scene, measured, &round, &mut progress) {
            Ok(d) => out.push(d),
            Err(OptimError::Budget {
                message,
                estimate_s,
            }) => {
                let needed = budget_that_would_do(elapsed + estimate_s, "run");
                stop(
                    &mut out,
                    round_no,
                    format!("{message}; {needed}"),
                    &mut progress,
                );
                break;
            }
            Err(e) => {
                stop(&mut out, round_no, format!("it failed: {e}"), &mut progress);
                break;
            }
        }
    }
    Ok(out)
}

/// The advice on a round the budget stopped: a budget of `needed_s` seconds,
/// rounded up to ten, would let it `what` ("start" or "run").
fn budget_that_would_do(needed_s: f64, what: &str) -> String {
    let budget = (needed_s / 10.0).ceil() * 10.0;
    format!("`--budget {budget:.0}` would let it {what}")
}

/// Records on the last of `rounds` why round `round_no` did not run or finish.
fn stop(rounds: &mut [Diagnosis], round_no: usize, why: String, progress: &mut dyn FnMut(&str)) {
    let why = format!("round {round_no} stopped: {why}");
    progress(&why);
    if let Some(last) = rounds.last_mut() {
        last.next_round_stopped = Some(why);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// In a later round the named effect's parameter is calibrated, and no
    /// longer a candidate, even where that calibration has taken it to its
    /// null, where the catalogue would switch it on again: the sphere's
    /// speckle at strength 0 is a catalogue candidate until its strength is
    /// among the calibrated parameters.
    #[test]
    fn a_calibrated_parameter_is_no_candidate() {
        let text = include_str!("../../../../bench/tier_a/a2_sphere.toml").replace(
            "roughness = 0.3\n",
            "roughness = 0.3\nscatterer_density_per_mm3 = 5.0\nscatterer_strength = 0.0\n",
        );
        let scene = Scene::from_toml_str(&text, "a2_sphere.toml", ".").unwrap();
        let strength = scene.key("materials.target.scatterer_strength").unwrap();
        let base = default_free_params(&scene);
        assert!(!base.contains(&strength));
        assert!(candidates(&scene, &base).iter().any(|c| c.key == strength));
        let mut later = base.clone();
        later.push(strength.clone());
        let left = candidates(&scene, &later);
        assert!(left.iter().all(|c| !later.contains(&c.key)), "{left:?}");
        assert!(!left.is_empty());
    }

    /// An effect that removes the same loss in both rounds has additivity 1:
    /// excess 0.25 of a second-round loss 0.8 is 0.2 of the first round's 1.0,
    /// which is what it scored there.
    #[test]
    fn additivity_is_the_first_round_score_over_the_loss_the_effect_removes() {
        let first = FirstRound {
            scores: BTreeMap::from([("a".to_string(), 0.2), ("b".to_string(), 0.002)]),
            loss_held_out: 1.0,
            seconds_over_calibration: 6.0,
        };
        let a = additivity("a", Some(0.25), &first, 0.8).unwrap();
        assert!((a - 1.0).abs() < 1e-12, "{a}");
        let b = additivity("b", Some(0.25), &first, 0.8).unwrap();
        assert!((b - 0.01).abs() < 1e-12, "{b}");
        // Absent for a candidate the first round did not have, or one that gains nothing.
        assert!(additivity("c", Some(0.25), &first, 0.8).is_none());
        assert!(additivity("a", Some(-0.1), &first, 0.8).is_none());
        assert!(additivity("a", None, &first, 0.8).is_none());
    }
}
