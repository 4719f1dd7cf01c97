//! The fit loop (paper §"Optimization procedure", Algorithm "One optimization
//! iteration"): Adam with parameter groups on the paper's clip-and-scale state
//! (eqs. clip01, scale_phys, clip_grad), gradient clipping, common random numbers.

use crate::adam::{Adam, AdamGroup, AdamState};
use crate::journal::Journal;
use crate::objective::Objective;
use crate::params::ParamMap;
use crate::OptimError;
use std::time::Instant;
use usray_transport::scene::ParamGroup;
use usray_transport::ParamKey;

/// Index of a group's learning rate in the fit's list of base rates.
fn group_index(group: ParamGroup) -> usize {
    match group {
        ParamGroup::Material => 0,
        ParamGroup::Geometry => 1,
        ParamGroup::Acquisition => 2,
    }
}

/// Settings of a fit.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Adam iterations (gradient evaluations and updates).
    pub iters: usize,
    /// Learning rate of the material group, in fractions of each parameter's range
    /// per step (default 0.03).
    pub lr_material: f64,
    /// Learning rate of the geometry group (default 0.02).
    pub lr_geometry: f64,
    /// Learning rate of the acquisition group (default 0.01: the image is most
    /// sensitive to pitch, frequency and speeds).
    pub lr_acquisition: f64,
    /// Learning rates decay exponentially to this fraction of their initial value
    /// by the last iteration, `η_k = η·f^{k/(N−1)}` (default 0.1), so the iterate
    /// settles instead of dithering at `±η`.
    pub lr_final_fraction: f64,
    /// Clip the state gradient to this multiple of the first iteration's gradient
    /// norm (default 5; `None`: no clipping). Protects Adam's moments from a spike
    /// when a visibility change jumps the loss.
    pub clip_factor: Option<f64>,
    /// Draw fresh random numbers every iteration (seed + k) instead of common random
    /// numbers; the gradient is then stochastic (paper: "unless explicitly stated").
    pub resample_seed: bool,
    /// Learning rates of single parameters, overriding their group's
    /// (each such parameter gets a group of its own; default none). The
    /// diagnosis gives an effect's strength, which may lie anywhere in its range,
    /// a faster rate than the calibrated parameters it refits with.
    pub lr_overrides: Vec<(ParamKey, f64)>,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            iters: 150,
            lr_material: 0.03,
            lr_geometry: 0.02,
            lr_acquisition: 0.01,
            lr_final_fraction: 0.1,
            clip_factor: Some(5.0),
            resample_seed: false,
            lr_overrides: Vec::new(),
        }
    }
}

impl FitOptions {
    /// The learning rate `key` starts a fit with: its own
    /// ([`FitOptions::lr_overrides`], the first that names it) or its group's.
    ///
    /// ```
    /// use usray_optim::FitOptions;
    /// use usray_transport::{Field, ParamKey};
    /// let strength = ParamKey::material("m", Field::ScattererStrength);
    /// let mut opts = FitOptions::default();
    /// assert_eq!(opts.learning_rate_of(&strength), opts.lr_material);
    /// opts.lr_overrides = vec![(strength.clone(), 0.001), (strength.clone(), 0.5)];
    /// assert_eq!(opts.learning_rate_of(&strength), 0.001);
    /// ```
    pub fn learning_rate_of(&self, key: &ParamKey) -> f64 {
        match self.lr_overrides.iter().find(|(p, _)| p == key) {
            Some((_, lr)) => *lr,
            None => {
                [self.lr_material, self.lr_geometry, self.lr_acquisition][group_index(key.group())]
            }
        }
    }
}

/// One iteration of a fit.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FitStep {
    /// Iteration, from 0.
    pub iter: usize,
    /// Loss at the parameters below.
    pub loss: f64,
    /// Physical parameter values at this iteration, in the objective's order.
    pub params: Vec<f64>,
    /// `‖∂L/∂θ̃‖` of the normalised state, before clipping.
    pub grad_norm: f64,
    /// Seconds since the fit started.
    pub seconds: f64,
}

/// The outcome of a fit.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FitResult {
    /// Loss and parameters at every iteration (before its update).
    pub history: Vec<FitStep>,
    /// Parameters after the last update.
    pub final_params: Vec<f64>,
    /// Loss at [`FitResult::final_params`] (same seed as the last iteration).
    pub final_loss: f64,
    /// Wall time, seconds.
    pub seconds: f64,
}

impl FitResult {
    /// The parameters of the lowest loss the fit met — its iterates and its
    /// final point — and that loss. With common random numbers (no
    /// [`FitOptions::resample_seed`]) every loss is the same function of the
    /// parameters, so the lowest is the best point seen; Adam on a rugged loss
    /// can step out of a basin on one misleading gradient and end above its
    /// start. Ties go to the later point.
    ///
    /// ```
    /// use usray_optim::{FitResult, FitStep};
    /// let step = |iter: usize, loss: f64, p: f64| FitStep {
    ///     iter, loss, params: vec![p], grad_norm: 1.0, seconds: 0.0,
    /// };
    /// let r = FitResult {
    ///     history: vec![step(0, 0.09, 0.944), step(1, 0.11, 1.04)],
    ///     final_params: vec![1.15],
    ///     final_loss: 0.108,
    ///     seconds: 1.0,
    /// };
    /// assert_eq!(r.best(), (&[0.944][..], 0.09));
    /// let r = FitResult { final_loss: 0.07, ..r };
    /// assert_eq!(r.best(), (&[1.15][..], 0.07));
    /// ```
    #[must_use]
    pub fn best(&self) -> (&[f64], f64) {
        self.history
            .iter()
            .map(|s| (s.params.as_slice(), s.loss))
            .chain(std::iter::once((
                self.final_params.as_slice(),
                self.final_loss,
            )))
            .fold((self.final_params.as_slice(), f64::INFINITY), |best, p| {
                if p.1 <= best.1 {
                    p
                } else {
                    best
                }
            })
    }
}

