//! Plane-wave acquisitions, found by content (see the [`super`] module): the
//! parameters by their spellings, the RF by its size and the counts, every
//! quantity's origin recorded.

use std::path::Path;

use serde_json::{json, Map, Value};

use super::axes::{self, Axis};
use super::quantities::{AngleUnit, Numbers, Params, Quantity};
use super::samples;
use super::{validated, ImportOptions};
use crate::channels::{
    ChannelData, ChannelMeta, ProbeMeta, TransmitMeta, CHANNELS_FORMAT, FRAME_KEY,
};
use crate::error::{Result, SignalError};
use crate::mat::{MatFile, MatValue};

/// Where each quantity came from and what was assumed: the output's `source`.
struct Record<'a> {
    params: Params<'a>,
    /// The file's top-level variable names, for messages.
    names: Vec<&'a str>,
    used: Map<String, Value>,
    assumed: Vec<String>,
}

impl<'a> Record<'a> {
    /// `forced` if given (from `flag`), else the file's scalar `q`.
    fn lookup(
        &mut self,
        key: &str,
        q: Quantity,
        forced: Option<f64>,
        flag: &str,
    ) -> std::result::Result<Option<f64>, String> {
        let found = match forced {
            Some(v) => Some((flag.to_string(), v)),
            None => self.params.scalar(q)?,
        };
        Ok(found.map(|(from, v)| {
            self.used.insert(key.into(), from.into());
            v
        }))
    }

    /// Like [`Record::lookup`], but missing is an error naming what was looked for.
    fn required(
        &mut self,
        key: &str,
        q: Quantity,
        forced: Option<f64>,
        flag: &str,
    ) -> std::result::Result<f64, String> {
        let where_ = match self.params.struct_name {
            Some(s) => format!("in struct `{s}` or at the top level"),
            None => "at the top level (the file has no struct of acquisition parameters)".into(),
        };
        let names = self.names.clone();
        self.lookup(key, q, forced, flag)?.ok_or_else(|| {
            format!(
                "no {} found: looked {where_} for a field named one of {} (case and underscores ignored; the file holds {names:?}); pass {flag}",
                q.describe(),
                q.looked_for()
            )
        })
    }

    fn assume(&mut self, key: &str, what: String) {
        self.used.insert(key.into(), "assumed".into());
        self.assumed.push(what);
    }
}

