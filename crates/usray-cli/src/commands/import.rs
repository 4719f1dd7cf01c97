//! `usray import FILE`: measured data into CONTRACT §2 channel data.

use crate::cli::{Common, ImportFlags};
use crate::output::OutDir;
use anyhow::{Context, Result};
use std::path::Path;
use usray_signal::import::Axis;
use usray_signal::{import_mat_with, import_uff_with, write_channels, ImportOptions};

impl ImportFlags {
    /// The flags as the library's options (which checks their values).
    pub fn options(&self) -> Result<ImportOptions> {
        Ok(ImportOptions {
            rf: self.rf.clone(),
            param: self.param.clone(),
            axes: self
                .axes
                .as_deref()
                .map(Axis::parse_order)
                .transpose()
                .map_err(|e| anyhow::anyhow!("--axes: {e}"))?,
            sampling_frequency_hz: self.fs,
            center_frequency_hz: self.fc,
            sound_speed_m_s: self.c,
            pitch_m: self.pitch,
            element_width_m: self.width,
            angles_rad: self
                .angles_deg
                .as_ref()
                .map(|a| a.iter().map(|d| d.to_radians()).collect()),
            t0_s: self.t0,
            sample_offset: self.offset,
        })
    }
}

/// Converts `file` and writes `NAME.npy`/`NAME.json` into `common.out`, with
/// `flags` supplying or overriding what the file stores; prints which variables
/// were used and what was assumed.
pub fn run(file: &Path, name: Option<&str>, flags: &ImportFlags, common: &Common) -> Result<()> {
    let options = flags.options()?;
    let extension = file
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let data = match extension.as_deref() {
        Some("mat") => import_mat_with(file, &options)?,
        Some("uff") => import_uff_with(file, &options)?,
        _ => anyhow::bail!(
            "{}: only MATLAB .mat (v5 or v7.3) and UFF .uff files can be imported",
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
        "usray import: {} → {} ({} transmits × {} elements × {} samples, fs {:.4e} Hz, fc {:.4e} Hz, c {} m/s, pitch {:.4e} m, t0 {:.4e} s on the CONTRACT §1 clock)",
        file.display(),
        json.display(),
        data.n_transmits(),
        data.n_elements(),
        data.n_samples,
        data.meta.sampling_frequency_hz,
        data.meta.center_frequency_hz,
        data.meta.sound_speed_m_s,
        data.meta.probe.pitch_m,
        data.meta.t0_s
    );
    eprint!("{}", provenance(&data.meta.extra["source"]));
    Ok(())
}

/// The import's `source` record as lines: the RF variable and its axes, where
/// each quantity came from, the transmits fitted to the file's delays, what was
/// assumed.
fn provenance(source: &serde_json::Value) -> String {
    let mut out = String::new();
    if let Some(rf) = source.get("rf") {
        out += &format!(
            "  RF: `{}` ({} {}, axes {})\n",
            rf["variable"].as_str().unwrap_or("?"),
            rf["class"].as_str().unwrap_or("?"),
            rf["dims"],
            rf["axes"].as_str().unwrap_or("?")
        );
    }
    if let Some(used) = source.get("used").and_then(|u| u.as_object()) {
        let from: Vec<String> = used
            .iter()
            .map(|(k, v)| format!("{k} ← {}", v.as_str().unwrap_or("?")))
            .collect();
        out += &format!("  from: {}\n", from.join("; "));
    }
    let fits = source["transmit_fit"]["transmits"].as_array();
    for t in fits.into_iter().flatten() {
        let mm = |k: &str| {
            let p = |i: usize| t[k][i].as_f64().unwrap_or(f64::NAN) * 1e3;
            format!("({:.3}, {:.3}) mm", p(0), p(1))
        };
        let wave = match t["kind"].as_str().unwrap_or("?") {
            "diverging" => format!("diverging, virtual source {}", mm("virtual_source_m")),
            "focused" => format!("focused, focus {}", mm("focus_m")),
            kind => format!(
                "{kind}, angle {:.3}°",
                t["angle_rad"].as_f64().unwrap_or(f64::NAN).to_degrees()
            ),
        };
        out += &format!(
            "  transmit {}: {wave} (fitted to the delays, largest residual {:.2e} samples)\n",
            t["transmit"],
            t["max_residual_samples"].as_f64().unwrap_or(f64::NAN)
        );
    }
    for a in source
        .get("assumed")
        .and_then(|a| a.as_array())
        .into_iter()
        .flatten()
    {
        out += &format!("  assumed: {}\n", a.as_str().unwrap_or("?"));
    }
    out
}
