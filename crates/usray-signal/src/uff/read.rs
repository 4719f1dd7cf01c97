//! Reading a UFF `uff.channel_data` into CONTRACT §2 channel data (the parent
//! module's documentation states what is read and how).

use std::path::Path;

use hdf5::{Group, LocationType};

use super::curvilinear::{clock_shift_s, frame_shift_m, shifted, ustb_element};
use super::{
    limits, CHANNEL_DATA_CLASS, GEOMETRY_ROWS, GEOMETRY_TOLERANCE_PITCHES, WAVEFRONT_PLANE,
    WAVEFRONT_SPHERICAL,
};
use crate::array::{ArrayGeometry, ArrayKind, RADIUS_KEY};
use crate::channels::{
    ChannelData, ChannelMeta, ProbeMeta, TransmitMeta, CHANNELS_FORMAT, FRAME_KEY,
};
use crate::h5::{element_count, read_f64, string_attr, R};
use crate::import::{flat_kind, kind_name, ImportOptions};
use crate::transmit::TransmitWave;

pub(super) fn read_channel_data(path: &Path, options: &ImportOptions) -> R<ChannelData> {
    let file =
        hdf5::File::open(path).map_err(|e| format!("not a readable HDF5 (UFF) file: {e}"))?;
    let name = channel_data_name(&file)?;
    let cd = file.group(&name).map_err(|e| format!("`/{name}`: {e}"))?;
    let at = format!("/{name}");
    let fs = required(&cd, "sampling_frequency", &at)?;
    let initial_time = required(&cd, "initial_time", &at)?;
    let c = required(&cd, "sound_speed", &at)?;
    let modulation = scalar(&cd, "modulation_frequency", &at)?.unwrap_or(0.0);
    if modulation != 0.0 {
        return Err(format!(
            "`{at}/modulation_frequency` = {modulation} Hz: IQ (demodulated) channel data are not supported, only RF"
        ));
    }
    let probe = read_probe(&cd, &at)?;
    let waves = read_waves(&cd, &at)?;
    let (n_frames, samples, n_samples) = read_samples(&cd, &at, probe.n_elements, waves.len())?;
    let fc = match options.center_frequency_hz {
        Some(f) => f,
        None => {
            let pulse = cd.group("pulse").map_err(|_| {
                format!("`{at}/pulse` (with the centre frequency) is missing; pass it (`usray import --fc HZ`, or ImportOptions::center_frequency_hz)")
            })?;
            required(&pulse, "center_frequency", &format!("{at}/pulse"))?
        }
    };
    // A curvilinear array: sources and clocks from USTB's frame (apex at the
    // origin) into usray's (chord at z = 0), `curvilinear`.
    let pitch_m = options.pitch_m.unwrap_or(probe.pitch_m);
    let array = ArrayGeometry {
        kind: if probe.radius_m.is_some() {
            ArrayKind::Convex
        } else {
            ArrayKind::Linear
        },
        n_elements: probe.n_elements,
        pitch_m,
        element_width_m: probe.element_width_m,
        radius_m: probe.radius_m.unwrap_or(f64::INFINITY),
    };
    let shift_m = frame_shift_m(&array);
    let waves: Vec<(TransmitWave<f64>, f64)> = waves
        .iter()
        .map(|w| {
            if shift_m == 0.0 {
                (w.wave, initial_time + w.delay_s)
            } else {
                let wave = shifted(w.wave, shift_m);
                (
                    wave,
                    initial_time + w.delay_s + clock_shift_s(&wave, shift_m, c),
                )
            }
        })
        .collect();
    if let Some((i, _)) = waves
        .iter()
        .enumerate()
        .find(|(_, (w, _))| matches!(w, TransmitWave::Diverging { source_m } if source_m[1] >= 0.0))
    {
        return Err(format!(
            "`{at}/sequence` wave {}: its source lies behind USTB's origin but not behind the chord through the end elements (usray's z = 0), so it is neither a virtual source behind the array nor a focus in front of it",
            i + 1
        ));
    }
    let same_delay = waves.iter().all(|w| w.1 == waves[0].1);
    let t0_s = if same_delay { waves[0].1 } else { initial_time };
    let tagged = n_frames.is_some();
    let transmits = (0..n_frames.unwrap_or(1))
        .flat_map(|frame| {
            waves.iter().map(move |&(wave, t0_k)| {
                let mut extra = serde_json::Map::new();
                if tagged {
                    extra.insert(FRAME_KEY.into(), frame.into());
                }
                let (kind, angle_rad) = wave.to_meta_fields(&mut extra);
                TransmitMeta {
                    kind: kind.into(),
                    angle_rad,
                    t0_s: (!same_delay).then_some(t0_k),
                    extra,
                }
            })
        })
        .collect();
    let (kind, kind_note) = match probe.radius_m {
        Some(_) => (ArrayKind::Convex, None),
        None => flat_kind(pitch_m, c, fc),
    };
    let mut extra = serde_json::Map::new();
    extra.insert(
        "source".into(),
        serde_json::json!({
            "file": path.file_name().map(|f| f.to_string_lossy().into_owned()),
            "layout": format!("UFF {CHANNEL_DATA_CLASS} `{at}` (RF, plane or spherical waves, {} array)", if shift_m == 0.0 { "linear" } else { "curvilinear" }),
            "clock": if shift_m == 0.0 {
                "t0 = initial_time + sequence(n).delay (USTB: t = 0 when the wave passes the origin, the array centre)".to_string()
            } else {
                format!("t0 = initial_time + sequence(n).delay + t_n((0, s)): USTB's origin is the arc's apex, usray's the chord through the end elements, s = R − h = {shift_m:e} m below it; sources moved by s in depth")
            },
            "assumed": kind_note.into_iter().collect::<Vec<_>>(),
            "overrides": options.overrides(),
        }),
    );
    Ok(ChannelData {
        meta: ChannelMeta {
            format: CHANNELS_FORMAT.into(),
            sampling_frequency_hz: fs,
            t0_s,
            sound_speed_m_s: c,
            center_frequency_hz: fc,
            probe: ProbeMeta {
                kind: kind_name(kind).into(),
                n_elements: probe.n_elements,
                pitch_m,
                element_width_m: probe.element_width_m,
                extra: probe
                    .radius_m
                    .map(|r| (RADIUS_KEY.to_string(), r.into()))
                    .into_iter()
                    .collect(),
            },
            transmits,
            extra,
        },
        n_samples,
        samples,
    })
}

