//! Step 4's look at more rays: every refit that would be named, and the
//! control, rendered again on the held-out seeds at four times the rays, and
//! each excess extrapolated to a simulation without Monte Carlo noise
//! ([`MoreRays`]; verdict test [`super::VerdictRule::holds_without_noise`]).

use super::calibration::Stage;
use super::held_out::{held_out, mean, mean_and_se, relative_differences};
use super::noise_budget::{noise_exponent, DEFAULT_NOISE_EXPONENT};
use super::options::DiagnoseOptions;
use super::refits::Refitted;
use super::results::{EffectResult, MoreRays};
use super::verdict::qualifies;
use crate::objective::Evaluation;
use std::time::Instant;
use usray_transport::{RenderOptions, Scene};

/// How many times the first look's rays the second renders: enough for the
/// Monte Carlo term to fall 2× (ℓ1) to 4× (ℓ2), at about four held-out
/// evaluations' cost per model.
pub(crate) const RAYS_FACTOR: usize = 4;

/// Renders every refit of `refits` that passes every other test of the
/// verdict ([`qualifies`]), and the control (`baseline_scene`, the null
/// refit's), on the stage's held-out seeds at [`RAYS_FACTOR`] times its
/// rays, and records in each refit's [`EffectResult::more_rays`] its excess
/// there and the noise-free excess both looks give. The first look is
/// [`EffectResult::seeds_look`]. The control is rendered once and shared. Returns the
/// seconds spent. A render that fails is reported through `progress` and
/// leaves its refit (or, for the control, every refit) unmeasured.
#[allow(clippy::too_many_arguments)]
pub(crate) fn more_rays_looks(
    refits: &[Refitted],
    effects: &mut [EffectResult],
    stage: &Stage,
    baseline_scene: &Scene,
    held_data: &[f64],
    opts: &DiagnoseOptions,
    noise_passed: bool,
    progress: &mut dyn FnMut(&str),
) -> f64 {
    let due: Vec<&Refitted> = refits
        .iter()
        .filter(|r| qualifies(&effects[r.candidate], noise_passed, &opts.rule))
        .collect();
    let Some(rays) = stage.render_s.rays_per_element else {
        return 0.0;
    };
    if due.is_empty() || rays == 0 {
        return 0.0;
    }
    let t = Instant::now();
    let more = rays * RAYS_FACTOR;
    let renders: Vec<RenderOptions> = stage
        .renders_held
        .iter()
        .map(|r| RenderOptions {
            rays_per_element: Some(more),
            ..r.clone()
        })
        .collect();
    progress(&format!(
        "rendering the control and {} refit(s) that would be named again at {more} rays",
        due.len()
    ));
    let control = match held_out(baseline_scene, held_data, &renders, &stage.setup) {
        Ok(c) => c,
        Err(e) => {
            progress(&format!(
                "the look at more rays was not taken: the control's render failed: {e}"
            ));
            return t.elapsed().as_secs_f64();
        }
    };
    let p = if stage.setup.paired {
        DEFAULT_NOISE_EXPONENT
    } else {
        noise_exponent(rays, stage.noise_loss, more, pairs_noise(stage, &control))
            .unwrap_or(DEFAULT_NOISE_EXPONENT)
    };
    let control: Vec<f64> = control.iter().map(|e| e.loss).collect();
    for Refitted {
        candidate: k,
        scene,
        ..
    } in due
    {
        let k = *k;
        let after = match held_out(scene, held_data, &renders, &stage.setup) {
            Ok(a) => a.iter().map(|e| e.loss).collect::<Vec<_>>(),
            Err(err) => {
                progress(&format!(
                    "{} ({}) was not rendered at more rays: {err}",
                    effects[k].effect, effects[k].path
                ));
                continue;
            }
        };
        let (excess, excess_std) =
            mean_and_se(&relative_differences(&control, &after, stage.held_loss));
        let Some(first) = effects[k].seeds_look() else {
            continue;
        };
        let (g, g_std) = MoreRays::extrapolate(first, rays, (excess, excess_std), more, p);
        effects[k].more_rays = Some(MoreRays {
            rays: more,
            excess,
            excess_std,
            noise_exponent: p,
            noise_free_excess: g,
            noise_free_std: g_std,
        });
    }
    t.elapsed().as_secs_f64()
}

/// The noise level of `evals`, renders of one model on independent seeds:
/// the mean loss between disjoint pairs of their images, as
/// [`super::Diagnosis::noise_loss`] is between two renders. 0 (no
/// measurement) for fewer than two.
fn pairs_noise(stage: &Stage, evals: &[Evaluation]) -> f64 {
    let losses: Vec<f64> = evals
        .chunks_exact(2)
        .map(|pair| stage.objective.loss_between(&pair[0].image, &pair[1].image))
        .collect();
    mean(&losses)
}
