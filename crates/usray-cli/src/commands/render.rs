//! `usray render SCENE`: channel data, B-mode and render statistics.

use crate::cli::{Common, Sampling};
use crate::output::{spinner, OutDir};
use crate::plots::{bmode_figure, Grid};
use anyhow::{Context, Result};
use serde_json::json;
use std::path::Path;
use usray_signal::{write_channels, BMode, ChannelData, ImagingSettings};
use usray_transport::{render, AcquisitionPlan, Scene};

/// Renders `scene` into `common.out`.
pub fn run(scene_path: &Path, sampling: &Sampling, common: &Common) -> Result<()> {
    let scene = Scene::load(scene_path)?;
    let opts = sampling.render_options(common.threads)?;
    crate::work::confirm_work(1.0, &scene, &opts, common.yes)?;
    let out = OutDir::create(&common.out)?;
    // The beamformer's set-up is checked before the trace, so a bad imaging grid
    // fails at once rather than after it.
    let plan = AcquisitionPlan::new(&scene);
    BMode::new(
        &scene.imaging_settings(),
        &plan.channel_meta(),
        plan.grid.n_samples,
    )
    .context("setting up the beamformer from the scene's [imaging]")?;
    let bar = spinner(common.quiet, &format!("tracing {}", scene_path.display()));
    let (channels, stats) = render(&scene, &opts)?;
    bar.finish_and_clear();
    write_channels(out.path("channels.json"), &channels)?;
    let bmode = beamform_to(
        &scene.imaging_settings(),
        &channels,
        &out,
        &figure_title(scene_path),
    )?;
    let info = json!({
        "scene": scene_path.display().to_string(),
        "seed": opts.seed.unwrap_or(scene.acquisition.seed),
        "sampler": opts.sampler.unwrap_or(scene.acquisition.sampler),
        "rays_traced": stats.rays_traced,
        "paths": stats.paths,
        "deposits": stats.deposits,
        "seconds": stats.seconds,
        "rays_per_second": stats.rays_per_second,
        "threads": rayon::current_num_threads(),
        "bmode_shape": [bmode.0, bmode.1],
    });
    out.write_json("render.json", &info)?;
    out.finish()?;
    eprintln!(
        "usray render: traced {} rays in {:.2} s ({:.3e} rays/s); wrote channels, bmode.npy/.png, the B-mode figure and render.json to {}",
        stats.rays_traced,
        stats.seconds,
        stats.rays_per_second,
        common.out.display()
    );
    Ok(())
}

/// The B-mode figure's title: "B-mode of" the file it came from.
pub fn figure_title(source: &Path) -> String {
    let name = source.file_name().unwrap_or(source.as_os_str());
    format!("B-mode of {}", name.to_string_lossy())
}

/// Forms the B-mode of `channels` on the grid of `settings` and writes
/// `bmode.npy` (the data), `bmode.png` (one grey pixel per grid point) and the
/// figure `bmode_figure.png`/`.svg` (mm axes, dB colour bar, `title`); returns
/// `(nz, nx)`.
pub fn beamform_to(
    settings: &ImagingSettings,
    channels: &ChannelData,
    out: &OutDir,
    title: &str,
) -> Result<(usize, usize)> {
    let op = BMode::new(settings, &channels.meta, channels.n_samples)
        .context("setting up the beamformer from the imaging settings")?;
    let mut ws = op.workspace();
    let image = op.forward(channels, &mut ws)?;
    let grid = Grid::from_settings(settings)?;
    let figure = |name: &str| {
        bmode_figure(
            &out.path(name),
            &grid,
            &image.data,
            settings.dynamic_range_db,
            title,
        )
    };
    // The four files are independent: written side by side.
    let ((npy, png), (fig_png, fig_svg)) = rayon::join(
        || {
            rayon::join(
                || image.write_npy(out.path("bmode.npy")),
                || image.write_png(out.path("bmode.png")),
            )
        },
        || rayon::join(|| figure("bmode_figure.png"), || figure("bmode_figure.svg")),
    );
    npy?;
    png?;
    fig_png?;
    fig_svg?;
    Ok((image.nz, image.nx))
}
