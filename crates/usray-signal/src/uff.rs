//! UFF channel data (USTB's ultrasound file format, also PICMUS's): import into
//! CONTRACT §2 channel data and export from it: plane, diverging and focused
//! transmits on a linear (or phased) or a curvilinear (convex) array.
//!
//! Format: USTB's `+uff` classes (`uff.channel_data`, `uff.wave`, `uff.point`,
//! `uff.linear_array`, `uff.curvilinear_array`, `uff.pulse`) as stored in HDF5 by USTB and by `pyuff_ustb`
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
//!   plain `uff.probe` whose `geometry` is such an array; or
//!   `uff.curvilinear_array` (`radius` too), a `convex` probe. `geometry` is
//!   MATLAB `[element, 7]` (HDF5 `[7, element]`): x, y, z, azimuth, elevation,
//!   width, height. A linear array's elements must lie on `z = 0` at
//!   `x = (i - (N-1)/2)·pitch`; a curvilinear array's where USTB puts them, the
//!   arc's apex at the origin, which is `s = R − h` above usray's origin (the
//!   chord through the end elements, CONTRACT §1): element positions, wave
//!   sources and clocks are moved by `s` on import and export (`curvilinear`).
//!   A flat array whose pitch is at most 0.6 wavelength is imported as `phased`
//!   (`crate::import::PHASED_PITCH_WAVELENGTHS`), else `linear`.
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
//! `t0_s = initial_time + sequence(n).delay` (plus, for a curvilinear array, the
//! usray time at which wave `n` passes USTB's origin). Import sets the global
//! `t0_s` to that when every wave has the same value, else `initial_time` with a
//! `t0_s` on each transmit; export writes `initial_time = t0_s` and
//! `delay = t0_for(n) - t0_s` (minus that passing time).
//!
//! Not supported, each refused naming it: IQ data (`modulation_frequency` ≠ 0, or
//! complex `data`), other probes (matrix arrays), photoacoustic waves, elevated
//! waves, a spherical wave's source on `z = 0` or (curvilinear) between the
//! apex and the chord, several `uff.channel_data` objects in one file.

mod curvilinear;
mod read;
mod write;

use std::path::Path;

use crate::channels::ChannelData;
use crate::error::{Result, SignalError};
use crate::h5::create_atomic;
use crate::import::{validated, ImportOptions};
use read::read_channel_data;
use write::{frame_grid, write_channel_data};

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

/// Convert the channel data of a UFF file into CONTRACT §2 channel data (see the [module documentation](self) for the mapping).
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
/// `uff.linear_array` probe (linear and phased) or a `uff.curvilinear_array`
/// (convex), a `uff.pulse` holding the centre frequency and one `uff.wave` per
/// transmit, plane or spherical (per frame's transmit for frame-tagged data,
/// whose frames must then repeat one sequence of waves and times).
/// Samples are written as `single`, the other numbers as `double`.
///
/// # Errors
/// Channel data that fail [`ChannelData::validate`] or whose frames do not form
/// a regular grid; a write that fails (the error names `path`).
pub fn export_uff(path: impl AsRef<Path>, ch: &ChannelData) -> Result<()> {
    let path = path.as_ref();
    ch.validate().map_err(SignalError::Invalid)?;
    let grid = frame_grid(&ch.meta).map_err(|w| {
        SignalError::Invalid(format!("{}: cannot be written as UFF: {w}", path.display()))
    })?;
    create_atomic(path, |file| write_channel_data(file, ch, &grid))
}
