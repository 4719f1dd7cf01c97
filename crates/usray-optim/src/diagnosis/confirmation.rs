//! Step 4's second look: a borderline refit ([`super::VerdictRule::borderline`])
//! and the control rendered again on fresh held-out seeds, within the budget
//! ([`Confirmation`]).

use super::calibration::Stage;
use super::held_out::{held_out, held_out_seed, mean_and_se, relative_differences};
use super::options::DiagnoseOptions;
use super::refits::Refitted;
use super::results::{Confirmation, EffectResult};
use super::verdict::needs_second_look;
use crate::OptimError;
use std::time::Instant;
use usray_transport::{RenderOptions, Scene};

/// The render options of a second look's `count` fresh seeds: held-out seeds
/// `first … first + count` ([`held_out_seed`]) of `render_s`'s seed, where
/// step 4 rendered `0 … first` (`first` = [`DiagnoseOptions::held_out_seeds`]).
fn fresh_renders(render_s: &RenderOptions, first: usize, count: usize) -> Vec<RenderOptions> {
    let seed = render_s.seed.unwrap_or_default();
    (first..first + count)
        .map(|j| RenderOptions {
            seed: Some(held_out_seed(seed, j)),
            ..render_s.clone()
        })
        .collect()
}

/// Measures every borderline refit of `refits` that passes the verdict's
/// other tests ([`needs_second_look`]) again on fresh seeds, the largest
/// shrink first, against `baseline_scene` (the control's), and records each
/// in its [`EffectResult::confirmation`]: measured, or over budget where the
/// budget left (counted from `started`; journaled, so a resumed run decides
/// the same) cannot pay for its renders, estimated from the stage's
/// held-out evaluation ([`Stage::held_eval_s`]). The control's fresh losses
/// are rendered once and shared.
#[allow(clippy::too_many_arguments)]
pub(crate) fn second_looks(
    refits: &[Refitted],
    effects: &mut [EffectResult],
    stage: &Stage,
    baseline_scene: &Scene,
    held_data: &[f64],
    opts: &DiagnoseOptions,
    noise_passed: bool,
    started: Instant,
    progress: &mut dyn FnMut(&str),
) -> Result<(), OptimError> {
    if opts.confirmation_seeds == 0 {
        return Ok(());
    }
    let mut due: Vec<&Refitted> = refits
        .iter()
        .filter(|r| needs_second_look(&effects[r.candidate], noise_passed, &opts.rule))
        .collect();
    let shrink = |r: &Refitted| effects[r.candidate].shrink.unwrap_or(f64::NEG_INFINITY);
    due.sort_by(|a, b| shrink(b).total_cmp(&shrink(a)));
    let renders = fresh_renders(
        &stage.render_s,
        opts.held_out_seeds,
        opts.confirmation_seeds,
    );
    let mut baseline: Option<Vec<f64>> = None;
    for Refitted {
        candidate: k,
        scene,
        ..
    } in due
    {
        let (k, path) = (*k, effects[*k].path.clone());
        let models = if baseline.is_some() { 1 } else { 2 };
        let estimate_s = (models * renders.len()) as f64 * stage.held_eval_s;
        let left_s = opts
            .journal
            .remember(&format!("second look {path} budget left"), || {
                Ok(opts.budget_s.map(|b| b - started.elapsed().as_secs_f64()))
            })?;
        if let Some(left_s) = left_s.filter(|left| estimate_s > *left) {
            effects[k].confirmation = Some(Confirmation::OverBudget {
                seeds: renders.len(),
                estimate_s,
                left_s,
            });
            continue;
        }
        let e = &effects[k];
        progress(&format!(
            "{} ({path}) is borderline ({:.1} standard errors over {} seeds): measuring it again on {} fresh seeds",
            e.effect,
            e.excess.unwrap_or(0.0) / e.excess_std.unwrap_or(f64::NAN),
            e.held_out_losses.len(),
            renders.len()
        ));
        let t = Instant::now();
        let losses = |s: &Scene| -> Result<Vec<f64>, OptimError> {
            Ok(held_out(s, held_data, &renders, &stage.setup)?
                .iter()
                .map(|e| e.loss)
                .collect())
        };
        let base = match &mut baseline {
            Some(base) => base,
            none => none.insert(losses(baseline_scene)?),
        };
        let after = losses(scene)?;
        let (excess, excess_std) =
            mean_and_se(&relative_differences(base, &after, stage.held_loss));
        effects[k].confirmation = Some(Confirmation::Measured {
            seeds: renders.len(),
            excess,
            excess_std,
            seconds: t.elapsed().as_secs_f64(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fresh_seeds_are_none_of_step_4s() {
        // Step 4 renders held-out seeds 0…K−1 of seed s (as the calibration
        // builds them) and s itself; the second look's are none of those.
        let opts = DiagnoseOptions::default();
        let s = 1234;
        let render_s = RenderOptions {
            seed: Some(s),
            rays_per_element: Some(7),
            ..Default::default()
        };
        let step4: Vec<u64> = (0..opts.held_out_seeds)
            .map(|j| held_out_seed(s, j))
            .collect();
        let renders = fresh_renders(&render_s, opts.held_out_seeds, opts.confirmation_seeds);
        assert!(renders.iter().all(|r| r.rays_per_element == Some(7)));
        let fresh: Vec<u64> = renders.iter().filter_map(|r| r.seed).collect();
        assert_eq!(fresh.len(), opts.confirmation_seeds);
        assert!(fresh.iter().all(|f| !step4.contains(f) && *f != s));
        let mut unique = fresh.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), fresh.len());
    }
}
