//! Step 4 of a diagnosis: the null refit (the control) and the leading
//! candidates' refits, each measured on the held-out renders: its shrink of
//! the held-out loss, its excess over the null refit, the share of the gap it
//! explains and its effect parameter's limit of detection.

use super::calibration::Stage;
use super::catalogue::Candidate;
use super::held_out::{held_out, mean, mean_and_se, relative_differences};
use super::options::DiagnoseOptions;
use super::results::{EffectResult, NullRefit};
use super::spatial::{block_px, excess_spatial_std, held_out_losses, HeldOutLosses};
use crate::fit::{fit_journaled, FitOptions};
use crate::objective::Objective;
use crate::params::ParamSpec;
use crate::spread::parameter_spread;
use crate::OptimError;
use std::time::Instant;
use usray_transport::Scene;

/// How many Monte Carlo spreads of an effect parameter make its limit of
/// detection ([`EffectResult::detection_limit`]): 3, the analytical chemists'
/// convention — the limit of detection is the blank's mean plus three of its
/// standard deviations (IUPAC; Long & Winefordner, *Anal. Chem.* 55, 712A,
/// 1983), which a Gaussian estimate exceeds by chance with probability 0.13%.
pub(crate) const DETECTION_LIMIT_SPREADS: f64 = 3.0;

/// A candidate's refit and its held-out evaluation (step 4).
struct Refit {
    /// The held-out losses, per seed and by block of the image (`spatial`).
    after_held: HeldOutLosses,
    params: Vec<(String, f64)>,
    params_std: Vec<(String, Option<f64>)>,
    image_s: Vec<f64>,
    scene: Scene,
    spread_s: f64,
}

/// The Adam step of a candidate's parameter in its refit, as a fraction of its
/// range: [`Candidate::learning_rate`] (the effect's strength may lie anywhere
/// in its range and refits are short: 5% of the range per step, less for a
/// narrow basin), but for an effect whose null is the bottom of its range a
/// quarter of the start's distance from it. Adam's first steps are each about
/// one learning rate long whatever the gradient, so from a start near the
/// null (a faint speckle scored best at 0.035 of a 0–2 strength) a longer
/// step *down* reaches the bound, where the clip map's derivative is zero
/// (paper eq. clip_grad) and the effect, switched off, could never come back.
/// When the screen says the loss falls towards the null (`toward_null`: its
/// best point lies below the onset, or the onset's gradient is positive) that
/// quarter is a ceiling; otherwise the refit climbs away from the bound and
/// the step is kept between a quarter of the learning rate and the learning
/// rate, so that a weak start (a depth gain at 1% of its range) can grow
/// within the refit's iterations.
fn refit_learning_rate(c: &Candidate, start: f64, toward_null: bool) -> f64 {
    match c.null {
        Some(null) if !c.two_sided && null <= c.range.0 => {
            let Some(quarter) = quarter_from_null(c.range, c.range.0, start) else {
                return c.learning_rate;
            };
            if toward_null {
                quarter.min(c.learning_rate)
            } else {
                quarter.clamp(0.25 * c.learning_rate, c.learning_rate)
            }
        }
        _ => c.learning_rate,
    }
}

/// A quarter of `value`'s distance from `null`, a bound of `range`, as a
/// fraction of the range's width: the longest step an effect near its null
/// takes, so that no single Adam step lands on the null (where the clip map's
/// derivative is zero). `None` for an empty range.
pub(crate) fn quarter_from_null(range: (f64, f64), null: f64, value: f64) -> Option<f64> {
    let width = range.1 - range.0;
    (width > 0.0).then(|| 0.25 * (value - null).abs() / width)
}

