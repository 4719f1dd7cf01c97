//! Step 3 of a diagnosis: every candidate scored by one value and gradient of
//! the loss at its onset, and a Newton step along it checked by a render
//! (module docs of [`crate::diagnosis`]).

use super::calibration::{LossSetup, Stage};
use super::catalogue::Candidate;
use super::results::EffectResult;
use crate::objective::Objective;
use crate::params::ParamSpec;
use crate::OptimError;
use std::collections::BTreeMap;
use usray_transport::{RenderOptions, Scene};

/// Scoring renders the loss at a candidate's Newton step only when the quadratic
/// model predicts that the step cuts at least this fraction of the calibrated
/// loss; below it the prediction is the score. The score only orders the
/// candidates for their refits; no verdict turns on it.
const MIN_CHECKED_REDUCTION: f64 = 0.03;

/// At most this many halvings of a candidate's Newton step in its scoring
/// ([`score_candidate`]), each one render.
const MAX_STEP_HALVINGS: usize = 3;

/// A candidate's score (module docs, step 3): how much of the calibrated loss it
/// removes along its own parameter alone, the others held at their calibrated
/// values.
#[derive(Clone, Debug, PartialEq)]
pub struct Score {
    /// `(L_cal − min(L(onset), L(step))) / L_cal`, at least 0: the fraction of
    /// the calibrated loss removed at the best of the onset and the checked
    /// Newton step (or the quadratic model's prediction, when it predicts less
    /// than 3% of the calibrated loss: not worth a render).
    pub score: f64,
    /// The onset: the best of [`Candidate::onsets`] by loss, refined.
    pub onset: f64,
    /// `∂L/∂θ` at the onset (loss per unit of the parameter).
    pub gradient: f64,
    /// The loss at the onset.
    pub loss_onset: f64,
    /// Where a confirming refit starts: the best rendered point (the checked
    /// step when it lowered the loss, else the onset) — except for a
    /// candidate refitted whatever its score ([`Candidate::refit_always`])
    /// whose best point is its null, from where its refit has no gradient:
    /// it starts from the best of its other onsets by loss.
    pub start: f64,
}

/// Scores candidate `c` against `measured` at the calibrated scene (loss
/// `calibrated_loss`), rendering with `render` (the calibration's seed): one
/// value + gradient at the onset (the best of [`Candidate::onsets`] by loss, one
/// half-ray render each when there are several, refined by four more), one
/// render for the curvature, and one or two to check the Newton step.
///
/// A candidate [`Candidate::also_scored_from_null`] is scored again from its
/// null alone where the best of its onsets is another value, and keeps the
/// better of the two scores (with that score's onset and start): an onset from
/// outside the image may raise its score but not lower it below the
/// one-gradient screen at the modelled value. Where scoring from the null
/// fails, the onsets' score stands.
///
/// # Errors
/// A path the scene lacks, or a failing render.
pub fn score_candidate(
    c: &Candidate,
    calibrated: &Scene,
    measured: &[f64],
    calibrated_loss: f64,
    render: &RenderOptions,
    setup: &LossSetup,
) -> Result<Score, OptimError> {
    let best = score_from_onsets(c, calibrated, measured, calibrated_loss, render, setup)?;
    match c.null {
        Some(null) if c.also_scored_from_null && best.onset != null => {
            let alone = Candidate {
                onsets: vec![null],
                also_scored_from_null: false,
                ..c.clone()
            };
            // A failed render from the null keeps the onsets' score.
            match score_from_onsets(&alone, calibrated, measured, calibrated_loss, render, setup) {
                Ok(from_null) if from_null.score > best.score => Ok(from_null),
                _ => Ok(best),
            }
        }
        _ => Ok(best),
    }
}

