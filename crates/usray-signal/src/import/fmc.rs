//! Full-matrix capture files as in `synaptus` (`ArraySteelPins.mat`,
//! `ArrayCuBlockStationary.mat`), summed over transmits to one 0° plane wave.

use std::path::Path;

use super::samples::estimate_center_frequency;
use super::{validated, ImportOptions};
use crate::channels::{ChannelData, ChannelMeta, ProbeMeta, TransmitMeta, CHANNELS_FORMAT};
use crate::error::{Result, SignalError};
use crate::mat::{MatFile, MatValue};

/// The variable `name` of `vars`.
fn get<'a>(vars: &'a MatFile, name: &str) -> Option<&'a MatValue> {
    vars.iter().find(|(n, _)| n == name).map(|(_, v)| v)
}

/// Whether `vars` hold a full-matrix capture: a cell `data` and no `param`.
pub(super) fn is_full_matrix_capture(vars: &MatFile) -> bool {
    get(vars, "param").is_none() && matches!(get(vars, "data"), Some(MatValue::Cell { .. }))
}

/// Imports the full-matrix capture in `vars` (layout in [`super::import_mat_with`]).
pub(super) fn import(path: &Path, vars: &MatFile, options: &ImportOptions) -> Result<ChannelData> {
    let err = |w: String| SignalError::format(path, w);
    options
        .refuse_unused(
            "a full-matrix capture",
            &["--fs", "--fc", "--c", "--pitch", "--t0"],
        )
        .map_err(err)?;
    let scalar = |name: &str| -> Result<f64> {
        get(vars, name)
            .and_then(|v| v.scalar())
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                err(format!(
                    "full-matrix capture: scalar `{name}` is missing or not finite"
                ))
            })
    };
    let fs = match options.sampling_frequency_hz {
        Some(f) => f,
        None => scalar("fs")? * 1e6, // stored in MHz
    };
    let t0 = match options.t0_s {
        Some(t) => t,
        None => scalar("MWB")? / 1e6, // stored in µs
    };
    let c = match options.sound_speed_m_s {
        Some(c) => c,
        None => scalar("cp")?,
    };
    let ne = scalar("nTotElem")?;
    if ne.fract() != 0.0 || ne < 1.0 {
        return Err(err(format!(
            "full-matrix capture: `nTotElem` = {ne} is not a positive whole number"
        )));
    }
    let ne = ne as usize;
    let stated_fc = options
        .center_frequency_hz
        .or_else(|| get(vars, "fc").and_then(|v| v.scalar()));
    let pitch = options.pitch_m.ok_or_else(|| {
        err("full-matrix capture: the element pitch is not stored in the file; pass it (`usray import --pitch METRES`, or ImportOptions::pitch_m)".into())
    })?;
    if !(fs > 0.0 && c > 0.0 && stated_fc.is_none_or(|f| f > 0.0) && pitch > 0.0 && ne > 0) {
        return Err(err(format!("full-matrix capture: non-positive fs {fs}, cp {c}, fc {stated_fc:?}, pitch {pitch} or nTotElem {ne}")));
    }
    let Some(MatValue::Cell { cells, .. }) = get(vars, "data") else {
        return Err(err("`data` is not a cell array".into()));
    };
    if cells.len() != ne {
        return Err(err(format!(
            "`data` has {} transmits, `nTotElem` = {ne}",
            cells.len()
        )));
    }
    let mut sum: Vec<f64> = Vec::new();
    let mut ns = 0;
    for (k, cell) in cells.iter().enumerate() {
        let MatValue::Numeric {
            dims, re, im: None, ..
        } = cell
        else {
            return Err(err(format!(
                "`data{{{}}}` is not a real numeric array",
                k + 1
            )));
        };
        if dims.len() != 2 || dims[1] != ne {
            return Err(err(format!(
                "`data{{{}}}` has dimensions {dims:?}; expected (time, {ne})",
                k + 1
            )));
        }
        if k == 0 {
            ns = dims[0];
            sum = vec![0.0; ns * ne];
        } else if dims[0] != ns {
            return Err(err(format!(
                "`data{{{}}}` has {} samples, `data{{1}}` has {ns}",
                k + 1,
                dims[0]
            )));
        }
        // Column-major (time, rx) → C order [rx, time]: identical memory order.
        for (s, v) in sum.iter_mut().zip(re) {
            *s += v;
        }
    }
    // Without a stated centre frequency, the samples' own (as for plane waves).
    let (fc, fc_note) = match stated_fc {
        Some(f) => (f, "stated (the file's `fc` or --fc)".to_string()),
        None => {
            let f = estimate_center_frequency(&sum, ns, fs).ok_or_else(|| {
                err("full-matrix capture: no `fc` in the file and the samples are silent; pass --fc".into())
            })?;
            (
                f,
                format!(
                    "{:.4} MHz estimated from the samples (middle of the -6 dB band of their spectrum); pass --fc to set it",
                    f / 1e6
                ),
            )
        }
    };
    let mut extra = serde_json::Map::new();
    extra.insert(
        "source".into(),
        serde_json::json!({
            "file": path.file_name().map(|f| f.to_string_lossy().into_owned()),
            "fc_note": fc_note,
            "layout": "full-matrix capture data{k}(time, rx), summed over k to a 0-degree plane wave",
            "clock": "t0_s = MWB; the transducer's pulse-centre delay is unknown and not corrected",
            "overrides": options.overrides(),
            "width_note": "element width not stored: set to the pitch",
            "pitch_source": "user-supplied (not stored in the file)",
        }),
    );
    validated(
        path,
        ChannelData {
            meta: ChannelMeta {
                format: CHANNELS_FORMAT.into(),
                sampling_frequency_hz: fs,
                t0_s: t0,
                sound_speed_m_s: c,
                center_frequency_hz: fc,
                probe: ProbeMeta {
                    kind: "linear".into(),
                    n_elements: ne,
                    pitch_m: pitch,
                    element_width_m: pitch,
                    extra: serde_json::Map::new(),
                },
                transmits: vec![TransmitMeta {
                    kind: "plane_wave".into(),
                    angle_rad: 0.0,
                    t0_s: None,
                    extra: serde_json::Map::new(),
                }],
                extra,
            },
            n_samples: ns,
            samples: sum,
        },
    )
}