/// Refits candidate `c` with the base `specs` from `start` (step 4);
/// `toward_null` as [`refit_learning_rate`]'s.
#[allow(clippy::too_many_arguments)]
fn refit_candidate(
    c: &Candidate,
    start: f64,
    toward_null: bool,
    stage: &Stage,
    specs: &[ParamSpec],
    measured: &[f64],
    held_data: &[f64],
    opts: &DiagnoseOptions,
) -> Result<Refit, OptimError> {
    // Start strictly inside the range: at a bound the clip map's derivative is
    // zero (paper eq. clip_grad), so a strength starting at its null (the
    // bottom of its range) would never move.
    let margin = 0.01 * (c.range.1 - c.range.0);
    let start = start.clamp(c.range.0 + margin, c.range.1 - margin);
    let on = c.switched_on(&stage.scene, start)?;
    let mut refit_specs = vec![ParamSpec {
        key: c.key.clone(),
        min: c.range.0,
        max: c.range.1,
    }];
    refit_specs.extend(specs.iter().cloned());
    let mut obj = stage
        .setup
        .objective(on, measured, refit_specs, &stage.render_s)?;
    let x0 = obj.initial_physical();
    // The screen's best point may lie just past the loss's minimum along the
    // effect (a speckle strength of 0.02 whose loss is lowest at 0.01): there
    // the loss also falls towards the null, whatever the screen's onset said,
    // and a floored first step would land on the null and stay (the effect
    // parameter is the refit's first). One gradient at the start tells; it is
    // taken only where the step would otherwise keep its floor.
    let toward_null = toward_null
        || (refit_learning_rate(c, start, false) > refit_learning_rate(c, start, true)
            && obj.value_and_gradient(&x0)?.gradient[0] > 0.0);
    let r = fit_journaled(
        &mut obj,
        &x0,
        &FitOptions {
            iters: opts.refit_iters,
            // The candidate's own rate first (a fit takes the first match),
            // then any the options set (a later round's named effect).
            lr_overrides: std::iter::once((
                c.key.clone(),
                refit_learning_rate(c, start, toward_null),
            ))
            .chain(opts.fit.lr_overrides.iter().cloned())
            .collect(),
            ..opts.fit.clone()
        },
        &opts.journal,
        &format!("refit {} ({})", c.effect, c.key),
        |_| {},
    )?;
    // The refit's best point on its seed, not its last: on a loss whose
    // 20-ray gradient is rugged below a wavelength, one misleading first step
    // can carry a refit out of the basin it was scored in (`FitResult::best`).
    let best = r.best().0.to_vec();
    let fitted = obj.scene_at(&best)?;
    let after = held_out(&fitted, held_data, &stage.renders_held, &stage.setup)?;
    let t_spread = Instant::now();
    let image_s = image_on_fit_seed(&fitted, measured, stage)?;
    let std = parameter_spread(
        &obj,
        &best,
        &image_s,
        &after[0].image.data,
        opts.spread_pairs,
    )?;
    Ok(Refit {
        after_held: held_out_losses(&stage.setup, held_data, &after, block_px(&stage.scene)),
        params: obj
            .specs
            .iter()
            .zip(&best)
            .map(|(s, v)| (s.key.to_string(), *v))
            .chain(c.fixed.iter().map(|(k, v)| (k.to_string(), *v)))
            .collect(),
        params_std: obj
            .specs
            .iter()
            .zip(std)
            .map(|(s, v)| (s.key.to_string(), v))
            .collect(),
        image_s,
        scene: fitted,
        spread_s: t_spread.elapsed().as_secs_f64(),
    })
}

/// The null refit and the losses an effect's refit must beat.
pub(crate) struct Control {
    /// What the null refit found ([`super::Diagnosis::null_refit`]).
    pub null_refit: NullRefit,
    /// The baseline of every excess, its held-out losses per seed and by
    /// block of the image (`spatial`): the null refit's, or the calibrated model's where
    /// the null refit ended worse (every refit restarts Adam's moments and
    /// may).
    pub baseline: HeldOutLosses,
    /// The scene of that baseline, for a second look on fresh seeds
    /// ([`super::Confirmation`]).
    pub baseline_scene: Scene,
}