/// The one top-level group of class `uff.channel_data`.
fn channel_data_name(file: &hdf5::File) -> R<String> {
    let members = file
        .member_names()
        .map_err(|e| format!("cannot list the file's objects: {e}"))?;
    let classes: Vec<(String, Option<String>)> = members
        .into_iter()
        .map(|m| {
            let class = file.group(&m).ok().and_then(|g| string_attr(&g, "class"));
            (m, class)
        })
        .collect();
    let found: Vec<&String> = classes
        .iter()
        .filter(|(_, c)| c.as_deref() == Some(CHANNEL_DATA_CLASS))
        .map(|(m, _)| m)
        .collect();
    match found.as_slice() {
        [one] => Ok((*one).clone()),
        [] => Err(format!(
            "no {CHANNEL_DATA_CLASS} object at the top level; the file holds {:?}",
            classes
                .iter()
                .map(|(m, c)| format!("{m} ({})", c.as_deref().unwrap_or("no class")))
                .collect::<Vec<_>>()
        )),
        many => Err(format!(
            "{} {CHANNEL_DATA_CLASS} objects ({many:?}); only a file with one can be imported",
            many.len()
        )),
    }
}

/// The number `field` of the object `g` (at `at`), `None` when absent.
fn scalar(g: &Group, field: &str, at: &str) -> R<Option<f64>> {
    if !g.link_exists(field) {
        return Ok(None);
    }
    let what = format!("`{at}/{field}`");
    let ds = match g.loc_type_by_name(field) {
        Ok(LocationType::Dataset) => g.dataset(field).map_err(|e| format!("{what}: {e}"))?,
        _ => {
            return Err(format!(
                "{what} is not a real number (complex or an object)"
            ))
        }
    };
    if element_count(&ds.shape(), &what)? != 1 {
        return Err(format!(
            "{what} has shape {:?}; one number expected",
            ds.shape()
        ));
    }
    let v = read_f64(&ds, &what)?[0];
    if v.is_nan() {
        return Err(format!("{what} is NaN"));
    }
    Ok(Some(v))
}

