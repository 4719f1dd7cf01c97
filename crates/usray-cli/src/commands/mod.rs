//! One module per subcommand.

mod beamform;
pub mod calib;
pub mod demo;
mod diagnose;
mod export;
pub mod fit;
mod grad;
mod import;
mod params;
mod render;

use crate::cli::Command;
use crate::output::with_threads;

/// Runs one parsed command.
pub fn run(command: &Command) -> anyhow::Result<()> {
    let threads = command.common().threads;
    with_threads(threads, || match command {
        Command::Render {
            scene,
            sampling,
            common,
        } => render::run(scene, sampling, common),
        Command::Beamform {
            channels,
            scene,
            common,
        } => beamform::run(channels, scene.as_deref(), common),
        Command::Import {
            file,
            name,
            flags,
            common,
        } => import::run(file, name.as_deref(), flags, common),
        Command::Export {
            channels,
            format,
            name,
            common,
        } => export::run(channels, *format, name.as_deref(), common),
        Command::Params { scene, common } => params::run(scene, &common.out),
        Command::Demo { common } => demo::run(common),
        Command::Grad {
            scene,
            reference,
            params,
            fd_sweep,
            levels,
            sampling,
            common,
        } => grad::run(
            scene, reference, params, *fd_sweep, *levels, sampling, common,
        ),
        Command::Fit {
            scene,
            reference,
            params,
            iters,
            resample_seed,
            batches,
            paired,
            truth,
            levels,
            resume,
            sampling,
            common,
        } => fit::run(
            scene,
            reference,
            params,
            &fit::FitArgs {
                iters: *iters,
                resample_seed: *resample_seed,
                batches: *batches,
                paired: *paired,
                truth: truth.clone(),
                levels: *levels,
                sampling: sampling.clone(),
                resume: resume.is_some(),
            },
            &crate::output::resumed(common, resume.as_deref())?,
        ),
        Command::Diagnose {
            scene,
            measured,
            params,
            iters,
            confirm,
            sampling,
            held_out_seeds,
            paired,
            held_out_measured,
            held_out_frames,
            budget,
            rounds,
            smoothing,
            floor,
            levels,
            resume,
            common,
        } => diagnose::run(
            scene,
            measured,
            &diagnose::DiagnoseArgs {
                params: params.clone(),
                iters: *iters,
                confirm: *confirm,
                sampling: sampling.clone(),
                held_out_seeds: *held_out_seeds,
                paired: *paired,
                held_out_measured: held_out_measured.clone(),
                held_out_frames: *held_out_frames,
                budget_s: *budget,
                rounds: *rounds,
                smoothing_wavelengths: *smoothing,
                noise_floor: *floor,
                levels: *levels,
                resume: resume.is_some(),
            },
            &crate::output::resumed(common, resume.as_deref())?,
        ),
    })?
}