/// Imports the plane-wave acquisition in `vars`.
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
    let n_angles = angles.as_ref().map(Vec::len);
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
        Some(a) if a.len() == n_transmits => a,
        Some(a) => {
            return Err(format!(
                "{} transmit angles for {n_transmits} transmit(s) on `{rf_name}`'s axes",
                a.len()
            ))
        }
        None if n_transmits == 1 => {
            rec.assume(
                "angles",
                "no transmit angles in the file: every record is a 0° plane wave".into(),
            );
            vec![0.0]
        }
        None => {
            return Err(format!(
                "`{rf_name}` has a transmit axis of {n_transmits} but the file gives no angles ({}); pass --angles-deg",
                Quantity::Angles.looked_for()
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

    // Step 5: each transmit's clock (CONTRACT §1: t = 0 when the wave passes the
    // array centre).
    let delays = rec.params.get(Quantity::TransmitDelays);
    let crossing_s = centre_crossing_times(
        delays.as_ref().map(|d| (d.name.as_str(), d.value)),
        &angles,
        n_elements,
        pitch,
        c,
        fc,
        &mut rec,
    )?;

    let mut probe_extra = Map::new();
    if let Some(bw) = bandwidth {
        probe_extra.insert("bandwidth_percent".into(), bw.into());
    }
    let transmits = (0..n_frames)
        .flat_map(|f| {
            angles
                .iter()
                .zip(&crossing_s)
                .map(move |(&angle_rad, &cross)| {
                    let mut extra = Map::new();
                    if has_frames {
                        extra.insert(FRAME_KEY.into(), f.into());
                    }
                    let t0_k = t0 - cross;
                    TransmitMeta {
                        kind: "plane_wave".into(),
                        angle_rad,
                        t0_s: (t0_k != t0).then_some(t0_k),
                        extra,
                    }
                })
        })
        .collect();
    let mut extra = Map::new();
    extra.insert(
        "source".into(),
        json!({
            "file": path.file_name().map(|f| f.to_string_lossy().into_owned()),
            "layout": "plane wave, found by content",
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

/// The time, on the file's transmit clock, at which each transmit's wave passes
/// the array centre (CONTRACT §1's t = 0), seconds.
///
/// From the file's per-element delays when they are present and not all zero:
/// their least-squares line in the element position `x` (a plane wave fires
/// element `x` at `a + x·sin θ / c`) gives `a`, in seconds if the slope is
/// `sin θ / c` or in wavelengths (Verasonics' `TX.Delay`) if it is
/// `sin θ · fc / c`; a non-linear profile (focused, diverging) is refused.
/// Otherwise the first element fires at 0 and the centre is crossed
/// `(L/2)·|sin θ| / c` later (PyMUST's `txdelay`).
fn centre_crossing_times(
    delays: Option<(&str, &MatValue)>,
    angles: &[f64],
    n_el: usize,
    pitch_m: f64,
    c: f64,
    fc: f64,
    rec: &mut Record,
) -> std::result::Result<Vec<f64>, String> {
    let convention = |rec: &mut Record, why: &str| {
        rec.assume(
            "transmit_delays",
            format!("{why}: the first element fires at 0, the wave crosses the array centre (L/2)|sin θ|/c later"),
        );
        angles
            .iter()
            .map(|a| (n_el - 1) as f64 * pitch_m / 2.0 * a.sin().abs() / c)
            .collect()
    };
    let Some((name, value)) = delays else {
        return Ok(convention(rec, "no transmit delays in the file"));
    };
    let MatValue::Numeric { dims, re, .. } = value else {
        return Err(format!("`{name}` (transmit delays) is not numeric"));
    };
    if re.iter().all(|&d| d == 0.0) {
        if angles.iter().any(|&a| a != 0.0) {
            return Ok(convention(rec, &format!("`{name}` is all zero")));
        }
        rec.used.insert("transmit_delays".into(), name.into());
        return Ok(vec![0.0; angles.len()]);
    }
    let n_tx = angles.len();
    if re.len() != n_el * n_tx {
        return Err(format!(
            "`{name}` holds {} delays; {n_el} elements × {n_tx} transmit(s) need {}",
            re.len(),
            n_el * n_tx
        ));
    }
    // Column-major (elements, transmits) unless the first axis is the transmits'.
    let transmits_first = n_tx > 1 && dims.first() == Some(&n_tx) && dims.get(1) == Some(&n_el);
    let profile = |k: usize| -> Vec<f64> {
        (0..n_el)
            .map(|e| {
                if transmits_first {
                    re[e * n_tx + k]
                } else {
                    re[k * n_el + e]
                }
            })
            .collect()
    };
    let x: Vec<f64> = (0..n_el)
        .map(|e| (e as f64 - (n_el - 1) as f64 / 2.0) * pitch_m)
        .collect();
    let aperture_m = (n_el - 1) as f64 * pitch_m;
    let mut out = Vec::with_capacity(n_tx);
    let mut units = Vec::new();
    for (k, &theta) in angles.iter().enumerate() {
        let d = profile(k);
        let (a, b, rms) = fit_line(&x, &d);
        let span = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if rms > 1e-3 * span {
            return Err(format!(
                "`{name}` for transmit {k} is not linear in the element position (a focused or diverging transmit?): usray imports plane waves"
            ));
        }
        let slope_s = theta.sin() / c;
        let close = |got: f64| (got - slope_s).abs() <= 0.05 * slope_s.abs();
        let (crossing, unit) = if theta == 0.0 {
            if b.abs() * aperture_m > 1e-3 * a.abs() {
                return Err(format!(
                    "`{name}` for transmit {k} is a steered profile, but the transmit's angle is 0: pass --angles-deg"
                ));
            }
            // A constant delay: seconds if under a millisecond, else wavelengths
            // (zero is both).
            if a == 0.0 {
                (a, "")
            } else if a.abs() < 1e-3 {
                (a, "seconds")
            } else {
                (a / fc, "wavelengths")
            }
        } else if close(b) {
            (a, "seconds")
        } else if close(b / fc) {
            (a / fc, "wavelengths")
        } else {
            return Err(format!(
                "`{name}` for transmit {k}: its slope {b:.4e} per metre fits neither sin θ/c = {slope_s:.4e} s/m (delays in seconds) nor sin θ·fc/c = {:.4e} /m (in wavelengths) at the transmit's angle {:.2}°",
                slope_s * fc,
                theta.to_degrees()
            ));
        };
        if !unit.is_empty() && !units.contains(&unit) {
            units.push(unit);
        }
        out.push(crossing);
    }
    let unit = units.join(" and ");
    rec.used.insert(
        "transmit_delays".into(),
        format!("{name} (in {unit}; the centre crossing is their value at x = 0)").into(),
    );
    Ok(out)
}

/// Least-squares line `y ≈ a + b·x` and its residual RMS.
fn fit_line(x: &[f64], y: &[f64]) -> (f64, f64, f64) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let a = my - b * mx;
    let rms = (x
        .iter()
        .zip(y)
        .map(|(xi, yi)| (yi - a - b * xi).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    (a, b, rms)
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

    #[test]
    fn a_line_is_fitted_exactly() {
        let x = [-1.0, 0.0, 1.0, 2.0];
        let y: Vec<f64> = x.iter().map(|v| 3.0 - 2.0 * v).collect();
        let (a, b, rms) = fit_line(&x, &y);
        assert!((a - 3.0).abs() < 1e-12 && (b + 2.0).abs() < 1e-12 && rms < 1e-12);
    }
}