/// [`score_candidate`] from the best of [`Candidate::onsets`] alone.
fn score_from_onsets(
    c: &Candidate,
    calibrated: &Scene,
    measured: &[f64],
    calibrated_loss: f64,
    render: &RenderOptions,
    setup: &LossSetup,
) -> Result<Score, OptimError> {
    let spec = ParamSpec {
        key: c.key.clone(),
        min: c.range.0,
        max: c.range.1,
    };
    let objective_at = |v: f64, render: &RenderOptions| -> Result<Objective, OptimError> {
        setup.objective(
            c.switched_on(calibrated, v)?,
            measured,
            vec![spec.clone()],
            render,
        )
    };
    // The onset: the only one, or the best of a few by loss alone, refined by
    // trying the points half and a quarter of the onsets' spacing either side of
    // the best (four more renders): the basin of a wall or of a sound speed is
    // about one spacing wide and rugged at finer scales (interference of the
    // wall's two echoes, Monte Carlo noise), where its gradient says little.
    // The search only compares onsets with one another, so it renders with half
    // the rays (each onset's loss carries about the same Monte Carlo floor); the
    // chosen onset is then evaluated at the full count like any other.
    let mut onset = c.onsets[0];
    // The best onset other than the null, by loss (the start of a refit-always
    // candidate whose best point is its null).
    let mut departure = (f64::INFINITY, None);
    if c.onsets.len() > 1 {
        let rays = render
            .rays_per_element
            .unwrap_or(calibrated.acquisition.rays_per_element);
        let search = RenderOptions {
            rays_per_element: Some((rays / 2).max(1)),
            ..render.clone()
        };
        let search_obj = objective_at(onset, &search)?;
        let mut best = f64::INFINITY;
        for &v in &c.onsets {
            let l = search_obj.value(&[v])?.loss;
            if l < best {
                (best, onset) = (l, v);
            }
            if c.null != Some(v) && l < departure.0 {
                departure = (l, Some(v));
            }
        }
        let mut half = 0.5
            * c.onsets
                .iter()
                .filter(|&&v| v != onset)
                .map(|v| (v - onset).abs())
                .fold(f64::INFINITY, f64::min);
        for _ in 0..2 {
            let centre = onset;
            for v in [centre - half, centre + half] {
                if v > c.range.0 && v < c.range.1 {
                    let l = search_obj.value(&[v])?.loss;
                    if l < best {
                        (best, onset) = (l, v);
                    }
                }
            }
            half *= 0.5;
        }
    }
    let obj = objective_at(onset, render)?;
    let e = obj.value_and_gradient(&[onset])?;
    let g = e.gradient[0];
    // Gauss–Newton curvature of the ℓ2 term from a forward difference of the
    // image (into the range).
    let h = 0.01
        * (c.range.1 - c.range.0)
        * if onset + 0.01 * (c.range.1 - c.range.0) > c.range.1 {
            -1.0
        } else {
            1.0
        };
    let moved = obj.value(&[onset + h])?;
    let jj: f64 = obj
        .compared(&moved.image)
        .iter()
        .zip(&obj.compared(&e.image))
        .map(|(a, b)| ((a - b) / h).powi(2))
        .sum();
    let gauss_newton = 2.0 * obj.loss.lambda2 * jj / e.image.data.len() as f64;
    // The Gauss–Newton term leaves out the ℓ1 term's curvature (large where
    // the residual is mostly Monte Carlo noise around zero); the secant of
    // the same render, `2 (L(θ+h) − L(θ) − g h) / h²`, includes it. The
    // larger of the two gives the more cautious step.
    let secant = 2.0 * (moved.loss - e.loss - g * h) / (h * h);
    let curvature = gauss_newton.max(secant);
    // The Newton step along the effect, kept in its range, and the loss there
    // (one more render): the quadratic model overshoots where the image is far
    // from linear in the parameter (a speckle field appearing; an attenuation
    // inside the object, whose loss falls almost linearly to its minimum and
    // rises beyond), so its prediction is checked rather than trusted, and the
    // step is halved back towards the onset while that lowers the loss.
    let step = if curvature > 0.0 {
        (onset - g / curvature).clamp(c.range.0, c.range.1)
    } else {
        onset
    };
    // A step the quadratic model itself predicts to cut less than
    // `MIN_CHECKED_REDUCTION` of the calibrated loss is not worth a render:
    // such a candidate is scored by the prediction.
    let predicted = e.loss + g * (step - onset) + 0.5 * curvature * (step - onset).powi(2);
    // The refit starts from the best *rendered* point: the checked step if it
    // lowered the loss, else the onset.
    let mut l_step = e.loss;
    let mut start = onset;
    if step == onset {
        // No step: the onset's loss is the score's.
    } else if (calibrated_loss - predicted) < MIN_CHECKED_REDUCTION * calibrated_loss {
        l_step = predicted;
    } else {
        // Backtracking: the step, then half of it, a quarter, … (at most
        // `MAX_STEP_HALVINGS`), until a halving no longer lowers the loss of a
        // point that already lies below the onset's; the best point is kept.
        // Accepting the first step below the onset's loss would stop at a
        // step that overshoots to the range's bound, whose loss is barely under
        // the onset's while a point halfway back may halve it.
        let mut at = step;
        l_step = obj.value(&[at])?.loss;
        let mut best = (l_step, at);
        for _ in 0..MAX_STEP_HALVINGS {
            let half = 0.5 * (onset + at);
            let l_half = obj.value(&[half])?.loss;
            if l_half >= l_step && l_step < e.loss {
                break;
            }
            (at, l_step) = (half, l_half);
            if l_half < best.0 {
                best = (l_half, half);
            }
        }
        l_step = best.0;
        if l_step < e.loss {
            start = best.1;
        }
    }
    let score = (calibrated_loss - e.loss.min(l_step)).max(0.0) / calibrated_loss;
    Ok(Score {
        score,
        onset,
        gradient: g,
        loss_onset: e.loss,
        start: match departure.1 {
            Some(v) if c.refit_always && c.null == Some(start) => v,
            _ => start,
        },
    })
}