/// The number `field` of `g`, which must be there.
fn required(g: &Group, field: &str, at: &str) -> R<f64> {
    scalar(g, field, at)?.ok_or_else(|| format!("`{at}/{field}` is missing"))
}

/// The object (group) `name` of `g`.
fn object(g: &Group, name: &str, at: &str) -> R<Group> {
    match g.loc_type_by_name(name) {
        Ok(LocationType::Group) => g.group(name).map_err(|e| format!("`{at}/{name}`: {e}")),
        Ok(_) => Err(format!("`{at}/{name}` is not a UFF object (group)")),
        Err(_) => Err(format!("`{at}/{name}` is missing")),
    }
}

/// The array of a UFF probe: linear, or curvilinear (`radius_m`).
struct UffArray {
    n_elements: usize,
    pitch_m: f64,
    element_width_m: f64,
    radius_m: Option<f64>,
}

fn read_probe(cd: &Group, at: &str) -> R<UffArray> {
    let probe = object(cd, "probe", at)?;
    let at = format!("{at}/probe");
    let class = string_attr(&probe, "class").unwrap_or_default();
    let curvilinear = class == "uff.curvilinear_array";
    if !(curvilinear || matches!(class.as_str(), "uff.linear_array" | "uff.probe")) {
        return Err(format!(
            "`{at}` is a {class:?}; only linear arrays (uff.linear_array, or uff.probe with a linear geometry) and curvilinear ones (uff.curvilinear_array) are supported"
        ));
    }
    let radius_m = if curvilinear {
        let r = required(&probe, "radius", &at)?;
        if !(r.is_finite() && r > 0.0) {
            return Err(format!("`{at}/radius` = {r} is not a radius of curvature"));
        }
        Some(r)
    } else {
        None
    };
    let geometry = match probe.dataset("geometry") {
        Ok(ds) => {
            let what = format!("`{at}/geometry`");
            match ds.shape().as_slice() {
                [GEOMETRY_ROWS, n] if *n > 0 && *n <= crate::channels::limits::MAX_ELEMENTS => {}
                s => {
                    return Err(format!(
                        "{what} has shape {s:?}; [{GEOMETRY_ROWS}, elements] expected (MATLAB [elements, 7])"
                    ))
                }
            }
            Some(read_f64(&ds, &what)?)
        }
        Err(_) => None,
    };
    let geometry_n = geometry.as_ref().map(|g| g.len() / GEOMETRY_ROWS);
    let row = |r: usize| {
        geometry.as_deref().map(|g| {
            let n = g.len() / GEOMETRY_ROWS;
            &g[r * n..(r + 1) * n]
        })
    };
    let n = match (scalar(&probe, "N", &at)?, geometry_n) {
        (Some(n), Some(g)) if n != g as f64 => {
            return Err(format!(
                "`{at}/N` = {n} but `{at}/geometry` has {g} elements"
            ))
        }
        (Some(n), _)
            if n >= 1.0
                && n.fract() == 0.0
                && n <= crate::channels::limits::MAX_ELEMENTS as f64 =>
        {
            n as usize
        }
        (Some(n), _) => return Err(format!("`{at}/N` = {n} is not a number of elements")),
        (None, Some(g)) => g,
        (None, None) => return Err(format!("`{at}` has neither `N` nor `geometry`")),
    };
    let x = row(0);
    let pitch = match (scalar(&probe, "pitch", &at)?, x) {
        (Some(p), _) => p,
        (None, Some(x)) if n > 1 => (x[n - 1] - x[0]) / (n - 1) as f64,
        _ => {
            return Err(format!(
                "`{at}` has no `pitch` and no geometry to take it from"
            ))
        }
    };
    let width = match (scalar(&probe, "element_width", &at)?, row(5)) {
        (Some(w), _) => w,
        (None, Some(w)) => w[0],
        (None, None) => pitch,
    };
    match (&geometry, radius_m) {
        (Some(g), None) => check_linear(g, n, pitch, &at)?,
        (Some(g), Some(r)) => check_curvilinear(g, n, pitch, width, r, &at)?,
        (None, _) => {}
    }
    Ok(UffArray {
        n_elements: n,
        pitch_m: pitch,
        element_width_m: width,
        radius_m,
    })
}

