//! `usray beamform CHANNELS --scene SCENE`: B-mode (data, image and figure)
//! from any channel data.

use crate::cli::Common;
use crate::output::OutDir;
use anyhow::Result;
use std::path::Path;
use usray_signal::read_channels;
use usray_transport::Scene;

/// Beamforms the channel data at `channels` on the grid of `scene`'s `[imaging]`.
pub fn run(channels: &Path, scene: &Path, common: &Common) -> Result<()> {
    let scene = Scene::load(scene)?;
    let data = read_channels(channels)?;
    crate::work::confirm_beamforming(
        1.0,
        &scene,
        (data.n_elements() * data.n_transmits()) as f64,
        common.yes,
    )?;
    let out = OutDir::create(&common.out)?;
    let title = super::render::figure_title(channels);
    let (nz, nx) = super::render::beamform_to(&scene, &data, &out, &title)?;
    out.finish()?;
    eprintln!(
        "usray beamform: {} transmits × {} elements × {} samples → B-mode {nz}×{nx}; wrote bmode.npy, bmode.png and bmode_figure.png/.svg to {}",
        data.n_transmits(),
        data.n_elements(),
        data.n_samples,
        common.out.display()
    );
    Ok(())
}
