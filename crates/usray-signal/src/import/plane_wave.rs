//! Acquisitions found by content (see the [`super`] module): plane waves, or the
//! waves their transmit delays describe on a flat or convex array; the
//! parameters by their spellings, the RF by its size and the counts, every
//! quantity's origin recorded.

use std::path::Path;

use serde_json::{json, Map, Value};

use super::axes::{self, Axis};
use super::delays::{self, transmit_waves};
use super::quantities::{AngleUnit, Numbers, Params, Quantity};
use super::record::Record;
use super::samples;
use super::{flat_kind, kind_name, validated, ImportOptions};
use crate::array::{ArrayGeometry, ArrayKind, RADIUS_KEY};
use crate::channels::{
    ChannelData, ChannelMeta, ProbeMeta, TransmitMeta, CHANNELS_FORMAT, FRAME_KEY,
};
use crate::error::{Result, SignalError};
use crate::mat::{MatFile, MatValue};
use crate::transmit::TransmitWave;

/// Imports the acquisition in `vars`: plane waves, or the diverging and focused
/// waves its transmit delays describe ([`super::delays`]), on a flat or convex
/// array.
pub(super) fn import(path: &Path, vars: &MatFile, options: &ImportOptions) -> Result<ChannelData> {
    from_variables(path, vars, options).map_err(|w| SignalError::format(path, w))
}

