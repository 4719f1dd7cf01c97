//! One module per subcommand.

mod beamform;
pub mod calib;
pub mod demo;
mod diagnose;
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
            seed,
            rays,
            common,
        } => render::run(scene, *seed, *rays, common),
        Command::Beamform {
            channels,
            scene,
            common,
        } => beamform::run(channels, scene, common),
        Command::Import { file, name, common } => import::run(file, name.as_deref(), common),
        Command::Params { scene, common } => params::run(scene, &common.out),
        Command::Demo { common } => demo::run(common),
        Command::Grad {
            scene,
            reference,
            params,
            fd_sweep,
            rays,
            seed,
            common,
        } => grad::run(scene, reference, params, *fd_sweep, *rays, *seed, common),
        Command::Fit {
            scene,
            reference,
            params,
            iters,
            resample_seed,
            batches,
            paired,
            rays,
            seed,
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
                rays: *rays,
                seed: *seed,
            },
            common,
        ),
        Command::Diagnose {
            scene,
            measured,
            params,
            iters,
            confirm,
            rays,
            seed,
            held_out_seeds,
            paired,
            held_out_measured,
            held_out_frames,
            common,
        } => diagnose::run(
            scene,
            measured,
            &diagnose::DiagnoseArgs {
                params: params.clone(),
                iters: *iters,
                confirm: *confirm,
                rays: *rays,
                seed: *seed,
                held_out_seeds: *held_out_seeds,
                paired: *paired,
                held_out_measured: held_out_measured.clone(),
                held_out_frames: *held_out_frames,
            },
            common,
        ),
    })?
}
