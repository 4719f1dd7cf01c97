//! Writing CONTRACT §2 channel data as a UFF `uff.channel_data` (plane,
//! diverging and focused waves on a flat or convex array; the parent module's
//! documentation states the layout).

use hdf5::types::VarLenUnicode;
use hdf5::Group;

use super::curvilinear::{clock_shift_s, frame_shift_m, shifted, ustb_element};
use super::{CHANNEL_DATA_CLASS, GEOMETRY_ROWS, WAVEFRONT_PLANE, WAVEFRONT_SPHERICAL};
use crate::array::ArrayGeometry;
use crate::channels::{ChannelData, ChannelMeta, FRAME_KEY};
use crate::transmit::TransmitWave;

/// How channel data fill UFF's `[time, channel, wave, frame]`.
pub(super) struct FrameGrid {
    /// Frames, when the transmits carry `frame` tags (then `data` is 4-D).
    frames: Option<usize>,
    /// Waves per frame.
    waves: usize,
}

/// The frame grid of `meta` (validated): without `frame` tags one frame of
/// every transmit; with them, frames `0, 1, …` in order, each repeating frame
/// 0's waves and times of sample 0.
pub(super) fn frame_grid(meta: &ChannelMeta) -> Result<FrameGrid, String> {
    let wave = |i: usize| TransmitWave::from_meta(i, &meta.transmits[i]);
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
        let same = g
            .iter()
            .enumerate()
            .all(|(w, &i)| wave(i).ok() == wave(w).ok() && meta.t0_for(i) == meta.t0_for(w));
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

pub(super) fn write_channel_data(
    file: &hdf5::File,
    ch: &ChannelData,
    grid: &FrameGrid,
) -> hdf5::Result<()> {
    let m = &ch.meta;
    let cd = new_object(file, "channel_data", CHANNEL_DATA_CLASS)?;
    new_number(&cd, "sampling_frequency", m.sampling_frequency_hz)?;
    new_number(&cd, "initial_time", m.t0_s)?;
    new_number(&cd, "sound_speed", m.sound_speed_m_s)?;
    new_number(&cd, "modulation_frequency", 0.0)?;

    let p = &m.probe;
    let array = ArrayGeometry::from_meta(p).map_err(hdf5::Error::from)?;
    let shift_m = frame_shift_m(&array);
    let probe = if array.kind.is_flat() {
        new_object(&cd, "probe", "uff.linear_array")?
    } else {
        let probe = new_object(&cd, "probe", "uff.curvilinear_array")?;
        new_number(&probe, "radius", array.radius_m)?;
        probe
    };
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
        if array.kind.is_flat() {
            geometry[i] = (i as f64 - (n - 1) as f64 / 2.0) * p.pitch_m;
        } else {
            let (x, z, azimuth) = ustb_element(&array, i);
            geometry[i] = x;
            geometry[2 * n + i] = z;
            geometry[3 * n + i] = azimuth;
        }
        geometry[5 * n + i] = p.element_width_m;
        geometry[6 * n + i] = height;
    }
    new_array(&probe, "geometry", &[GEOMETRY_ROWS, n], &geometry)?;
    new_point(&probe, "origin", 0.0, 0.0)?;

    let pulse = new_object(&cd, "pulse", "uff.pulse")?;
    new_number(&pulse, "center_frequency", m.center_frequency_hz)?;

    // Each wave in USTB's frame (`super::curvilinear`): its source moved up
    // by the frame shift, its clock started as it passes USTB's origin.
    let wave = |parent: &Group, name: &str, tx: usize| -> hdf5::Result<()> {
        let tw = TransmitWave::from_meta(tx, &m.transmits[tx]).map_err(hdf5::Error::from)?;
        let w = new_object(parent, name, "uff.wave")?;
        let (wavefront, distance, azimuth) = match shifted(tw, -shift_m) {
            TransmitWave::PlaneWave { angle_rad } => (WAVEFRONT_PLANE, f64::INFINITY, angle_rad),
            TransmitWave::Diverging { source_m: [x, z] }
            | TransmitWave::Focused { focus_m: [x, z] } => {
                (WAVEFRONT_SPHERICAL, x.hypot(z), x.atan2(z))
            }
        };
        let ds = w.new_dataset::<i32>().shape([1, 1]).create("wavefront")?;
        ds.write_raw(&[wavefront as i32])?;
        set_string(&ds, "class", "uff.wavefront")?;
        set_string(&ds, "name", "wavefront")?;
        new_point(&w, "source", distance, azimuth)?;
        new_point(&w, "origin", 0.0, 0.0)?;
        let delay = if shift_m == 0.0 {
            m.t0_for(tx) - m.t0_s
        } else {
            m.t0_for(tx) - clock_shift_s(&tw, shift_m, m.sound_speed_m_s) - m.t0_s
        };
        new_number(&w, "delay", delay)?;
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
