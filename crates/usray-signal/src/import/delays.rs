//! Each transmit's wave and clock from what the file says about its transmits:
//! steering angles and per-element transmit delays (PyMUST's `param.TXdelay`,
//! `[n_transmits × n_elements]` or its transpose, in seconds; Verasonics'
//! `TX.Delay` in wavelengths).
//!
//! - A flat array with known angles and delays linear in the element position
//!   (or none): plane waves, the clock from the delays' value at `x = 0`, else
//!   from the first-firing convention ([`plane_centre_crossing_times`]).
//! - Otherwise, delays present: each transmit's wave is fitted to its delays
//!   ([`super::wave_fit`]: plane, diverging or focused, on the array's true
//!   element positions) within [`FIT_TOLERANCE_SAMPLES`] of a sample, or the
//!   transmit is refused by number with the residual of each model.
//! - A convex array with angles and no delays: plane waves, the first-firing
//!   element at 0.

use serde_json::{json, Value};

use super::record::Record;
use super::wave_fit::{self, fit_line};
use crate::array::ArrayGeometry;
use crate::mat::{MatFile, MatValue};
use crate::transmit::TransmitWave;

/// Largest residual, in sampling periods, between a file's delays and the
/// fitted wave's delay law: a tenth of a sample shifts an echo by far less
/// than the beamformer's interpolation error.
pub(super) const FIT_TOLERANCE_SAMPLES: f64 = 0.1;

/// Each transmit's wave, the file-clock time at which it passes the probe-frame
/// origin (`t0_s = t0 − crossing`), and, when the waves were fitted to the
/// delays, the fit's record for `source.transmit_fit`.
pub(super) struct Waves {
    pub waves: Vec<TransmitWave<f64>>,
    pub crossing_s: Vec<f64>,
    pub fit: Option<Value>,
}

impl Waves {
    /// Plane waves at `angles` (rad), given, not fitted: no fit record.
    fn plane(angles: &[f64], crossing_s: Vec<f64>) -> Self {
        Self {
            waves: angles
                .iter()
                .map(|&angle_rad| TransmitWave::PlaneWave { angle_rad })
                .collect(),
            crossing_s,
            fit: None,
        }
    }
}