/// Minimises `objective` from the physical values `start` with Adam
/// (paper eq. adam) on the clip-and-scale state; `progress` sees every iteration.
///
/// # Errors
/// Any error of an evaluation (a parameter value the scene rejects, …).
pub fn fit(
    objective: &mut Objective,
    start: &[f64],
    opts: &FitOptions,
    progress: impl FnMut(&FitStep),
) -> Result<FitResult, OptimError> {
    fit_journaled(objective, start, opts, &Journal::default(), "fit", progress)
}

/// A fit's iterations so far, as a checkpoint keeps them.
#[derive(serde::Serialize, serde::Deserialize)]
struct FitProgress {
    state: Vec<f64>,
    adam: AdamState,
    history: Vec<FitStep>,
}

/// [`fit`], checkpointed in `journal` under `key`: the state, Adam's moments
/// and the history after every iteration (`KEY.progress`), the result when it
/// ends (`KEY`). Started again on the same journal, a finished fit returns its
/// kept result and an interrupted one continues from its last iteration, with
/// the same bits as an uninterrupted fit (only `seconds` differ). `progress`
/// sees the kept iterations again, then the new ones.
///
/// # Errors
/// As [`fit`]; a checkpoint that cannot be written or read back.
pub fn fit_journaled(
    objective: &mut Objective,
    start: &[f64],
    opts: &FitOptions,
    journal: &Journal,
    key: &str,
    mut progress: impl FnMut(&FitStep),
) -> Result<FitResult, OptimError> {
    let base_seed = objective
        .opts
        .seed
        .unwrap_or(objective.scene.acquisition.seed);
    // With fresh random numbers per iteration, iteration k renders with seed
    // `base + k`, and the objective is left on the last one (the final loss's).
    let seed_of = |k: usize| base_seed.wrapping_add(k as u64);
    if let Some(done) = journal.get::<FitResult>(key)? {
        if opts.resample_seed {
            if let Some(last) = opts.iters.checked_sub(1) {
                objective.opts.seed = Some(seed_of(last));
            }
        }
        done.history.iter().for_each(&mut progress);
        return Ok(done);
    }
    let progress_key = format!("{key}.progress");
    let t0 = Instant::now();
    let map = ParamMap::new(objective.specs.clone());
    let mut state = map.state_from_physical(start);
    let mut base_lr = vec![opts.lr_material, opts.lr_geometry, opts.lr_acquisition];
    let group_of = objective
        .specs
        .iter()
        .map(
            |s| match opts.lr_overrides.iter().find(|(p, _)| *p == s.key) {
                Some((_, lr)) => {
                    base_lr.push(*lr);
                    base_lr.len() - 1
                }
                None => group_index(s.key.group()),
            },
        )
        .collect();
    let groups = base_lr
        .iter()
        .map(|&lr| AdamGroup {
            learning_rate: lr,
            ..Default::default()
        })
        .collect();
    let mut adam = Adam::new(groups, group_of);
    let mut history = Vec::with_capacity(opts.iters);
    // Seconds already spent before an interruption.
    let mut earlier_s = 0.0;
    if let Some(kept) = journal.get::<FitProgress>(&progress_key)? {
        if kept.state.len() != state.len() || kept.history.len() > opts.iters {
            return Err(OptimError::Checkpoint(format!(
                "`{progress_key}` does not belong to this fit ({} parameters, {} iterations kept)",
                kept.state.len(),
                kept.history.len()
            )));
        }
        adam.restore(&kept.adam).map_err(OptimError::Checkpoint)?;
        state = kept.state;
        history = kept.history;
        history.iter().for_each(&mut progress);
        earlier_s = history.last().map_or(0.0, |s| s.seconds);
    }
    for k in history.len()..opts.iters {
        if opts.resample_seed {
            objective.opts.seed = Some(seed_of(k));
        }
        let physical = map.physical(&state);
        let eval = objective.value_and_gradient(&physical)?;
        let g = map.state_gradient(&state, &eval.gradient);
        let decay = if opts.iters > 1 {
            opts.lr_final_fraction
                .powf(k as f64 / (opts.iters - 1) as f64)
        } else {
            1.0
        };
        for (grp, lr) in adam.groups.iter_mut().zip(&base_lr) {
            grp.learning_rate = lr * decay;
        }
        let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
        if k == 0 {
            adam.clip_norm = opts.clip_factor.map(|f| f * norm).filter(|c| *c > 0.0);
        }
        adam.step(&mut state, &g);
        let step = FitStep {
            iter: k,
            loss: eval.loss,
            params: physical,
            grad_norm: norm,
            seconds: earlier_s + t0.elapsed().as_secs_f64(),
        };
        history.push(step);
        if journal.is_active() {
            journal.put(
                &progress_key,
                &FitProgress {
                    state: state.clone(),
                    adam: adam.state(),
                    history: history.clone(),
                },
            )?;
        }
        progress(history.last().expect("pushed above"));
    }
    if opts.resample_seed {
        // The final loss on the last iteration's seed, also after a resume
        // that kept every iteration.
        if let Some(last) = opts.iters.checked_sub(1) {
            objective.opts.seed = Some(seed_of(last));
        }
    }
    let final_params = map.physical(&state);
    let final_loss = objective.value(&final_params)?.loss;
    let result = FitResult {
        history,
        final_params,
        final_loss,
        seconds: earlier_s + t0.elapsed().as_secs_f64(),
    };
    journal.put(key, &result)?;
    journal.forget(&progress_key)?;
    Ok(result)
}
