//! `usray grad SCENE --reference REF --params P1,P2 [--fd-sweep]`: `grad.json`.

use super::calib::{build_objective, grad_json, progress_bar, write_sweep_plots};
use crate::cli::{Common, Levels, Sampling};
use crate::output::{spinner, OutDir};
use anyhow::Result;
use std::path::Path;
use usray_optim::{best_fd, fd_sweeps, sweep_steps};

/// Gradient of the image loss at the scene's values, optionally with FD sweeps.
pub fn run(
    scene: &Path,
    reference: &Path,
    params: &[String],
    fd_sweep: bool,
    levels: Levels,
    sampling: &Sampling,
    common: &Common,
) -> Result<()> {
    let objective = build_objective(scene, reference, params, levels, sampling, common.threads)?;
    let at = objective.initial_physical();
    let sweep_renders = if fd_sweep {
        objective
            .specs
            .iter()
            .map(|s| 2 * sweep_steps(s).len())
            .sum::<usize>()
    } else {
        0
    };
    crate::work::confirm_work(
        1.0 + sweep_renders as f64,
        &objective.scene,
        &objective.opts,
        common.yes,
    )?;
    let out = OutDir::create(&common.out)?;
    let bar = spinner(common.quiet, "loss and gradient");
    let eval = objective.value_and_gradient(&at)?;
    bar.finish_and_clear();
    let sweeps = if fd_sweep {
        let n = objective.specs.len() as u64 * 2 * sweep_steps(&objective.specs[0]).len() as u64;
        let bar = progress_bar(common.quiet, n, "FD sweep");
        let s = fd_sweeps(&objective, &at, || bar.inc(1))?;
        bar.finish_and_clear();
        Some(s)
    } else {
        None
    };
    if let Some(s) = &sweeps {
        write_sweep_plots(&out, &objective.specs, &eval.gradient, s)?;
    }
    out.write_json(
        "grad.json",
        &grad_json(
            eval.loss,
            &objective.specs,
            &eval.gradient,
            sweeps.as_deref(),
        ),
    )?;
    out.finish()?;
    eprintln!("usray grad: loss {:.6e}", eval.loss);
    for (j, s) in objective.specs.iter().enumerate() {
        let g = eval.gradient[j];
        let mut line = format!("  {} = {}: ∂L/∂θ = {g:.6e}", s.key, at[j]);
        if eval.demod_fc_part[j] != 0.0 {
            line += &format!(
                " (of which the image formation's f_c, with the channel data held: {:.3e})",
                eval.demod_fc_part[j]
            );
        }
        if let Some((p, rel)) = sweeps.as_ref().and_then(|sw| best_fd(&sw[j], g)) {
            line += &format!(
                "; best FD {:.6e} at ε = {:.2e} (rel. diff {:.2e})",
                p.fd, p.eps, rel
            );
        }
        eprintln!("{line}");
    }
    eprintln!(
        "wrote grad.json{} to {}",
        if fd_sweep { " and FD-vs-AD plots" } else { "" },
        common.out.display()
    );
    Ok(())
}