/// The elements of `geometry` (`[7, n]`, C order) lie where USTB's
/// `uff.curvilinear_array` of radius `r` and this pitch puts them
/// ([`super::curvilinear`]: apex at the origin), facing outwards.
fn check_curvilinear(
    geometry: &[f64],
    n: usize,
    pitch: f64,
    width: f64,
    r: f64,
    at: &str,
) -> R<()> {
    let array = ArrayGeometry {
        kind: ArrayKind::Convex,
        n_elements: n,
        pitch_m: pitch,
        element_width_m: width,
        radius_m: r,
    };
    if r < (n - 1) as f64 * pitch / 2.0 {
        return Err(format!(
            "`{at}/radius` = {r} m is below half the aperture ((N − 1)·pitch/2): the arc cannot hold the elements"
        ));
    }
    let tol = GEOMETRY_TOLERANCE_PITCHES * pitch.abs();
    for i in 0..n {
        let v = |row: usize| geometry[row * n + i];
        let (x, z, azimuth) = ustb_element(&array, i);
        if (v(0) - x).abs() > tol
            || v(1).abs() > tol
            || (v(2) - z).abs() > tol
            || (v(3) - azimuth).abs() > tol / r
            || v(4) != 0.0
        {
            return Err(format!(
                "`{at}/geometry`: element {} lies at (x, y, z) = ({:e}, {:e}, {:e}) m facing azimuth {} rad, not at ({x:e}, 0, {z:e}) m facing {azimuth} rad where a curvilinear array of radius {r:e} m and pitch {pitch:e} m puts it (USTB: apex at the origin)",
                i + 1,
                v(0),
                v(1),
                v(2),
                v(3)
            ));
        }
    }
    Ok(())
}

/// The elements of `geometry` (`[7, n]`, C order) lie on `z = 0`, facing `z`,
/// at `x = (i - (n-1)/2)·pitch`: a linear array centred on the origin.
fn check_linear(geometry: &[f64], n: usize, pitch: f64, at: &str) -> R<()> {
    let tol = GEOMETRY_TOLERANCE_PITCHES * pitch.abs();
    for i in 0..n {
        let v = |r: usize| geometry[r * n + i];
        let x_expected = (i as f64 - (n - 1) as f64 / 2.0) * pitch;
        if (v(0) - x_expected).abs() > tol {
            return Err(format!(
                "`{at}/geometry`: element {} lies at x = {:e} m, not at {x_expected:e} m: usray needs a linear array of pitch {pitch:e} m centred on x = 0 (CONTRACT §1: t = 0 at the array centre)",
                i + 1,
                v(0)
            ));
        }
        if v(1).abs() > tol || v(2).abs() > tol || v(3) != 0.0 || v(4) != 0.0 {
            return Err(format!(
                "`{at}/geometry`: element {} is at y = {:e} m, z = {:e} m, turned by ({}, {}) rad; usray needs every element on z = 0 facing z",
                i + 1,
                v(1),
                v(2),
                v(3),
                v(4)
            ));
        }
    }
    Ok(())
}

/// One transmit of the sequence and its `delay` (USTB: sample 0 of this wave
/// is at `initial_time + delay` after the wave passed the origin).
struct Wave {
    wave: TransmitWave<f64>,
    delay_s: f64,
}

