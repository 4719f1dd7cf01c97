//! Reference images for a fit (CONTRACT §4 `REF`), on the scene's imaging grid.
//!
//! | file | how it becomes the reference `I_ref` |
//! |---|---|
//! | channel data `.json` (CONTRACT §2, its `.npy` beside it) | beamformed with the scene's `[imaging]` settings ([`usray_signal::BMode`]) |
//! | B-mode `.npy` (`[nz, nx]`, values in `[0, 1]`) | used as is; its shape must equal the scene's grid, else an error |
//! | B-mode `.png` (8- or 16-bit grey or colour, luminance used) + sidecar `.json` with `x_range_m` and `z_range_m` | grey/255; its size **and** ranges must equal the scene's grid (ranges within half a pixel), else an error — no resampling, so no interpolation bias enters the loss |

use crate::OptimError;
use std::path::Path;
use usray_signal::io::read_npy;
use usray_signal::{read_channels, BMode, ChannelData, ChannelMeta};
use usray_transport::Scene;

/// Traces `scene` in 2-D when it leaves `acquisition.dimensions` unset and
/// the measured data at `measured` are channel data that declare a 2-D
/// simulation ([`usray_signal::io::declared_dimensions`]: k-Wave's 2-D solver,
/// PyMUST's `simus`); returns the sentence saying so, for a report. A scene
/// that sets its dimensions, a B-mode reference and data that declare nothing
/// leave the scene as it is (`None`).
///
/// # Errors
/// A channel sidecar that cannot be read, or a `dimensions` key in it that is
/// not 2 or 3 (naming the file).
pub fn follow_declared_dimensions(
    scene: &mut Scene,
    measured: &Path,
) -> Result<Option<String>, OptimError> {
    use usray_transport::scene::Dimensions;
    let is_channels = measured
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if scene.acquisition.dimensions.is_some() || !is_channels {
        return Ok(None);
    }
    let declared = usray_signal::io::declared_dimensions(measured)?;
    let Some(declared) = declared.filter(|d| d.dimensions == 2) else {
        return Ok(None);
    };
    scene.acquisition.dimensions = Some(Dimensions::Two);
    Ok(Some(format!(
        "traced in 2-D (`acquisition.dimensions = 2`): the scene leaves the dimensions unset and {} declares a 2-D simulation ({}); set `acquisition.dimensions = 3` in the scene to trace in 3-D",
        measured.display(),
        declared.evidence
    )))
}

/// The amplitude unit of usray's 2-D renders with a collimated emission, as
/// channel data declare it in `amplitude_unit` (k-Wave's generator in
/// `../shared/tools/kwave` writes it): pressure per unit pressure on the
/// emitting elements' faces.
pub const SOURCE_PRESSURE_UNIT: &str = "Pa per 1 Pa source pressure";

/// Whether an `amplitude_unit` text names [`SOURCE_PRESSURE_UNIT`] (case and
/// spacing aside).
fn is_source_pressure_unit(text: &str) -> bool {
    let words = |t: &str| {
        t.split_whitespace()
            .map(str::to_ascii_lowercase)
            .collect::<Vec<_>>()
    };
    words(text) == words(SOURCE_PRESSURE_UNIT)
}

/// What [`compare_absolute_levels`] did.
#[derive(Clone, Debug, PartialEq)]
pub enum AbsoluteLevels {
    /// `imaging.reference_amplitude` was set; the sentence saying so.
    Set(String),
    /// The scene was left as it was; why.
    NotApplicable(String),
}