/// The control: the base parameters alone, refitted from the calibrated point
/// for as many iterations as each candidate, on the calibration's seed, from a
/// fresh Adam, and its held-out losses.
pub(crate) fn null_refit(
    stage: &Stage,
    specs: &[ParamSpec],
    measured: &[f64],
    held_data: &[f64],
    opts: &DiagnoseOptions,
) -> Result<Control, OptimError> {
    let mut null_obj = stage.setup.objective(
        stage.scene.clone(),
        measured,
        specs.to_vec(),
        &stage.render_s,
    )?;
    let null_fit = fit_journaled(
        &mut null_obj,
        &stage.params,
        &FitOptions {
            iters: opts.refit_iters,
            ..opts.fit.clone()
        },
        &opts.journal,
        "null refit",
        |_| {},
    )?;
    // Its best point, as every candidate's refit (`refit_candidate`).
    let null_best = null_fit.best().0.to_vec();
    let null_scene = null_obj.scene_at(&null_best)?;
    let null_after = held_out(&null_scene, held_data, &stage.renders_held, &stage.setup)?;
    let null_losses: Vec<f64> = null_after.iter().map(|e| e.loss).collect();
    let (shrink, shrink_std) = mean_and_se(&relative_differences(
        &stage.held_losses,
        &null_losses,
        stage.held_loss,
    ));
    let (baseline_evals, baseline_scene) = if shrink > 0.0 {
        (&null_after, null_scene)
    } else {
        (&stage.held, stage.scene.clone())
    };
    let baseline = held_out_losses(
        &stage.setup,
        held_data,
        baseline_evals,
        block_px(&stage.scene),
    );
    Ok(Control {
        null_refit: NullRefit {
            loss_after: mean(&null_losses),
            shrink,
            shrink_std,
            held_out_losses: null_losses,
            params: specs
                .iter()
                .zip(&null_best)
                .map(|(s, v)| (s.key.to_string(), *v))
                .collect(),
        },
        baseline,
        baseline_scene,
    })
}

/// A refitted candidate: its index among the candidates, its image on the
/// fit's seed and its fitted scene.
pub(crate) struct Refitted {
    /// Index of the candidate (and of its [`EffectResult`]).
    pub candidate: usize,
    /// The refitted model's image on the calibration's seed `s`.
    pub image_s: Vec<f64>,
    /// The scene with the effect switched on at its fitted value.
    pub scene: Scene,
}