fn read_waves(cd: &Group, at: &str) -> R<Vec<Wave>> {
    let sequence = object(cd, "sequence", at)?;
    let at = format!("{at}/sequence");
    // One wave is stored as the object itself, several as members NAME_0001, ….
    let waves: Vec<(String, Group)> = if sequence.link_exists("source") {
        vec![(at.clone(), sequence)]
    } else {
        let mut names = sequence
            .member_names()
            .map_err(|e| format!("`{at}`: {e}"))?;
        names.sort_by(|a, b| (a.len(), a).cmp(&(b.len(), b)));
        names
            .into_iter()
            .map(|m| Ok((format!("{at}/{m}"), object(&sequence, &m, &at)?)))
            .collect::<R<_>>()?
    };
    if waves.is_empty() {
        return Err(format!("`{at}` holds no waves"));
    }
    waves.iter().map(|(at, w)| read_wave(w, at)).collect()
}

fn read_wave(wave: &Group, at: &str) -> R<Wave> {
    let source = object(wave, "source", at)?;
    let source_at = format!("{at}/source");
    let azimuth = scalar(&source, "azimuth", &source_at)?.unwrap_or(0.0);
    let elevation = scalar(&source, "elevation", &source_at)?.unwrap_or(0.0);
    let distance = scalar(&source, "distance", &source_at)?.unwrap_or(0.0);
    let wavefront = scalar(wave, "wavefront", at)?;
    let (plane, spherical) = match wavefront {
        Some(w) => (w == WAVEFRONT_PLANE, w == WAVEFRONT_SPHERICAL),
        None => (distance.is_infinite(), false),
    };
    if elevation != 0.0 {
        return Err(format!(
            "`{source_at}/elevation` = {elevation} rad; only waves steered in azimuth are supported"
        ));
    }
    let delay_s = scalar(wave, "delay", at)?.unwrap_or(0.0);
    if plane {
        return Ok(Wave {
            wave: TransmitWave::PlaneWave { angle_rad: azimuth },
            delay_s,
        });
    }
    if !(spherical && distance.is_finite()) {
        return Err(format!(
            "`{at}` is not a plane wave, nor a spherical wave from a finite source (wavefront {wavefront:?}, source distance {distance} m)"
        ));
    }
    let p = [distance * azimuth.sin(), distance * azimuth.cos()];
    let wave = if p[1] < 0.0 {
        TransmitWave::Diverging { source_m: p }
    } else if p[1] > 0.0 {
        TransmitWave::Focused { focus_m: p }
    } else {
        return Err(format!(
            "`{source_at}` lies on the array plane (z = 0, x = {} m): neither a virtual source behind the array nor a focus in front of it",
            p[0]
        ));
    };
    Ok(Wave { wave, delay_s })
}

/// The samples of `data`: `(frames if 4-D, samples in [frame, wave, element,
/// sample] C order, samples per record)`.
fn read_samples(
    cd: &Group,
    at: &str,
    n_elements: usize,
    n_waves: usize,
) -> R<(Option<usize>, Vec<f64>, usize)> {
    let what = format!("`{at}/data`");
    let ds = match cd.loc_type_by_name("data") {
        Ok(LocationType::Dataset) => cd.dataset("data").map_err(|e| format!("{what}: {e}"))?,
        Ok(_) => {
            return Err(format!(
                "{what} is complex (IQ); only real RF channel data are supported"
            ))
        }
        Err(_) => return Err(format!("{what} is missing")),
    };
    let shape = ds.shape();
    let (frames, waves, elements, samples) = match *shape.as_slice() {
        [e, s] => (None, 1, e, s),
        [w, e, s] => (None, w, e, s),
        [f, w, e, s] => (Some(f), w, e, s),
        _ => {
            return Err(format!(
                "{what} has HDF5 shape {shape:?}; MATLAB [time, channel(, wave(, frame))] expected"
            ))
        }
    };
    if elements != n_elements || waves != n_waves {
        return Err(format!(
            "{what} has {elements} channels × {waves} waves (HDF5 shape {shape:?}) but the probe has {n_elements} elements and the sequence {n_waves} waves"
        ));
    }
    let count = element_count(&shape, &what)?;
    if count > limits::MAX_SAMPLES {
        return Err(format!(
            "{what} holds {count} samples, past the limit of {} (usray_signal::uff::limits::MAX_SAMPLES)",
            limits::MAX_SAMPLES
        ));
    }
    Ok((frames, read_f64(&ds, &what)?, samples))
}
