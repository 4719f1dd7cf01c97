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
        "json" => beamformed(&read_channels(path)?, scene),
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
        beamformed(&part, scene)
    };
    Ok((half(0)?, half(1)?))
}

/// `ch` beamformed into a B-mode with `scene`'s `[imaging]` settings.
fn beamformed(ch: &ChannelData, scene: &Scene) -> Result<Vec<f64>, OptimError> {
    let op = BMode::new(&scene.imaging_settings(), &ch.meta, ch.n_samples)?;
    let mut ws = op.workspace();
    Ok(op.forward(ch, &mut ws)?.data)
}