/// Refits the first [`DiagnoseOptions::confirm_top`] candidates of `order`
/// whose scoring completed, each from its start in `starts`, and fills their
/// [`EffectResult`]s in `effects` with the held-out statistics (against the
/// calibrated losses and the control's `baseline`). A failing refit is
/// recorded in [`EffectResult::failed`] and skipped. Returns the refits in
/// order and the seconds spent on their parameter spreads.
pub(crate) fn refit_leading(
    candidates: &[Candidate],
    starts: &[f64],
    order: &[usize],
    effects: &mut [EffectResult],
    stage: &Stage,
    specs: &[ParamSpec],
    baseline: &HeldOutLosses,
    measured: &[f64],
    held_data: &[f64],
    opts: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> (Vec<Refitted>, f64) {
    let mut refits = Vec::new();
    let mut spread_s = 0.0;
    let completed = |k: &usize| effects[*k].failed.is_none();
    let mut leading: Vec<usize> = order
        .iter()
        .copied()
        .filter(completed)
        .take(opts.confirm_top)
        .collect();
    let always: Vec<usize> = order
        .iter()
        .copied()
        .filter(|k| completed(k) && candidates[*k].refit_always && !leading.contains(k))
        .collect();
    leading.extend(always);
    for k in leading {
        let c = &candidates[k];
        progress(&format!("refitting with {} ({})", c.effect, c.key));
        let (onset, gradient) = (effects[k].onset, effects[k].gradient);
        let toward_null = starts[k] < onset || (starts[k] == onset && gradient > 0.0);
        let r = match refit_candidate(
            c,
            starts[k],
            toward_null,
            stage,
            specs,
            measured,
            held_data,
            opts,
        ) {
            Ok(r) => r,
            Err(e) => {
                effects[k].failed = Some(format!("refit: {e}"));
                continue;
            }
        };
        spread_s += r.spread_s;
        let e = &mut effects[k];
        record_held_out(e, &r.after_held, stage, baseline);
        e.params = r.params.into_iter().collect();
        e.params_std = r.params_std.into_iter().collect();
        e.detection_limit = c
            .null
            .and(e.params_std.get(&e.path).copied().flatten())
            .map(|spread| DETECTION_LIMIT_SPREADS * spread);
        if e.within_detection_limit() {
            match absence_cost(c, &r.scene, &r.after_held, stage, held_data) {
                Ok((cost, cost_std)) => {
                    e.absence_cost = Some(cost);
                    e.absence_cost_std = cost_std;
                }
                Err(err) => progress(&format!("{}: absence test failed: {err}", c.key)),
            }
        }
        refits.push(Refitted {
            candidate: k,
            image_s: r.image_s,
            scene: r.scene,
        });
    }
    (refits, spread_s)
}

/// `scene`'s image on the fit's seed (one render, also with a paired loss):
/// the image a verdict's model is shown by.
pub(crate) fn image_on_fit_seed(
    scene: &Scene,
    measured: &[f64],
    stage: &Stage,
) -> Result<Vec<f64>, OptimError> {
    Ok(Objective::new(
        scene.clone(),
        measured.to_vec(),
        vec![],
        stage.render_s.clone(),
    )?
    .value(&[])?
    .image
    .data)
}

/// Fills `e`'s held-out statistics from its model's held-out losses `after`:
/// the shrink against the calibrated model's, the excess over the control's
/// `baseline` (over the seeds and over the image's blocks), and the share of
/// the gap above the noise level it explains.
pub(crate) fn record_held_out(
    e: &mut EffectResult,
    after: &HeldOutLosses,
    stage: &Stage,
    baseline: &HeldOutLosses,
) {
    let (held_loss, noise_loss) = (stage.held_loss, stage.noise_loss);
    let after_loss = mean(&after.per_seed);
    let (shrink, shrink_std) = mean_and_se(&relative_differences(
        &stage.held_losses,
        &after.per_seed,
        held_loss,
    ));
    let (excess, excess_std) = mean_and_se(&relative_differences(
        &baseline.per_seed,
        &after.per_seed,
        held_loss,
    ));
    e.loss_after = Some(after_loss);
    e.shrink = Some(shrink);
    e.shrink_std = shrink_std;
    e.excess = Some(excess);
    e.excess_std = excess_std;
    e.excess_spatial_std = excess_spatial_std(&baseline.blocks, &after.blocks, held_loss);
    e.gap_explained =
        (held_loss > noise_loss).then(|| (held_loss - after_loss) / (held_loss - noise_loss));
    e.held_out_losses = after.per_seed.clone();
}

/// [`EffectResult::absence_cost`] and its standard error: the refitted
/// `scene` with `c`'s effect parameter alone set back to its null, on the
/// held-out seeds, against the refit's own held-out losses `after`.
fn absence_cost(
    c: &Candidate,
    scene: &Scene,
    after: &HeldOutLosses,
    stage: &Stage,
    held_data: &[f64],
) -> Result<(f64, Option<f64>), OptimError> {
    let null = c
        .null
        .ok_or_else(|| OptimError::Diagnosis(format!("{} has no null", c.key)))?;
    let off = c.switched_on(scene, null)?;
    let evals = held_out(&off, held_data, &stage.renders_held, &stage.setup)?;
    let without = held_out_losses(&stage.setup, held_data, &evals, block_px(&stage.scene));
    let (cost, seeds_std) = mean_and_se(&relative_differences(
        &without.per_seed,
        &after.per_seed,
        stage.held_loss,
    ));
    let spatial_std = excess_spatial_std(&without.blocks, &after.blocks, stage.held_loss);
    let std = match (seeds_std, spatial_std) {
        (Some(a), Some(b)) => Some(a.max(b)),
        (a, b) => a.or(b),
    };
    Ok((cost, std))
}

#[cfg(test)]
mod tests {
    use super::*;
    use usray_transport::{Field, ParamKey};

    /// A speckle strength on `[0, 2]` whose null is the bottom of its range.
    fn speckle() -> Candidate {
        Candidate {
            effect: "volume_scattering".into(),
            key: ParamKey::material("m", Field::ScattererStrength),
            onsets: vec![0.0],
            range: (0.0, 2.0),
            two_sided: false,
            null: Some(0.0),
            fixed: vec![],
            learning_rate: 0.05,
            tolerance: None,
            refit_always: false,
            also_scored_from_null: false,
        }
    }

    #[test]
    fn a_refit_falling_towards_its_null_cannot_step_onto_it() {
        // Adam's first step is about one learning rate (× the range) long:
        // towards the null it stays a quarter of the start's distance.
        let c = speckle();
        let start = 0.019;
        let step = refit_learning_rate(&c, start, true) * (c.range.1 - c.range.0);
        assert!((step - 0.25 * start).abs() < 1e-12, "{step}");
        // Climbing away from it, the step keeps its floor (a quarter of the
        // learning rate), so a weak start can grow within the refit.
        let up = refit_learning_rate(&c, start, false);
        assert_eq!(up, 0.25 * c.learning_rate);
        // Far from the null both are the candidate's own rate.
        assert_eq!(refit_learning_rate(&c, 1.5, true), c.learning_rate);
        assert_eq!(refit_learning_rate(&c, 1.5, false), c.learning_rate);
    }
}
