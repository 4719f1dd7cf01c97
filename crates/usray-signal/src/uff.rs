//! UFF channel data (USTB's ultrasound file format, also PICMUS's): import into
//! CONTRACT §2 channel data and export from it, for plane-wave transmits on a
//! linear array (import also reads spherical waves: diverging and focused).
//!
//! Format: USTB's `+uff` classes (`uff.channel_data`, `uff.wave`, `uff.point`,
//! `uff.linear_array`, `uff.pulse`) as stored in HDF5 by USTB and by `pyuff_ustb`
//! (3.0, the Python reader and writer USTB publishes): every object is a group
//! with the attributes `class` (`"uff.channel_data"`, …), `name`, `array` and
//! `size`; its properties are members — numbers as datasets with MATLAB's
//! reversed dimensions (attributes `class`, `complex`, `imaginary`), objects as
//! groups, an array of objects as a group (`array` = 1, `size` = `[1, n]`) of
//! members `NAME_0001`, `NAME_0002`, …, an enumeration (`uff.wavefront`: plane 0,
//! spherical 1, photoacoustic 2) as an integer dataset.
//!
//! - `channel_data.data` is MATLAB `[time, channel, wave, frame]`, i.e. HDF5 shape
//!   `[frame, wave, channel, time]` (trailing MATLAB singletons dropped), so one
//!   frame's C order is usray's `[transmit, element, sample]`; the frames of 4-D
//!   data become transmits tagged `"frame": k` (CONTRACT §2's extension), in
//!   frame-major order.
//! - Probe: `uff.linear_array` (`N`, `pitch`, `element_width`, `geometry`), or a
//!   plain `uff.probe` whose `geometry` is such an array. `geometry` is MATLAB
//!   `[element, 7]` (HDF5 `[7, element]`): x, y, z, azimuth, elevation, width,
//!   height. The elements must lie on `z = 0` at `x = (i - (N-1)/2)·pitch`.
//! - Waves: `wavefront` plane (0), or — in files without `wavefront` — a `source`
//!   at infinite `distance`; the steering angle is `source.azimuth`, the
//!   elevation must be 0. Import also reads `wavefront` spherical (1) with a
//!   finite `source` (`uff.point`: `(x, z) = distance·(sin azimuth, cos azimuth)`
//!   at elevation 0): behind the array (`z < 0`) a `diverging` transmit with
//!   that `virtual_source_m`, in front of it a `focused` one with that `focus_m`
//!   (`crate::transmit`; USTB's clock is the same, t = 0 when the wave passes
//!   the origin).
//!
//! **Time origin.** USTB's `uff.wave` documentation: "`delay` defines the time
//! interval between the reference time `t0` and the start of acquisition for this
//! particular wave. We refer to reference time, or time zero, as the moment the
//! wave passes through the origin of coordinates (0, 0, 0)"; `uff.channel_data`:
//! `initial_time` is the "time of the initial sample", and its `time(n_wave)` is
//! `initial_time + (0:N_samples-1)/sampling_frequency + sequence(n_wave).delay`
//! (USTB's `midprocess.das` samples the data at the plane-wave delay
//! `(x sin θ + z cos θ)/c - delay` on the `initial_time` axis). With the array
//! centred on the origin that is CONTRACT §1's clock, so transmit `n` has
//! `t0_s = initial_time + sequence(n).delay`. Import sets the global `t0_s` to
//! that when every wave has the same delay, else `initial_time` with a `t0_s` on
//! each transmit; export writes `initial_time = t0_s` and
//! `delay = t0_for(n) - t0_s`.
//!
//! Not supported, each refused naming it: IQ data (`modulation_frequency` ≠ 0, or
//! complex `data`), other probes (matrix; curvilinear: USTB's
//! `uff.curvilinear_array` puts the arc's apex on the origin where usray puts
//! the chord through the end elements, PyMUST's convention, so its positions
//! and each wave's time origin would need moving by `R − h`), photoacoustic
//! waves, elevated waves, a spherical wave's source on `z = 0`, several
//! `uff.channel_data` objects in one file; export writes plane waves on flat
//! arrays only.

use std::path::Path;

use hdf5::types::VarLenUnicode;
use hdf5::{Group, LocationType};

use crate::channels::{
    ChannelData, ChannelMeta, ProbeMeta, TransmitMeta, CHANNELS_FORMAT, FRAME_KEY,
};
use crate::error::{Result, SignalError};
use crate::h5::{create_atomic, element_count, read_f64, string_attr, R};
use crate::import::{validated, ImportOptions};
use crate::transmit::{TransmitWave, FOCUS_KEY, VIRTUAL_SOURCE_KEY};