/// Compares absolute levels when the measured data and the model's renders
/// share a unit: channel data at `measured` that declare `amplitude_unit` =
/// [`SOURCE_PRESSURE_UNIT`], against a scene traced in 2-D with the collimated
/// emission (whose channel data carry ray theory's pressure per unit source
/// pressure; `docs/architecture.md`, "Spreading"). Then
/// `imaging.reference_amplitude` is set to the maximum envelope of the
/// measured data beamformed on the scene's grid, so that every image, measured
/// or simulated, is in dB against that one level: an echo the model renders
/// 3 dB too strong shows 3 dB too bright, which normalising each image to its
/// own maximum hides (a wall's impedance is then fixed by its echo's strength,
/// not only by the echo's share of the image).
///
/// Leaves the scene as it is, saying why, for a B-mode reference, data in
/// another or no declared unit (a scanner's are arbitrary), a scene traced in
/// 3-D (its renders keep the energy law, not pressure) or with the cosine lobe,
/// and a scene that sets `imaging.reference_amplitude` itself.
///
/// # Errors
/// Channel data that cannot be read or beamformed on the scene's grid.
pub fn compare_absolute_levels(
    scene: &mut Scene,
    measured: &Path,
) -> Result<AbsoluteLevels, OptimError> {
    use usray_transport::scene::{Dimensions, Emission};
    let not = |why: &str| Ok(AbsoluteLevels::NotApplicable(why.to_string()));
    let is_channels = measured
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if !is_channels {
        return not(
            "a B-mode reference has no amplitude unit; absolute levels need channel data (.json)",
        );
    }
    if scene.acquisition.dimensions != Some(Dimensions::Two) {
        return not("the scene is traced in 3-D, whose renders keep the energy law, not pressure; absolute levels need `acquisition.dimensions = 2`");
    }
    if scene.acquisition.emission != Emission::PlaneWave {
        return not("the scene emits the paper's cosine lobe, whose renders are not a pressure; absolute levels need `emission = \"plane_wave\"`");
    }
    if scene.imaging.reference_amplitude.is_some() {
        return not("the scene sets `imaging.reference_amplitude` itself");
    }
    let ch = read_channels(measured)?;
    let declared = ch.meta.extra.get("amplitude_unit").and_then(|u| u.as_str());
    if !declared.is_some_and(is_source_pressure_unit) {
        return Ok(AbsoluteLevels::NotApplicable(format!(
            "{} declares its amplitudes in {}, not in the renders' unit (`amplitude_unit` = \"{SOURCE_PRESSURE_UNIT}\")",
            measured.display(),
            declared.map_or("no unit".to_string(), |u| format!("\"{u}\"")),
        )));
    }
    let op = BMode::new(&scene.imaging_settings(), &ch.meta, ch.n_samples)?;
    let mut ws = op.workspace();
    op.forward(&ch, &mut ws)?;
    let peak = ws.envelope().iter().copied().fold(0.0, f64::max);
    if !(peak.is_finite() && peak > 0.0) {
        return not("the measured image is empty: no level to compare against");
    }
    scene.imaging.reference_amplitude = Some(peak);
    Ok(AbsoluteLevels::Set(format!(
        "levels compared absolutely: {} declares `amplitude_unit` = \"{SOURCE_PRESSURE_UNIT}\", the unit of the model's 2-D renders, so every image is in dB against the measured image's maximum (`imaging.reference_amplitude` = {peak:.4e}) instead of its own",
        measured.display()
    )))
}

/// Loads `path` as a reference B-mode `[nz, nx]` (row-major) on `scene`'s grid.
///
/// # Errors
/// Unreadable or malformed files, unknown extensions, and shape or grid mismatches,
/// each with a one-line message naming the file and both shapes.
pub fn load_reference(path: &Path, scene: &Scene) -> Result<Vec<f64>, OptimError> {
    let (nz, nx) = crate::objective::grid_shape(scene)?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let shown = path.display();
    match ext.as_str() {
        "json" => reference_from_channels(&read_channels(path)?, scene),
        "npy" => {
            let a = read_npy(path)?;
            if a.shape != [nz, nx] {
                return Err(OptimError::Reference(format!(
                    "{shown}: B-mode shape {:?} differs from the scene's imaging grid [{nz}, {nx}] (set [imaging] x_range_m/z_range_m/pixel_m to match, or pass channel data)",
                    a.shape
                )));
            }
            Ok(a.data)
        }
        "png" => {
            let sidecar = path.with_extension("json");
            let text = std::fs::read_to_string(&sidecar).map_err(|e| {
                OptimError::Reference(format!(
                    "{shown}: a PNG reference needs a sidecar {} with x_range_m and z_range_m: {e}",
                    sidecar.display()
                ))
            })?;
            let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
                OptimError::Reference(format!("{}: not JSON: {e}", sidecar.display()))
            })?;
            let range = |key: &str| -> Result<[f64; 2], OptimError> {
                let a = v.get(key).and_then(|r| r.as_array());
                match a.map(|a| a.iter().filter_map(|x| x.as_f64()).collect::<Vec<_>>()) {
                    Some(r) if r.len() == 2 => Ok([r[0], r[1]]),
                    _ => Err(OptimError::Reference(format!(
                        "{}: `{key}` must be [min, max] in metres",
                        sidecar.display()
                    ))),
                }
            };
            let (xr, zr) = (range("x_range_m")?, range("z_range_m")?);
            let im = &scene.imaging;
            let tol = 0.5 * im.pixel_m;
            let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() <= tol && (a[1] - b[1]).abs() <= tol;
            if !close(xr, im.x_range_m) || !close(zr, im.z_range_m) {
                return Err(OptimError::Reference(format!(
                    "{shown}: ranges x {xr:?}, z {zr:?} m differ from the scene's imaging grid x {:?}, z {:?} m (no resampling is done)",
                    im.x_range_m, im.z_range_m
                )));
            }
            let img = image::open(path)
                .map_err(|e| OptimError::Reference(format!("{shown}: cannot read PNG: {e}")))?
                .to_luma16();
            let (w, h) = img.dimensions();
            if (h as usize, w as usize) != (nz, nx) {
                return Err(OptimError::Reference(format!(
                    "{shown}: PNG is {h} × {w} pixels (rows × columns) but the scene's imaging grid is {nz} × {nx}"
                )));
            }
            Ok(img.pixels().map(|p| p.0[0] as f64 / 65535.0).collect())
        }
        _ => Err(OptimError::Reference(format!(
            "{shown}: a reference must be channel data (.json) or a B-mode (.npy, or .png with a sidecar .json)"
        ))),
    }
}