/// Every candidate scored (step 3), in catalogue order, and the order in which
/// they are refitted.
pub(crate) struct Screening {
    /// One result per candidate: its score, onset and gradient (the refit's
    /// fields still empty), or why its scoring failed.
    pub effects: Vec<EffectResult>,
    /// Where each candidate's refit starts ([`Score::start`]).
    pub starts: Vec<f64>,
    /// Candidate indices, completed ones first, then by score, highest first.
    pub order: Vec<usize>,
}

/// Scores every candidate at the calibrated `stage` against `measured`. A
/// candidate whose scoring fails (a render error at an extreme of its range)
/// is kept with score 0 and [`EffectResult::failed`] set.
pub(crate) fn screen(
    candidates: &[Candidate],
    stage: &Stage,
    measured: &[f64],
    progress: &mut dyn FnMut(&str),
) -> Screening {
    let mut effects = Vec::new();
    let mut starts = Vec::new();
    for c in candidates {
        progress(&format!("scoring {} ({})", c.effect, c.key));
        let scored = score_candidate(
            c,
            &stage.scene,
            measured,
            stage.eval.loss,
            &stage.render_s,
            &stage.setup,
        );
        let (sc, failed) = match scored {
            Ok(sc) => (sc, None),
            Err(e) => (
                Score {
                    score: 0.0,
                    onset: c.onsets[0],
                    gradient: 0.0,
                    loss_onset: f64::NAN,
                    start: c.onsets[0],
                },
                Some(format!("scoring: {e}")),
            ),
        };
        starts.push(sc.start);
        effects.push(EffectResult {
            effect: c.effect.clone(),
            path: c.key.to_string(),
            score: sc.score,
            onset: sc.onset,
            range: [c.range.0, c.range.1],
            null: c.null,
            gradient: sc.gradient,
            loss_onset: sc.loss_onset,
            loss_after: None,
            shrink: None,
            shrink_std: None,
            excess: None,
            excess_std: None,
            excess_spatial_std: None,
            gap_explained: None,
            held_out_losses: Vec::new(),
            params: BTreeMap::new(),
            params_std: BTreeMap::new(),
            detection_limit: None,
            tolerance: c.tolerance,
            absence_cost: None,
            absence_cost_std: None,
            additivity: None,
            failed,
            confirmation: None,
            spectral_z: None,
            more_rays: None,
        });
    }
    let mut order: Vec<usize> = (0..effects.len()).collect();
    order.sort_by(|&a, &b| {
        let failed = |k: usize| effects[k].failed.is_some();
        failed(a)
            .cmp(&failed(b))
            .then(effects[b].score.total_cmp(&effects[a].score))
    });
    Screening {
        effects,
        starts,
        order,
    }
}
