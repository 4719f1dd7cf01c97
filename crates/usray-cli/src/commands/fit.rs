//! `usray fit SCENE --reference REF --params … [--iters N]`.

use super::calib::{build_objective, progress_bar, write_fit_outputs};
use crate::cli::{Common, Levels, Sampling};
use crate::output::OutDir;
use anyhow::{Context, Result};
use std::path::Path;
use usray_optim::{fit_journaled, FitOptions, Journal, Objective, ParamSpec};
use usray_transport::ParamKey;

/// Settings of `usray fit` beyond the objective.
pub struct FitArgs {
    /// Iterations.
    pub iters: usize,
    /// Fresh random numbers each iteration.
    pub resample_seed: bool,
    /// Transmit micro-batches for the transport replay (1 = none).
    pub batches: usize,
    /// The paired loss (two renders with independent seeds).
    pub paired: bool,
    /// `--truth` entries, `PATH=VALUE`.
    pub truth: Vec<String>,
    /// `--levels`.
    pub levels: Levels,
    /// Rays, seed and sampler.
    pub sampling: Sampling,
    /// Continue from the checkpoint in `--out`.
    pub resume: bool,
}

/// Name of a fit's checkpoint in its `--out`.
const CHECKPOINT: &str = "fit.checkpoint.json";

/// Runs the fit and writes its outputs.
pub fn run(
    scene: &Path,
    reference: &Path,
    params: &[String],
    args: &FitArgs,
    common: &Common,
) -> Result<()> {
    let mut objective = build_objective(
        scene,
        reference,
        params,
        args.levels,
        &args.sampling,
        common.threads,
    )?;
    let truth = parse_truth(&objective.specs, &args.truth)?;
    anyhow::ensure!(args.iters >= 1, "--iters must be at least 1");
    crate::work::confirm_work(
        args.iters as f64 * if args.paired { 2.0 } else { 1.0 },
        &objective.scene,
        &objective.opts,
        common.yes,
    )?;
    set_batches(&mut objective, args.batches)?;
    if args.paired {
        objective.pair_seeds();
    }
    let options = FitOptions {
        iters: args.iters,
        resample_seed: args.resample_seed,
        ..Default::default()
    };
    let mut out = OutDir::create(&common.out)?;
    let journal = out.journal(
        CHECKPOINT,
        &[
            &objective.scene,
            &objective.reference,
            &objective.specs,
            &objective.opts,
            &objective.transmit_batches,
            &args.paired,
            &options,
        ],
        args.resume,
    )?;
    let r = run_fit(
        &mut objective,
        &options,
        &out,
        &journal,
        common.quiet,
        &truth,
    )?;
    out.finish()?;
    eprintln!(
        "usray fit: loss {:.4e} → {:.4e} (×{:.1} lower) in {} iterations, {:.1} s; wrote fit.json, fitted.toml, images and plots to {}",
        r.history[0].loss,
        r.final_loss,
        r.history[0].loss / r.final_loss,
        r.history.len(),
        r.seconds,
        common.out.display()
    );
    Ok(())
}

/// Each fitted parameter's true value from `--truth` entries (`PATH=VALUE`),
/// `None` where not given; a path that is not fitted is an error.
pub fn parse_truth(specs: &[ParamSpec], entries: &[String]) -> Result<Vec<Option<f64>>> {
    let mut truth = vec![None; specs.len()];
    for entry in entries {
        let (path, value) = entry
            .split_once('=')
            .with_context(|| format!("--truth: `{entry}` is not PATH=VALUE"))?;
        let key = path.trim().parse::<ParamKey>().ok();
        let j = specs
            .iter()
            .position(|s| Some(&s.key) == key.as_ref())
            .with_context(|| format!("--truth: `{}` is not one of --params", path.trim()))?;
        let v: f64 = value
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .with_context(|| format!("--truth: `{entry}`: the value is not a finite number"))?;
        truth[j] = Some(v);
    }
    Ok(truth)
}

/// Splits the scene's transmits into `n` contiguous micro-batches.
pub fn set_batches(objective: &mut Objective, n: usize) -> Result<()> {
    let n_tx = objective.scene.n_transmits();
    anyhow::ensure!(
        n >= 1 && n <= n_tx,
        "--batches must lie in 1..={n_tx} (the scene's transmits)"
    );
    objective.transmit_batches = if n == 1 {
        Vec::new()
    } else {
        (0..n)
            .map(|b| (b * n_tx / n..(b + 1) * n_tx / n).collect())
            .collect()
    };
    Ok(())
}

/// Fits from the scene's current values with a progress bar and writes every
/// output of a fit; `truth` holds each parameter's true value where known.
pub fn run_fit(
    objective: &mut Objective,
    options: &FitOptions,
    out: &OutDir,
    journal: &Journal,
    quiet: bool,
    truth: &[Option<f64>],
) -> Result<usray_optim::FitResult> {
    let start = objective.initial_physical();
    let initial = objective.value(&start)?.image.data;
    let bar = progress_bar(quiet, options.iters as u64, "fit");
    let result = fit_journaled(objective, &start, options, journal, "fit", |s| {
        bar.set_message(format!("loss {:.4e}", s.loss));
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    let final_image = objective.value(&result.final_params)?.image.data;
    write_fit_outputs(
        out,
        objective,
        &start,
        &result,
        options,
        &initial,
        &final_image,
        truth,
    )?;
    Ok(result)
}
