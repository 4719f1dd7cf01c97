//! `usray import FILE`: measured data into CONTRACT §2 channel data.

use crate::cli::Common;
use crate::output::OutDir;
use anyhow::{Context, Result};
use std::path::Path;
use usray_signal::{import_mat_with, import_uff_with, write_channels, ImportOptions};

/// Converts `file` and writes `NAME.npy`/`NAME.json` into `common.out`, with
/// `options` supplying what the file does not store.
pub fn run(
    file: &Path,
    name: Option<&str>,
    options: &ImportOptions,
    common: &Common,
) -> Result<()> {
    for (flag, v) in [
        ("--pitch", options.pitch_m),
        ("--fc", options.center_frequency_hz),
    ] {
        if let Some(v) = v {
            anyhow::ensure!(
                v.is_finite() && v > 0.0,
                "{flag} must be a positive number, got {v}"
            );
        }
    }
    let extension = file
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let data = match extension.as_deref() {
        Some("mat") => import_mat_with(file, options)?,
        Some("uff") => import_uff_with(file, options)?,
        _ => anyhow::bail!(
            "{}: only MATLAB .mat (v5 or v7.3; Verasonics plane-wave or full-matrix layout) and UFF .uff files can be imported",
            file.display()
        ),
    };
    let stem = match name {
        Some(n) => n.to_string(),
        None => file
            .file_stem()
            .context("the input has no file name")?
            .to_string_lossy()
            .into_owned(),
    };
    let out = OutDir::create(&common.out)?;
    write_channels(out.path(&format!("{stem}.json")), &data)?;
    out.finish()?;
    let json = common.out.join(format!("{stem}.json"));
    eprintln!(
        "usray import: {} → {} ({} transmits × {} elements × {} samples, fs {:.4e} Hz, t0 {:.4e} s on the CONTRACT §1 clock)",
        file.display(),
        json.display(),
        data.n_transmits(),
        data.n_elements(),
        data.n_samples,
        data.meta.sampling_frequency_hz,
        data.meta.t0_s
    );
    Ok(())
}