/// Loads multi-frame channel data (`.json`, frames as in
/// [`usray_signal::ChannelMeta::frames`]) as two reference B-modes on `scene`'s
/// grid: the even-numbered frames (0, 2, 4, … in label order) and the
/// odd-numbered ones, each beamformed and frame-averaged like
/// [`load_reference`]. The first is for the fit, the second for held-out losses
/// ([`crate::DiagnoseOptions::held_out_measured`]).
///
/// # Errors
/// Anything [`load_reference`] refuses; a file that is not channel data; channel
/// data with fewer than two frames.
pub fn load_reference_frames(
    path: &Path,
    scene: &Scene,
) -> Result<(Vec<f64>, Vec<f64>), OptimError> {
    let shown = path.display();
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if !is_json {
        return Err(OptimError::Reference(format!(
            "{shown}: holding frames out needs multi-frame channel data (.json), not a B-mode"
        )));
    }
    let ch = read_channels(path)?;
    let frames = ch
        .meta
        .frames()
        .map_err(|e| OptimError::Reference(format!("{shown}: {e}")))?;
    if frames.len() < 2 {
        return Err(OptimError::Reference(format!(
            "{shown}: holding frames out needs at least two frames (transmits tagged `frame`); this file has one"
        )));
    }
    let half = |parity: usize| -> Result<Vec<f64>, OptimError> {
        let transmits: Vec<usize> = frames
            .iter()
            .skip(parity)
            .step_by(2)
            .flatten()
            .copied()
            .collect();
        let record = ch.n_elements() * ch.n_samples;
        let part = ChannelData {
            meta: ChannelMeta {
                transmits: transmits
                    .iter()
                    .map(|&t| ch.meta.transmits[t].clone())
                    .collect(),
                ..ch.meta.clone()
            },
            n_samples: ch.n_samples,
            samples: transmits
                .iter()
                .flat_map(|&t| ch.samples[t * record..(t + 1) * record].iter().copied())
                .collect(),
        };
        reference_from_channels(&part, scene)
    };
    Ok((half(0)?, half(1)?))
}

/// Channel data already in memory as a reference B-mode `[nz, nx]` on
/// `scene`'s grid: `ch` beamformed with `scene`'s `[imaging]` settings, as
/// [`load_reference`] does with a channel-data file. For a caller that keeps
/// the channels too (`usray diagnose` checks their spectra) and so reads the
/// file once.
///
/// # Errors
/// Channel data the scene's imaging settings cannot beamform (no samples,
/// mismatched metadata).
pub fn reference_from_channels(ch: &ChannelData, scene: &Scene) -> Result<Vec<f64>, OptimError> {
    let op = BMode::new(&scene.imaging_settings(), &ch.meta, ch.n_samples)?;
    let mut ws = op.workspace();
    Ok(op.forward(ch, &mut ws)?.data)
}