fn from_variables(
    path: &Path,
    vars: &MatFile,
    options: &ImportOptions,
) -> std::result::Result<ChannelData, String> {
    let mut rec = Record {
        params: Params::find(vars, options.param.as_deref())?,
        names: vars.iter().map(|(n, _)| n.as_str()).collect(),
        used: Map::new(),
        assumed: Vec::new(),
    };

    // Step 1: the quantities with no default.
    let fs = rec.required(
        "sampling_frequency_hz",
        Quantity::SamplingFrequency,
        options.sampling_frequency_hz,
        "--fs",
    )?;
    let c = rec.required(
        "sound_speed_m_s",
        Quantity::SoundSpeed,
        options.sound_speed_m_s,
        "--c",
    )?;
    let pitch = rec.required("pitch_m", Quantity::Pitch, options.pitch_m, "--pitch")?;
    let n_elements_file = match rec.params.scalar(Quantity::ElementCount)? {
        Some((name, n)) if n.fract() == 0.0 && n >= 1.0 => {
            rec.used.insert("n_elements".into(), name.into());
            Some(n as usize)
        }
        Some((name, n)) => {
            return Err(format!(
                "`{name}` = {n} is not a positive whole number of elements"
            ))
        }
        None => None,
    };

    // Step 2: the transmit angles, in radians.
    let angles = match &options.angles_rad {
        Some(a) => {
            rec.used.insert("angles".into(), "--angles-deg".into());
            Some(a.clone())
        }
        None => match rec.params.numbers(Quantity::Angles)? {
            Some(Numbers { name, values, unit }) => {
                let (radians, why) = angles_in_radians(&values, unit);
                rec.used.insert("angles".into(), name.clone().into());
                rec.assumed.push(format!("`{name}` in {why}"));
                Some(radians)
            }
            None => None,
        },
    };

    // The transmit count the delays give when no angles do (PyMUST's TXdelay
    // of diverging or focused waves); all-zero delays say nothing.
    // Else Verasonics' struct array `TX(k).Delay`, gathered into one matrix.
    let tx_struct = delays::struct_array_delays(vars);
    let delays_found: Option<(String, &MatValue)> = match rec.params.get(Quantity::TransmitDelays) {
        Some(f) => Some((f.name, f.value)),
        None => tx_struct.as_ref().map(|(n, v)| (n.clone(), v)),
    };
    let has_delays = delays_found.as_ref().is_some_and(
        |d| !matches!(d.1, MatValue::Numeric { re, .. } if re.iter().all(|&v| v == 0.0)),
    );
    let n_transmits_hint = angles.as_ref().map(Vec::len).or_else(|| {
        let n_el = n_elements_file.filter(|_| has_delays)?;
        delays::transmit_count(delays_found.as_ref()?.1, n_el)
    });

    // Step 3: the RF array and the roles of its axes.
    let (rf_name, rf) = find_rf(vars, options.rf.as_deref())?;
    let MatValue::Numeric {
        class,
        dims,
        re,
        im,
    } = rf
    else {
        return Err(format!("`{rf_name}` is not a numeric array"));
    };
    if im.is_some() {
        return Err(format!(
            "`{rf_name}` is complex (IQ data?); usray imports real RF so far"
        ));
    }
    if let Some(i) = re.iter().position(|v| !v.is_finite()) {
        return Err(format!("`{rf_name}` sample {i} is not finite"));
    }
    let n_angles = n_transmits_hint;
    let roles = match &options.axes {
        Some(given) => {
            axes::check(dims, given, n_elements_file, n_angles)
                .map_err(|w| format!("`{rf_name}` {dims:?}: {w}"))?;
            given.clone()
        }
        None => {
            let r = axes::assign(dims, n_elements_file, n_angles).map_err(|w| {
                format!(
                    "`{rf_name}` has dimensions {dims:?}: {w} (elements from {}, transmits from {}); pass --axes (e.g. samples,elements,transmits)",
                    rec.used.get("n_elements").and_then(Value::as_str).unwrap_or("no field"),
                    rec.used.get("angles").and_then(Value::as_str).unwrap_or("no field"),
                )
            })?;
            if let Some(note) = r.ambiguity {
                rec.assumed.push(format!("`{rf_name}`: {note}"));
            }
            r.roles
        }
    };
    let (offset, offset_note) = samples::integer_offset(*class, options.sample_offset);
    if let Some(w) = samples::offset_warning(re, *class, offset) {
        rec.assumed.push(w);
    }
    rec.assumed.push(offset_note);
    let (samples_c, (n_frames, n_transmits, n_elements, n_samples)) =
        axes::gather(re, dims, &roles, offset);
    let has_frames = roles.contains(&Axis::Frames);
    let angles = match angles {
        Some(a) if a.len() == n_transmits => Some(a),
        Some(a) => {
            return Err(format!(
                "{} transmit angles for {n_transmits} transmit(s) on `{rf_name}`'s axes",
                a.len()
            ))
        }
        None if n_transmits == 1 && !has_delays => {
            rec.assume(
                "angles",
                "no transmit angles in the file: every record is a 0° plane wave".into(),
            );
            Some(vec![0.0])
        }
        None if has_delays => None,
        None => {
            return Err(format!(
                "`{rf_name}` has a transmit axis of {n_transmits} but the file gives no angles ({}) and no transmit delays ({}); pass --angles-deg",
                Quantity::Angles.looked_for(),
                Quantity::TransmitDelays.looked_for()
            ))
        }
    };

    // Step 4: what has a stated default.
    let fc = match rec.lookup(
        "center_frequency_hz",
        Quantity::CenterFrequency,
        options.center_frequency_hz,
        "--fc",
    )? {
        Some(f) => f,
        None => {
            let f = samples::estimate_center_frequency(&samples_c, n_samples, fs)
                .ok_or("no centre frequency in the file and the samples are silent: pass --fc")?;
            rec.assume(
                "center_frequency_hz",
                format!(
                    "centre frequency {:.4} MHz estimated from the samples (middle of the -6 dB band of their spectrum); pass --fc to set it",
                    f / 1e6
                ),
            );
            f
        }
    };
    let width = match rec.lookup(
        "element_width_m",
        Quantity::ElementWidth,
        options.element_width_m,
        "--width",
    )? {
        Some(w) => w,
        None => {
            rec.assume(
                "element_width_m",
                "element width not stored: set to the pitch (no kerf)".into(),
            );
            pitch
        }
    };
    let t0 = match rec.lookup("t0_s", Quantity::StartTime, options.t0_s, "--t0")? {
        Some(t) => t,
        None => {
            rec.assume(
                "t0_s",
                "time of sample 0 not stored: 0, the instant the first element fires".into(),
            );
            0.0
        }
    };
    let bandwidth = rec.lookup("bandwidth_percent", Quantity::Bandwidth, None, "")?;

    let array = array_geometry(&mut rec, n_elements, pitch, width, c, fc)?;

    // Step 5: each transmit's wave and clock (CONTRACT §1: t = 0 when the wave
    // passes the probe-frame origin).
    let waves = transmit_waves(
        delays_found.as_ref().map(|d| (d.0.as_str(), d.1)),
        angles.as_deref(),
        n_transmits,
        &array,
        c,
        fc,
        fs,
        &mut rec,
    )?;

    let mut probe_extra = Map::new();
    if let Some(bw) = bandwidth {
        probe_extra.insert("bandwidth_percent".into(), bw.into());
    }
    if array.kind == ArrayKind::Convex {
        probe_extra.insert(RADIUS_KEY.into(), array.radius_m.into());
    }
    let all_plane = waves.waves.iter().all(TransmitWave::is_plane);
    let transmits = (0..n_frames)
        .flat_map(|f| {
            waves
                .waves
                .iter()
                .zip(&waves.crossing_s)
                .map(move |(wave, &cross)| {
                    let mut extra = Map::new();
                    if has_frames {
                        extra.insert(FRAME_KEY.into(), f.into());
                    }
                    let (kind, angle_rad) = wave.to_meta_fields(&mut extra);
                    let t0_k = t0 - cross;
                    TransmitMeta {
                        kind: kind.into(),
                        angle_rad,
                        t0_s: (t0_k != t0).then_some(t0_k),
                        extra,
                    }
                })
        })
        .collect();
    let mut extra = Map::new();
    let mut source = json!({
        "file": path.file_name().map(|f| f.to_string_lossy().into_owned()),
        "layout": if all_plane {
            "plane wave, found by content"
        } else {
            "diverging or focused waves (from the transmit delays), found by content"
        },
        "parameters": rec.params.struct_name,
        "rf": {
            "variable": rf_name,
            "class": class.name(),
            "dims": dims,
            "axes": axes::join(&roles),
            "offset": offset,
        },
        "used": rec.used,
        "assumed": rec.assumed,
        "overrides": options.overrides(),
    });
    if let Some(fit) = waves.fit {
        source["transmit_fit"] = fit;
    }
    extra.insert("source".into(), source);
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
                    kind: kind_name(array.kind).into(),
                    n_elements,
                    pitch_m: pitch,
                    element_width_m: width,
                    extra: probe_extra,
                },
                transmits,
                extra,
            },
            n_samples,
            samples: samples_c,
        },
    )
    .map_err(|e| e.to_string())
}

