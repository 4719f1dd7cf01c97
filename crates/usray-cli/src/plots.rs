//! Figures a user expects from a fit: line plots (loss and parameter histories,
//! FD-vs-AD sweeps) and the paper's green/red overlay of simulated and reference
//! B-modes. Everything is written as PNG, atomically.

use anyhow::{Context, Result};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// One named line of a plot.
pub struct Series {
    /// Legend text.
    pub name: String,
    /// `(x, y)` points, in order.
    pub points: Vec<(f64, f64)>,
}

/// Axis scaling of a plot.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// Linear axis.
    Linear,
    /// Base-10 logarithmic axis (non-positive values are dropped).
    Log,
}

const WIDTH: u32 = 800;
const HEIGHT: u32 = 500;

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

/// Draws `series` as lines with a legend and writes a PNG to `path`.
pub fn line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    x_scale: Scale,
    y_scale: Scale,
) -> Result<()> {
    register_font();
    let keep = |v: f64, s: Scale| v.is_finite() && (s == Scale::Linear || v > 0.0);
    let pts: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .copied()
                .filter(|&(x, y)| keep(x, x_scale) && keep(y, y_scale))
                .collect()
        })
        .collect();
    let all: Vec<(f64, f64)> = pts.iter().flatten().copied().collect();
    let range = |vals: &mut dyn Iterator<Item = f64>, s: Scale| -> (f64, f64) {
        let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        if !lo.is_finite() {
            return (if s == Scale::Log { 0.1 } else { 0.0 }, 1.0);
        }
        match s {
            Scale::Log => {
                let (lo, hi) = if lo == hi {
                    (lo / 2.0, hi * 2.0)
                } else {
                    (lo, hi)
                };
                (lo / 1.2, hi * 1.2)
            }
            Scale::Linear => {
                let pad = if hi > lo {
                    0.05 * (hi - lo)
                } else {
                    lo.abs().max(1e-12) * 0.1
                };
                (lo - pad, hi + pad)
            }
        }
    };
    let (x0, x1) = range(&mut all.iter().map(|p| p.0), x_scale);
    let (y0, y1) = range(&mut all.iter().map(|p| p.1), y_scale);

    let mut buf = vec![255u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE)
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        // One body for the four axis-scale combinations.
        macro_rules! draw {
            ($xr:expr, $yr:expr) => {{
                let mut chart = ChartBuilder::on(&root)
                    .caption(title, ("sans-serif", 22))
                    .margin(12)
                    .x_label_area_size(45)
                    .y_label_area_size(80)
                    .build_cartesian_2d($xr, $yr)
                    .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
                chart
                    .configure_mesh()
                    .x_desc(x_label)
                    .y_desc(y_label)
                    .x_label_formatter(&|v| format!("{v:.3e}"))
                    .y_label_formatter(&|v| format!("{v:.3e}"))
                    .draw()
                    .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
                for (i, (s, p)) in series.iter().zip(&pts).enumerate() {
                    let c = colour(i);
                    chart
                        .draw_series(LineSeries::new(p.iter().copied(), c.stroke_width(2)))
                        .map_err(|e| anyhow::anyhow!("plot: {e}"))?
                        .label(s.name.as_str())
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                        });
                    if p.len() <= 40 {
                        chart
                            .draw_series(p.iter().map(|&q| Circle::new(q, 3, c.filled())))
                            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
                    }
                }
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .draw()
                    .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
            }};
        }
        match (x_scale, y_scale) {
            (Scale::Linear, Scale::Linear) => draw!(x0..x1, y0..y1),
            (Scale::Linear, Scale::Log) => draw!(x0..x1, (y0..y1).log_scale()),
            (Scale::Log, Scale::Linear) => draw!((x0..x1).log_scale(), y0..y1),
            (Scale::Log, Scale::Log) => draw!((x0..x1).log_scale(), (y0..y1).log_scale()),
        }
        root.present().map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    }
    write_rgb_png(path, WIDTH, HEIGHT, buf)
}

/// The paper's overlay (figure "sim_real_image_compare"): simulated image in the
/// green channel, reference in the red, so agreement shows yellow.
pub fn overlay_png(
    path: &Path,
    nz: usize,
    nx: usize,
    simulated: &[f64],
    reference: &[f64],
) -> Result<()> {
    let to_u8 = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    let mut buf = Vec::with_capacity(nz * nx * 3);
    for (s, r) in simulated.iter().zip(reference) {
        buf.extend_from_slice(&[to_u8(*r), to_u8(*s), 0]);
    }
    write_rgb_png(path, nx as u32, nz as u32, buf)
}

/// The signed residual map of [`usray_optim::residual::signed_residual_rgb`]
/// (red: simulation brighter than measurement, blue: darker) as a PNG; returns
/// the grey-level difference that saturates the colours.
pub fn residual_png(
    path: &Path,
    nz: usize,
    nx: usize,
    simulated: &[f64],
    measured: &[f64],
) -> Result<f64> {
    let map = usray_optim::residual::signed_residual_rgb(simulated, measured, nz, nx, None)?;
    write_rgb_png(path, map.width as u32, map.height as u32, map.rgb)?;
    Ok(map.scale)
}

fn write_rgb_png(path: &Path, width: u32, height: u32, buf: Vec<u8>) -> Result<()> {
    let img = image::RgbImage::from_raw(width, height, buf)
        .context("internal: image buffer does not match its size")?;
    usray_signal::write_atomic(path, |w| {
        let mut bytes = Vec::new();
        img.write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(std::io::Error::other)?;
        w.write_all(&bytes)
    })
    .with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plots_and_overlays_are_valid_pngs_of_the_right_size() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("loss.png");
        let s = Series {
            name: "loss".into(),
            points: (1..50).map(|i| (i as f64, 1.0 / i as f64)).collect(),
        };
        line_plot(
            &p,
            "Loss",
            "iteration",
            "loss",
            &[s],
            Scale::Linear,
            Scale::Log,
        )
        .unwrap();
        let img = image::open(&p).unwrap();
        assert_eq!((img.width(), img.height()), (WIDTH, HEIGHT));
        // Something other than background was drawn.
        let rgb = img.to_rgb8();
        assert!(rgb.pixels().filter(|p| p.0 != [255, 255, 255]).count() > 1000);

        let q = dir.path().join("overlay.png");
        overlay_png(
            &q,
            2,
            3,
            &[0.0, 1.0, 0.5, 0.0, 0.0, 1.0],
            &[1.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        )
        .unwrap();
        let o = image::open(&q).unwrap().to_rgb8();
        assert_eq!(o.dimensions(), (3, 2));
        assert_eq!(o.get_pixel(1, 0).0, [255, 255, 0]); // both: yellow
        assert_eq!(o.get_pixel(0, 0).0, [255, 0, 0]); // reference only: red
        assert_eq!(o.get_pixel(2, 1).0, [0, 255, 0]); // simulated only: green
    }
}
