//! `usray export CHANNELS.json --format uff`: channel data into another format.

use crate::cli::{Common, ExportFormat};
use crate::output::OutDir;
use anyhow::{Context, Result};
use std::path::Path;
use usray_signal::{export_uff, read_channels};

/// Reads the channel data `channels` and writes `NAME.uff` into `common.out`.
pub fn run(
    channels: &Path,
    format: ExportFormat,
    name: Option<&str>,
    common: &Common,
) -> Result<()> {
    let data = read_channels(channels)?;
    let stem = match name {
        Some(n) => n.to_string(),
        None => channels
            .with_extension("")
            .file_name()
            .context("the input has no file name")?
            .to_string_lossy()
            .into_owned(),
    };
    let file = match format {
        ExportFormat::Uff => format!("{stem}.uff"),
    };
    let out = OutDir::create(&common.out)?;
    match format {
        ExportFormat::Uff => export_uff(out.path(&file), &data)?,
    }
    out.finish()?;
    eprintln!(
        "usray export: {} → {} ({} transmits × {} elements × {} samples)",
        channels.display(),
        common.out.join(&file).display(),
        data.n_transmits(),
        data.n_elements(),
        data.n_samples
    );
    Ok(())
}