/// The array: convex if the file gives a finite radius of curvature (PyMUST's
/// `param.radius`; `Inf` or absent is a flat array), else flat, recorded as
/// `phased` when its pitch is at most [`PHASED_PITCH_WAVELENGTHS`] wavelengths
/// at `fc` (phased arrays are built near λ/2 to steer without grating lobes),
/// else `linear`. Checked as a channel file's probe is.
fn array_geometry(
    rec: &mut Record,
    n_elements: usize,
    pitch_m: f64,
    element_width_m: f64,
    c: f64,
    fc: f64,
) -> std::result::Result<ArrayGeometry<f64>, String> {
    let radius = match rec.params.get(Quantity::Radius) {
        None => None,
        Some(f) => match f.value.scalar() {
            Some(r) if r == f64::INFINITY => {
                rec.used.insert(
                    "radius_m".into(),
                    format!("{} (Inf: a flat array)", f.name).into(),
                );
                None
            }
            Some(r) if r.is_finite() && r > 0.0 => {
                rec.used.insert("radius_m".into(), f.name.into());
                Some(r)
            }
            _ => {
                return Err(format!(
                    "`{}` ({}) must be a positive number or Inf (a flat array)",
                    f.name,
                    Quantity::Radius.describe()
                ))
            }
        },
    };
    let kind = match radius {
        Some(_) => ArrayKind::Convex,
        None => {
            let (kind, note) = flat_kind(pitch_m, c, fc);
            rec.assumed.extend(note);
            kind
        }
    };
    let mut extra = Map::new();
    if let Some(r) = radius {
        extra.insert(RADIUS_KEY.into(), r.into());
    }
    ArrayGeometry::from_meta(&ProbeMeta {
        kind: kind_name(kind).into(),
        n_elements,
        pitch_m,
        element_width_m,
        extra,
    })
}