/// The waves of `n_tx` transmits fired by `array` (module documentation).
/// `angles` are the file's or the user's (`None` when neither gives them; then
/// the delays must).
#[allow(clippy::too_many_arguments)]
pub(super) fn transmit_waves(
    delays: Option<(&str, &MatValue)>,
    angles: Option<&[f64]>,
    n_tx: usize,
    array: &ArrayGeometry<f64>,
    c: f64,
    fc: f64,
    fs: f64,
    rec: &mut Record,
) -> Result<Waves, String> {
    let n_el = array.n_elements;
    let rows = match delays {
        Some((name, value)) => {
            let (dims, re) = numeric(name, value)?;
            // All zero on a flat array: the 0° plane wave's or unset, the
            // angles decide; on a convex one, a wave from the arc's centre.
            if re.iter().all(|&d| d == 0.0) && array.kind.is_flat() {
                None
            } else {
                Some((name, delay_rows(name, dims, re, n_el, n_tx)?))
            }
        }
        None => None,
    };
    let linear = |rows: &[Vec<f64>]| {
        let x: Vec<f64> = array.elements().iter().map(|e| e.centre_m[0]).collect();
        rows.iter().all(|d| {
            let span = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            fit_line(&x, d).2 <= 1e-3 * span
        })
    };
    if let Some(angles) = angles {
        let plane_only = rows.as_ref().is_none_or(|(_, r)| linear(r));
        if array.kind.is_flat() && plane_only {
            let crossing_s =
                plane_centre_crossing_times(delays, angles, n_el, array.pitch_m, c, fc, rec)?;
            return Ok(Waves::plane(angles, crossing_s));
        }
    }
    let Some((name, rows)) = rows else {
        let Some(angles) = angles else {
            return Err(format!(
                "{n_tx} transmits but the file gives neither transmit angles nor transmit delays; pass --angles-deg"
            ));
        };
        // A convex array (flat ones returned above): plane waves, the first
        // element to fire at 0 on the file's clock.
        rec.assume(
            "transmit_delays",
            "no transmit delays in the file: plane waves, the first element fires at 0".into(),
        );
        let els = array.elements();
        let crossing_s = angles
            .iter()
            .map(|&angle_rad| {
                let w = TransmitWave::PlaneWave { angle_rad };
                -els.iter()
                    .map(|e| w.element_delay_s(e.centre_m, c))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        return Ok(Waves::plane(angles, crossing_s));
    };
    fitted_waves(name, &rows, angles, array, c, fc, fs, rec)
}

/// Each transmit's wave fitted to its row of delays (the fit path of
/// [`transmit_waves`]).
#[allow(clippy::too_many_arguments)]
fn fitted_waves(
    name: &str,
    rows: &[Vec<f64>],
    angles: Option<&[f64]>,
    array: &ArrayGeometry<f64>,
    c: f64,
    fc: f64,
    fs: f64,
    rec: &mut Record,
) -> Result<Waves, String> {
    // Seconds if every delay is under a millisecond (an aperture is crossed in
    // tens of microseconds), else wavelengths at fc.
    let largest = rows.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let (to_s, unit) = if largest < 1e-3 {
        (1.0, "seconds")
    } else {
        (1.0 / fc, "wavelengths")
    };
    let els = array.elements();
    if els.len() < 3 {
        return Err(format!(
            "`{name}`: {} element(s) are too few to tell the transmitted wave from its delays (a plane wave needs 3, a circular one 4); pass --angles-deg for plane waves",
            els.len()
        ));
    }
    let tolerance_s = FIT_TOLERANCE_SAMPLES / fs;
    let mut out = Waves {
        waves: Vec::with_capacity(rows.len()),
        crossing_s: Vec::with_capacity(rows.len()),
        fit: None,
    };
    let mut records = Vec::with_capacity(rows.len());
    let mut ignored_angles = false;
    for (k, row) in rows.iter().enumerate() {
        let d: Vec<f64> = row.iter().map(|v| v * to_s).collect();
        let f = wave_fit::fit_wave(&els, &d, c, tolerance_s).map_err(|e| {
            let show = |r: Option<f64>| match r {
                Some(r) => format!("{:.3} samples", r * fs),
                None => "no fit".into(),
            };
            format!(
                "`{name}` (in {unit}) for transmit {k} fits no transmit model within {FIT_TOLERANCE_SAMPLES} sample: largest residual of a plane wave {}, of a circular wave (virtual source or focus) {}",
                show(e.plane_s),
                show(e.circular_s)
            )
        })?;
        let mut r = json!({
            "transmit": k,
            "max_residual_s": f.max_residual_s,
            "max_residual_samples": f.max_residual_s * fs,
        });
        match f.wave {
            TransmitWave::PlaneWave { angle_rad } => {
                if let Some(&given) = angles.and_then(|a| a.get(k)) {
                    if (angle_rad - given).abs() > ANGLE_TOLERANCE_RAD {
                        return Err(format!(
                            "`{name}` for transmit {k} is a plane wave steered {:.3}°, but the transmit's angle is {:.3}°",
                            angle_rad.to_degrees(),
                            given.to_degrees()
                        ));
                    }
                }
                r["kind"] = "plane_wave".into();
                r["angle_rad"] = angle_rad.into();
            }
            TransmitWave::Diverging { source_m } => {
                ignored_angles |= angles.is_some();
                r["kind"] = "diverging".into();
                r["virtual_source_m"] = source_m.to_vec().into();
            }
            TransmitWave::Focused { focus_m } => {
                ignored_angles |= angles.is_some();
                r["kind"] = "focused".into();
                r["focus_m"] = focus_m.to_vec().into();
            }
        }
        records.push(r);
        out.waves.push(f.wave);
        out.crossing_s.push(f.offset_s);
    }
    if ignored_angles {
        rec.assumed.push(
            "the file's transmit angles are not used for the diverging and focused transmits (their geometry comes from the delays)".into(),
        );
    }
    rec.used.insert(
        "transmit_delays".into(),
        format!("{name} (in {unit}; each transmit's wave fitted to them, `transmit_fit`)").into(),
    );
    out.fit = Some(json!({
        "model": "d_e = a + τ_e: τ_e the wave's delay law on usray's clock (t = 0 as the wave passes the origin), a the file-clock time of that instant; t0_s = t0 − a",
        "tolerance_samples": FIT_TOLERANCE_SAMPLES,
        "transmits": records,
    }));
    Ok(out)
}

/// Largest difference between a file's transmit angle and the angle of the
/// plane wave fitted to its delays, rad (0.5°).
const ANGLE_TOLERANCE_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// The dims and values of the numeric delays `name`.
fn numeric<'a>(name: &str, value: &'a MatValue) -> Result<(&'a [usize], &'a [f64]), String> {
    match value {
        MatValue::Numeric {
            dims, re, im: None, ..
        } => {
            if let Some(v) = re.iter().find(|v| !v.is_finite()) {
                return Err(format!("`{name}` (transmit delays) holds {v}"));
            }
            Ok((dims, re))
        }
        _ => Err(format!(
            "`{name}` (transmit delays) is not a real numeric array"
        )),
    }
}

/// Verasonics' per-transmit delays: the field `Delay` (any case) of a top-level
/// struct array (`TX(k).Delay`, wavelengths), every element a numeric row of
/// the same length (more than one element), as `(name, [n_transmits × n_elements]
/// matrix)`; `None` if the file has no such struct.
pub(super) fn struct_array_delays(vars: &MatFile) -> Option<(String, MatValue)> {
    vars.iter().find_map(|(name, v)| {
        let MatValue::Struct { fields, elems, .. } = v else {
            return None;
        };
        let f = fields
            .iter()
            .position(|f| f.eq_ignore_ascii_case("delay"))?;
        let rows: Vec<&[f64]> = elems
            .iter()
            .map(|e| match &e[f] {
                MatValue::Numeric { re, im: None, .. } => Some(re.as_slice()),
                _ => None,
            })
            .collect::<Option<_>>()?;
        let n_el = rows.first()?.len();
        if n_el < 2 || rows.iter().any(|r| r.len() != n_el) {
            return None;
        }
        let n_tx = rows.len();
        // Column-major [n_tx × n_el]: element e of transmit k at e·n_tx + k.
        let re = (0..n_el)
            .flat_map(|e| rows.iter().map(move |r| r[e]))
            .collect();
        let value = MatValue::Numeric {
            class: crate::mat::NumericClass::Double,
            dims: vec![n_tx, n_el],
            re,
            im: None,
        };
        Some((format!("{name}(k).{}", fields[f]), value))
    })
}

/// The number of transmits the delays `value` hold for `n_el` elements: the
/// other axis of an `[n_transmits × n_el]` matrix or its transpose.
pub(super) fn transmit_count(value: &MatValue, n_el: usize) -> Option<usize> {
    let MatValue::Numeric { dims, re, .. } = value else {
        return None;
    };
    if re.is_empty() || re.len() % n_el != 0 || dims.iter().filter(|&&d| d > 1).count() > 2 {
        return None;
    }
    Some(re.len() / n_el)
}

/// One row of delays per transmit from the column-major `re` of `dims`: an
/// `[n_tx × n_el]` matrix (PyMUST's `TXdelay`, a row per transmit), else
/// `[n_el × n_tx]` (a column per transmit).
fn delay_rows(
    name: &str,
    dims: &[usize],
    re: &[f64],
    n_el: usize,
    n_tx: usize,
) -> Result<Vec<Vec<f64>>, String> {
    if re.len() != n_el * n_tx {
        return Err(format!(
            "`{name}` holds {} delays; {n_el} elements × {n_tx} transmit(s) need {}",
            re.len(),
            n_el * n_tx
        ));
    }
    let transmits_first = n_tx > 1 && dims.first() == Some(&n_tx) && dims.get(1) == Some(&n_el);
    Ok((0..n_tx)
        .map(|k| {
            (0..n_el)
                .map(|e| {
                    if transmits_first {
                        re[e * n_tx + k]
                    } else {
                        re[k * n_el + e]
                    }
                })
                .collect()
        })
        .collect())
}

/// The time, on the file's transmit clock, at which each transmit's wave passes
/// the array centre (CONTRACT §1's t = 0), seconds.
///
/// From the file's per-element delays when they are present and not all zero:
/// their least-squares line in the element position `x` (a plane wave fires
/// element `x` at `a + x·sin θ / c`) gives `a`, in seconds if the slope is
/// `sin θ / c` or in wavelengths (Verasonics' `TX.Delay`) if it is
/// `sin θ · fc / c` ([`transmit_waves`] sends non-linear profiles to the fit).
/// Otherwise the first element fires at 0 and the centre is crossed
/// `(L/2)·|sin θ| / c` later (PyMUST's `txdelay`). For a flat array whose
/// transmit angles are known.
fn plane_centre_crossing_times(
    delays: Option<(&str, &MatValue)>,
    angles: &[f64],
    n_el: usize,
    pitch_m: f64,
    c: f64,
    fc: f64,
    rec: &mut Record,
) -> Result<Vec<f64>, String> {
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
    let (dims, re) = numeric(name, value)?;
    if re.iter().all(|&d| d == 0.0) {
        if angles.iter().any(|&a| a != 0.0) {
            return Ok(convention(rec, &format!("`{name}` is all zero")));
        }
        rec.used.insert("transmit_delays".into(), name.into());
        return Ok(vec![0.0; angles.len()]);
    }
    let rows = delay_rows(name, dims, re, n_el, angles.len())?;
    let x: Vec<f64> = (0..n_el)
        .map(|e| (e as f64 - (n_el - 1) as f64 / 2.0) * pitch_m)
        .collect();
    let aperture_m = (n_el - 1) as f64 * pitch_m;
    let mut out = Vec::with_capacity(angles.len());
    let mut units = Vec::new();
    for (k, &theta) in angles.iter().enumerate() {
        let d = &rows[k];
        let (a, b, _) = fit_line(&x, d);
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