/// What a UFF file may make the reader hold, checked before the read allocates.
pub mod limits {
    /// Most channel-data samples read from one file (64 Mi samples, 512 MiB as
    /// `f64`; PICMUS's largest data set holds 29 Mi).
    pub const MAX_SAMPLES: usize = 64 << 20;
}

/// The UFF class of channel data.
const CHANNEL_DATA_CLASS: &str = "uff.channel_data";
/// `uff.wavefront.plane`.
const WAVEFRONT_PLANE: f64 = 0.0;
/// USTB's `uff.wavefront.spherical`.
const WAVEFRONT_SPHERICAL: f64 = 1.0;
/// Rows of a `geometry` (x, y, z, azimuth, elevation, width, height).
const GEOMETRY_ROWS: usize = 7;
/// How far an element may lie from its place on an ideal linear array, in
/// pitches (single precision and rounding in the writer).
const GEOMETRY_TOLERANCE_PITCHES: f64 = 1e-3;

/// Convert the plane-wave channel data of a UFF file into CONTRACT §2 channel
/// data (see the [module documentation](self) for the mapping).
pub fn import_uff(path: impl AsRef<Path>) -> Result<ChannelData> {
    import_uff_with(path, &ImportOptions::default())
}

/// [`import_uff`] with user-supplied values, which win over the file's: the
/// centre frequency (UFF stores it only in the optional `pulse`) and the pitch.
pub fn import_uff_with(path: impl AsRef<Path>, options: &ImportOptions) -> Result<ChannelData> {
    let path = path.as_ref();
    options
        .check()
        .and_then(|()| options.refuse_unused("a UFF file", &["--fc", "--pitch"]))
        .map_err(|w| SignalError::format(path, w))?;
    let data = read_channel_data(path, options).map_err(|w| SignalError::format(path, w))?;
    validated(path, data)
}

/// Write `ch` as a UFF file at `path` (atomically), readable by USTB and
/// `pyuff_ustb`: one `uff.channel_data` named `channel_data` with a
/// `uff.linear_array` probe, a `uff.pulse` holding the centre frequency and one
/// plane `uff.wave` per transmit (per frame's transmit for frame-tagged data,
/// whose frames must then repeat one sequence of angles and times).
/// Samples are written as `single`, the other numbers as `double`.
///
/// # Errors
/// Channel data that fail [`ChannelData::validate`], whose frames do not form a
/// regular grid, whose probe is convex or whose transmits are not all plane
/// waves (a phased probe is written as the linear array it is geometrically);
/// a write that fails (the error names `path`).
pub fn export_uff(path: impl AsRef<Path>, ch: &ChannelData) -> Result<()> {
    let path = path.as_ref();
    ch.validate().map_err(SignalError::Invalid)?;
    let grid = frame_grid(&ch.meta).map_err(|w| {
        SignalError::Invalid(format!("{}: cannot be written as UFF: {w}", path.display()))
    })?;
    create_atomic(path, |file| write_channel_data(file, ch, &grid))
}

// ---------------------------------------------------------------- reading