/// The RF: `forced` (a top-level name or `struct.field`), else the largest real
/// numeric array with at least two axes longer than 1, at the top level or one
/// field deep in a 1×1 struct.
fn find_rf<'a>(
    vars: &'a MatFile,
    forced: Option<&str>,
) -> std::result::Result<(String, &'a MatValue), String> {
    let mut all: Vec<(String, &MatValue)> = Vec::new();
    for (name, v) in vars {
        all.push((name.clone(), v));
        if let MatValue::Struct { fields, elems, .. } = v {
            if elems.len() == 1 {
                for (f, fv) in fields.iter().zip(&elems[0]) {
                    all.push((format!("{name}.{f}"), fv));
                }
            }
        }
    }
    if let Some(name) = forced {
        return all.into_iter().find(|(n, _)| n == name).ok_or_else(|| {
            format!(
                "--rf {name}: no such variable (the file holds {:?})",
                vars.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>()
            )
        });
    }
    let size = |v: &MatValue| match v {
        MatValue::Numeric { dims, re, .. } if dims.iter().filter(|&&d| d > 1).count() >= 2 => {
            re.len()
        }
        _ => 0,
    };
    let empty = all
        .iter()
        .find(|(_, v)| matches!(v, MatValue::Numeric { dims, re, .. } if dims.len() >= 2 && re.is_empty()))
        .map(|(n, _)| n.clone());
    all.into_iter()
        .filter(|(_, v)| size(v) > 0)
        .max_by_key(|(_, v)| size(v))
        .ok_or_else(|| {
            if let Some(n) = empty {
                return format!("no RF array: `{n}` holds no samples");
            }
            format!(
                "no RF array: no numeric variable with at least two axes longer than 1 (the file holds {:?})",
                vars.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>()
            )
        })
}

/// Angles in radians, and why the file's numbers were read in that unit: the
/// unit the name states; else degrees if any exceeds π/2 or all are whole
/// numbers (not all zero) — steering angles are a few tens of degrees, so whole
/// radians are implausible; else radians.
fn angles_in_radians(values: &[f64], unit: Option<AngleUnit>) -> (Vec<f64>, &'static str) {
    let max = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let whole = values.iter().all(|v| v.fract() == 0.0) && max > 0.0;
    let (degrees, why) = match unit {
        Some(AngleUnit::Degrees) => (true, "degrees (its name says so)"),
        Some(AngleUnit::Radians) => (false, "radians (its name says so)"),
        None if max > std::f64::consts::FRAC_PI_2 => (true, "degrees (values beyond π/2)"),
        None if whole => (true, "degrees (whole numbers)"),
        None => (false, "radians (within ±π/2, not whole numbers)"),
    };
    let radians = values
        .iter()
        .map(|&v| if degrees { v.to_radians() } else { v })
        .collect();
    (radians, why)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_units_follow_name_then_values() {
        let r = |v: &[f64], u| angles_in_radians(v, u).0;
        assert_eq!(r(&[-10.0, 0.0, 10.0], None)[2], 10f64.to_radians());
        assert_eq!(r(&[-0.1, 0.0, 0.1], None)[2], 0.1);
        assert_eq!(
            r(&[-0.1, 0.0, 0.1], Some(AngleUnit::Degrees))[2],
            0.1f64.to_radians()
        );
        assert_eq!(r(&[-1.0, 1.0], Some(AngleUnit::Radians))[1], 1.0);
        assert_eq!(r(&[2.5], None)[0], 2.5f64.to_radians());
        assert_eq!(r(&[0.0], None)[0], 0.0);
    }
}
