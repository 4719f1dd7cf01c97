//! `usray beamform CHANNELS [--scene SCENE]`: B-mode (data, image and figure)
//! from any channel data.

use crate::cli::Common;
use crate::output::OutDir;
use anyhow::{Context, Result};
use std::path::Path;
use usray_signal::{read_channels, ImagingSettings};
use usray_transport::Scene;

/// Beamforms the channel data at `channels` on the grid of `scene`'s `[imaging]`,
/// or without a scene on [`ImagingSettings::for_channels`].
pub fn run(channels: &Path, scene: Option<&Path>, common: &Common) -> Result<()> {
    let data = read_channels(channels)?;
    let settings = match scene {
        Some(p) => Scene::load(p)?.imaging_settings(),
        None => ImagingSettings::for_channels(&data.meta, data.n_samples)
            .context("choosing an imaging grid from the channel data")?,
    };
    let (x, z) = settings.grid().context("the imaging grid")?;
    crate::work::confirm_beamforming(
        1.0,
        (z.len(), x.len()),
        (data.n_elements() * data.n_transmits()) as f64,
        common.yes,
    )?;
    let out = OutDir::create(&common.out)?;
    let title = super::render::figure_title(channels);
    let (nz, nx) = super::render::beamform_to(&settings, &data, &out, &title)?;
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