fn read_channel_data(path: &Path, options: &ImportOptions) -> R<ChannelData> {
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
    let same_delay = waves.iter().all(|w| w.delay_s == waves[0].delay_s);
    let t0_s = if same_delay {
        initial_time + waves[0].delay_s
    } else {
        initial_time
    };
    let tagged = n_frames.is_some();
    let transmits = (0..n_frames.unwrap_or(1))
        .flat_map(|frame| {
            waves.iter().map(move |w| {
                let mut extra = serde_json::Map::new();
                if tagged {
                    extra.insert(FRAME_KEY.into(), frame.into());
                }
                let (kind, angle_rad) = match w.wave {
                    TransmitWave::PlaneWave { angle_rad } => ("plane_wave", angle_rad),
                    TransmitWave::Diverging { source_m } => {
                        extra.insert(VIRTUAL_SOURCE_KEY.into(), source_m.to_vec().into());
                        ("diverging", 0.0)
                    }
                    TransmitWave::Focused { focus_m } => {
                        extra.insert(FOCUS_KEY.into(), focus_m.to_vec().into());
                        ("focused", 0.0)
                    }
                };
                TransmitMeta {
                    kind: kind.into(),
                    angle_rad,
                    t0_s: (!same_delay).then_some(initial_time + w.delay_s),
                    extra,
                }
            })
        })
        .collect();
    let mut extra = serde_json::Map::new();
    extra.insert(
        "source".into(),
        serde_json::json!({
            "file": path.file_name().map(|f| f.to_string_lossy().into_owned()),
            "layout": format!("UFF {CHANNEL_DATA_CLASS} `{at}` (RF, plane or spherical waves, linear array)"),
            "clock": "t0 = initial_time + sequence(n).delay (USTB: t = 0 when the wave passes the origin, the array centre)",
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
                kind: "linear".into(),
                n_elements: probe.n_elements,
                pitch_m: options.pitch_m.unwrap_or(probe.pitch_m),
                element_width_m: probe.element_width_m,
                extra: serde_json::Map::new(),
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

/// The linear array of a UFF probe.
struct LinearArray {
    n_elements: usize,
    pitch_m: f64,
    element_width_m: f64,
}

fn read_probe(cd: &Group, at: &str) -> R<LinearArray> {
    let probe = object(cd, "probe", at)?;
    let at = format!("{at}/probe");
    let class = string_attr(&probe, "class").unwrap_or_default();
    if !matches!(class.as_str(), "uff.linear_array" | "uff.probe") {
        return Err(format!(
            "`{at}` is a {class:?}; only linear arrays (uff.linear_array, or uff.probe with a linear geometry) are supported"
        ));
    }
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
    if let Some(g) = &geometry {
        check_linear(g, n, pitch, &at)?;
    }
    Ok(LinearArray {
        n_elements: n,
        pitch_m: pitch,
        element_width_m: width,
    })
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

// ---------------------------------------------------------------- writing

/// How channel data fill UFF's `[time, channel, wave, frame]`.
struct FrameGrid {
    /// Frames, when the transmits carry `frame` tags (then `data` is 4-D).
    frames: Option<usize>,
    /// Waves per frame.
    waves: usize,
}

/// The frame grid of `meta`: without `frame` tags one frame of every transmit;
/// with them, frames `0, 1, …` in order, each repeating frame 0's angles and
/// times of sample 0.
fn frame_grid(meta: &ChannelMeta) -> std::result::Result<FrameGrid, String> {
    // Only what this writer can say: a flat array (a phased one is written as
    // the linear array it is geometrically) and plane waves.
    if meta.probe.kind == "convex" {
        return Err("`probe.kind` is \"convex\": the UFF writer holds linear arrays only".into());
    }
    if let Some((i, t)) = meta
        .transmits
        .iter()
        .enumerate()
        .find(|(_, t)| t.kind != "plane_wave")
    {
        return Err(format!(
            "transmits[{i}].kind is {:?}: the UFF writer holds plane waves only",
            t.kind
        ));
    }
    let n = meta.transmits.len();
    if !meta
        .transmits
        .iter()
        .any(|t| t.extra.contains_key(FRAME_KEY))
    {
        return Ok(FrameGrid {
            frames: None,
            waves: n,
        });
    }
    let groups = meta.frames()?;
    let waves = groups[0].len();
    for (k, g) in groups.iter().enumerate() {
        let contiguous = g.len() == waves && g.iter().enumerate().all(|(w, &i)| i == k * waves + w);
        let same = g.iter().enumerate().all(|(w, &i)| {
            meta.transmits[i].angle_rad == meta.transmits[w].angle_rad
                && meta.t0_for(i) == meta.t0_for(w)
        });
        if !(contiguous && same) {
            return Err(format!(
                "frame {k} (transmits {g:?}) does not repeat frame 0's {waves} transmits in order: UFF holds one wave sequence for every frame"
            ));
        }
    }
    Ok(FrameGrid {
        frames: Some(groups.len()),
        waves,
    })
}

fn write_channel_data(file: &hdf5::File, ch: &ChannelData, grid: &FrameGrid) -> hdf5::Result<()> {
    let m = &ch.meta;
    let cd = new_object(file, "channel_data", CHANNEL_DATA_CLASS)?;
    new_number(&cd, "sampling_frequency", m.sampling_frequency_hz)?;
    new_number(&cd, "initial_time", m.t0_s)?;
    new_number(&cd, "sound_speed", m.sound_speed_m_s)?;
    new_number(&cd, "modulation_frequency", 0.0)?;

    let p = &m.probe;
    let probe = new_object(&cd, "probe", "uff.linear_array")?;
    new_number(&probe, "N", p.n_elements as f64)?;
    new_number(&probe, "pitch", p.pitch_m)?;
    new_number(&probe, "element_width", p.element_width_m)?;
    // The height is known only from the sidecar's extra key; else USTB's
    // default (`uff.linear_array`: 10 element widths).
    let height = p
        .extra
        .get("elevation_height_m")
        .and_then(|v| v.as_f64())
        .unwrap_or(10.0 * p.element_width_m);
    new_number(&probe, "element_height", height)?;
    let n = p.n_elements;
    let mut geometry = vec![0.0; GEOMETRY_ROWS * n];
    for i in 0..n {
        geometry[i] = (i as f64 - (n - 1) as f64 / 2.0) * p.pitch_m;
        geometry[5 * n + i] = p.element_width_m;
        geometry[6 * n + i] = height;
    }
    new_array(&probe, "geometry", &[GEOMETRY_ROWS, n], &geometry)?;
    new_point(&probe, "origin", 0.0, 0.0)?;

    let pulse = new_object(&cd, "pulse", "uff.pulse")?;
    new_number(&pulse, "center_frequency", m.center_frequency_hz)?;

    let wave = |parent: &Group, name: &str, tx: usize| -> hdf5::Result<()> {
        let w = new_object(parent, name, "uff.wave")?;
        let ds = w.new_dataset::<i32>().shape([1, 1]).create("wavefront")?;
        ds.write_raw(&[WAVEFRONT_PLANE as i32])?;
        set_string(&ds, "class", "uff.wavefront")?;
        set_string(&ds, "name", "wavefront")?;
        new_point(&w, "source", f64::INFINITY, m.transmits[tx].angle_rad)?;
        new_point(&w, "origin", 0.0, 0.0)?;
        new_number(&w, "delay", m.t0_for(tx) - m.t0_s)?;
        new_number(&w, "sound_speed", m.sound_speed_m_s)
    };
    if grid.waves == 1 {
        wave(&cd, "sequence", 0)?;
    } else {
        let sequence = new_objects(&cd, "sequence", "uff.wave", grid.waves)?;
        for tx in 0..grid.waves {
            wave(&sequence, &format!("sequence_{:04}", tx + 1), tx)?;
        }
    }

    let mut shape = vec![grid.waves, n, ch.n_samples];
    if let Some(f) = grid.frames {
        shape.insert(0, f);
    }
    let data = cd.new_dataset::<f32>().shape(shape).create("data")?;
    let samples: Vec<f32> = ch.samples.iter().map(|&v| v as f32).collect();
    data.write_raw(&samples)?;
    number_attrs(&data, "data", "single")
}

/// A new UFF object (group) `name` of class `class`.
fn new_object(parent: &Group, name: &str, class: &str) -> hdf5::Result<Group> {
    new_objects(parent, name, class, 1)
}

/// A new UFF group `name` for `count` objects of class `class` (`array` 1 and
/// `size` `[1, count]` when there are several, to be filled with members
/// `NAME_0001`, …).
fn new_objects(parent: &Group, name: &str, class: &str, count: usize) -> hdf5::Result<Group> {
    let g = parent.create_group(name)?;
    set_string(&g, "class", class)?;
    set_string(&g, "name", name)?;
    set_ints(&g, "array", &[i64::from(count != 1)])?;
    set_ints(&g, "size", &[1, count as i64])?;
    Ok(g)
}

/// A new `uff.point` at `distance` (m) and `azimuth` (rad), elevation 0.
fn new_point(parent: &Group, name: &str, distance: f64, azimuth: f64) -> hdf5::Result<()> {
    let p = new_object(parent, name, "uff.point")?;
    new_number(&p, "distance", distance)?;
    new_number(&p, "azimuth", azimuth)?;
    new_number(&p, "elevation", 0.0)
}

/// A new number (MATLAB 1×1 `double`).
fn new_number(parent: &Group, name: &str, value: f64) -> hdf5::Result<()> {
    new_array(parent, name, &[1, 1], &[value])
}

/// A new real `double` array of HDF5 shape `shape` (MATLAB's reversed).
fn new_array(parent: &Group, name: &str, shape: &[usize], values: &[f64]) -> hdf5::Result<()> {
    let ds = parent.new_dataset::<f64>().shape(shape).create(name)?;
    ds.write_raw(values)?;
    number_attrs(&ds, name, "double")
}

/// The attributes USTB and `pyuff_ustb` give a real numeric dataset.
fn number_attrs(ds: &hdf5::Dataset, name: &str, class: &str) -> hdf5::Result<()> {
    set_string(ds, "class", class)?;
    set_string(ds, "name", name)?;
    set_ints(ds, "complex", &[0])?;
    set_ints(ds, "imaginary", &[0])
}

fn set_string(loc: &hdf5::Location, name: &str, value: &str) -> hdf5::Result<()> {
    let value: VarLenUnicode = value
        .parse()
        .map_err(|e| hdf5::Error::from(format!("attribute {name} = {value:?}: {e}")))?;
    loc.new_attr::<VarLenUnicode>()
        .create(name)?
        .write_scalar(&value)
}

fn set_ints(loc: &hdf5::Location, name: &str, values: &[i64]) -> hdf5::Result<()> {
    loc.new_attr::<i64>()
        .shape(values.len())
        .create(name)?
        .write_raw(values)
}
