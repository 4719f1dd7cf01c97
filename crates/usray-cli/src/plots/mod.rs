//! Figures a paper would print: line figures of a fit (loss and parameter
//! histories, FD-vs-AD sweeps; [`lines`]) and image figures of B-modes,
//! overlays and residual maps with axes in millimetres and colour bars
//! ([`images`]). Text uses the embedded DejaVu Sans font; files are written
//! atomically.

mod images;
mod lines;
mod ticks;

pub use images::{bmode_figure, overlay_figure, residual_figure, Grid};
pub use lines::{line_figure, Axis, Panel, Series};

use anyhow::{Context, Result};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// Axis scaling of a plot and how its ticks are labelled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    /// Linear axis.
    Linear,
    /// Linear axis of whole numbers (iterations): ticks at integers, labelled
    /// without decimals.
    Count,
    /// Base-10 logarithmic axis (non-positive values are dropped).
    Log,
}

/// How a scene parameter is shown on an axis: its unit, and the factor from
/// its SI value (the scene's, e.g. metres) to the shown one (e.g. mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unit {
    /// Unit text, e.g. `"mm"`; `"dimensionless"` for a pure number.
    pub name: &'static str,
    /// Shown value per scene value.
    pub per_si: f64,
}

/// Unit suffixes of scene parameter names (CONTRACT: SI names like
/// `radius_m`, `center_frequency_hz`), longest match first, with the unit each
/// is shown in: lengths in mm, frequencies in MHz, others as named.
const UNIT_SUFFIXES: [(&str, Unit); 9] = [
    (
        "_m_s",
        Unit {
            name: "m/s",
            per_si: 1.0,
        },
    ),
    (
        "_m",
        Unit {
            name: "mm",
            per_si: 1e3,
        },
    ),
    (
        "_hz",
        Unit {
            name: "MHz",
            per_si: 1e-6,
        },
    ),
    (
        "_mrayl",
        Unit {
            name: "MRayl",
            per_si: 1.0,
        },
    ),
    (
        "_deg",
        Unit {
            name: "°",
            per_si: 1.0,
        },
    ),
    (
        "_db_cm_mhz",
        Unit {
            name: "dB/(cm·MHz)",
            per_si: 1.0,
        },
    ),
    (
        "_db_per_cm",
        Unit {
            name: "dB/cm",
            per_si: 1.0,
        },
    ),
    (
        "_db",
        Unit {
            name: "dB",
            per_si: 1.0,
        },
    ),
    (
        "_per_mm3",
        Unit {
            name: "1/mm³",
            per_si: 1.0,
        },
    ),
];

/// The unit suffix of parameter `path` and the unit it is shown in.
fn unit_suffix(path: &str) -> Option<(&'static str, Unit)> {
    UNIT_SUFFIXES
        .iter()
        .copied()
        .find(|(suffix, _)| path.ends_with(suffix))
}

/// The unit a parameter `path` is shown in (`dimensionless` without a unit
/// suffix, e.g. `roughness`).
pub fn param_unit(path: &str) -> Unit {
    unit_suffix(path).map_or(
        Unit {
            name: "dimensionless",
            per_si: 1.0,
        },
        |(_, unit)| unit,
    )
}

/// A parameter's short axis name: its last two path segments without the unit
/// suffix (`objects.cylinder.radius_m` → `cylinder.radius`).
pub fn param_name(path: &str) -> String {
    let stem = unit_suffix(path).map_or(path, |(suffix, _)| &path[..path.len() - suffix.len()]);
    let segments: Vec<&str> = stem.rsplitn(3, '.').collect();
    match segments.as_slice() {
        [last, parent, ..] => format!("{parent}.{last}"),
        _ => stem.to_string(),
    }
}

/// Registers the embedded DejaVu Sans font once, so text renders on any machine
/// without system fonts.
fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The embedded font is a valid TTF; failing here would be a packaging bug.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// The colour of the `i`-th series.
fn colour(i: usize) -> RGBColor {
    const PALETTE: [RGBColor; 6] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(23, 190, 207),
    ];
    PALETTE[i % PALETTE.len()]
}

/// A plotters drawing error as an anyhow error.
fn drawing<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing a figure: {e}")
}

/// PNG encoding of a `width × height` RGB buffer.
fn png_bytes(width: u32, height: u32, buf: Vec<u8>) -> Result<Vec<u8>> {
    let img = image::RgbImage::from_raw(width, height, buf)
        .context("internal: image buffer does not match its size")?;
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .context("encoding a PNG")?;
    Ok(bytes)
}

/// Writes `width × height` RGB pixels to `path` as a PNG, atomically.
fn write_rgb_png(path: &Path, width: u32, height: u32, buf: Vec<u8>) -> Result<()> {
    write_bytes(path, &png_bytes(width, height, buf)?)
}

/// Writes `bytes` to `path`, atomically.
fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    usray_signal::write_atomic(path, |w| w.write_all(bytes))
        .with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_are_shown_in_their_units_under_short_names() {
        assert_eq!(param_unit("objects.cylinder.radius_m").name, "mm");
        assert_eq!(param_unit("objects.cylinder.radius_m").per_si, 1e3);
        assert_eq!(param_unit("materials.water.sound_speed_m_s").name, "m/s");
        assert_eq!(param_unit("probe.center_frequency_hz").per_si, 1e-6);
        assert_eq!(
            param_unit("materials.target.roughness").name,
            "dimensionless"
        );
        assert_eq!(param_name("objects.cylinder.radius_m"), "cylinder.radius");
        assert_eq!(
            param_name("materials.water.sound_speed_m_s"),
            "water.sound_speed"
        );
        assert_eq!(param_name("materials.target.roughness"), "target.roughness");
        assert_eq!(param_name("radius_m"), "radius");
    }
}
