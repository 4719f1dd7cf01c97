//! The signed residual as a diverging colour map, for figures.

use super::{check_images, invalid};
use crate::OptimError;

/// A signed residual map as RGB pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct SignedResidualMap {
    /// Image width = `nx`.
    pub width: usize,
    /// Image height = `nz`.
    pub height: usize,
    /// `height · width · 3` bytes, row-major RGB.
    pub rgb: Vec<u8>,
    /// The residual `d = I − R` (grey levels) drawn at full colour.
    pub scale: f64,
}

/// The signed residual `d = I − R` as a diverging colour map: with
/// `t = clamp(d / scale, −1, 1)`, `t ≥ 0` is `(255, 255(1−t), 255(1−t))` (white to
/// red: simulation brighter than measurement) and `t < 0` is
/// `(255(1+t), 255(1+t), 255)` (white to blue: simulation darker); `d = 0` is
/// white. `scale` (grey levels; `1` grey level = `D` dB) defaults to the 99th
/// percentile of `|d|` (nearest rank), or 1 when that is 0, so a few outliers do
/// not wash out the map; the value used is returned for the colour bar.
///
/// ```
/// use usray_optim::residual::signed_residual_rgb;
/// let m = signed_residual_rgb(&[0.5, 0.0, 0.2], &[0.0, 0.5, 0.2], 1, 3, Some(0.5)).unwrap();
/// assert_eq!(m.rgb, vec![255, 0, 0, 0, 0, 255, 255, 255, 255]);
/// ```
///
/// # Errors
/// [`OptimError::Diagnosis`] for images not of `nz · nx` pixels in `[0, 1]`, or a
/// scale that is not a positive number.
pub fn signed_residual_rgb(
    simulated: &[f64],
    measured: &[f64],
    nz: usize,
    nx: usize,
    scale: Option<f64>,
) -> Result<SignedResidualMap, OptimError> {
    check_images(simulated, measured, nz, nx)?;
    let d: Vec<f64> = simulated.iter().zip(measured).map(|(i, r)| i - r).collect();
    let scale = match scale {
        Some(s) if s.is_finite() && s > 0.0 => s,
        Some(s) => {
            return Err(invalid(format!(
                "residual map scale must be a positive number, found {s}"
            )))
        }
        None => percentile_scale(&d),
    };
    let mut rgb = Vec::with_capacity(3 * d.len());
    for v in d {
        let t = (v / scale).clamp(-1.0, 1.0);
        let fade = |t: f64| (255.0 * (1.0 - t.abs())).round() as u8;
        if t >= 0.0 {
            rgb.extend_from_slice(&[255, fade(t), fade(t)]);
        } else {
            rgb.extend_from_slice(&[fade(t), fade(t), 255]);
        }
    }
    Ok(SignedResidualMap {
        width: nx,
        height: nz,
        rgb,
        scale,
    })
}

/// The default scale of [`signed_residual_rgb`]: the 99th percentile of
/// `|d|` (nearest rank), or 1 when that is 0.
fn percentile_scale(d: &[f64]) -> f64 {
    let mut a: Vec<f64> = d.iter().map(|v| v.abs()).collect();
    a.sort_by(f64::total_cmp);
    let p = if a.is_empty() {
        0.0
    } else {
        a[((0.99 * a.len() as f64).ceil() as usize).clamp(1, a.len()) - 1]
    };
    if p > 0.0 {
        p
    } else {
        1.0
    }
}

/// The residual `d = I − R` (grey levels) that [`signed_residual_rgb`] draws
/// at full colour by default: the 99th percentile of `|d|` (nearest rank), or
/// 1 when that is 0. Reports quote it beside the residual figures.
///
/// ```
/// use usray_optim::residual::residual_scale;
/// assert_eq!(residual_scale(&[0.5, 0.0, 0.2], &[0.0, 0.5, 0.2], 1, 3).unwrap(), 0.5);
/// ```
///
/// # Errors
/// As [`signed_residual_rgb`], for images not of `nz · nx` pixels in `[0, 1]`.
pub fn residual_scale(
    simulated: &[f64],
    measured: &[f64],
    nz: usize,
    nx: usize,
) -> Result<f64, OptimError> {
    check_images(simulated, measured, nz, nx)?;
    let d: Vec<f64> = simulated.iter().zip(measured).map(|(i, r)| i - r).collect();
    Ok(percentile_scale(&d))
}
