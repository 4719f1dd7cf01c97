//! Line figures (loss and parameter histories, FD-vs-AD sweeps): one or more
//! panels stacked in one PNG, each with its own axes, ticks from [`super::ticks`]
//! and, where the true value is known, a dashed horizontal line at it.

use super::ticks::{label, ticked, ticks};
use super::{colour, drawing, register_font, write_rgb_png, Scale};
use anyhow::Result;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use std::path::Path;

/// One named line of a panel.
pub struct Series {
    /// Legend text.
    pub name: String,
    /// `(x, y)` points, in order.
    pub points: Vec<(f64, f64)>,
    /// The true value of `y`, where known: drawn as a dashed horizontal line
    /// in the series' colour, so that a fit's convergence to it shows.
    pub truth: Option<f64>,
}

/// One axis of a panel.
#[derive(Clone, Copy)]
pub struct Axis<'a> {
    /// Axis title with its unit, e.g. `"radius (mm)"`, `"iteration"`.
    pub label: &'a str,
    /// Scaling and tick style.
    pub scale: Scale,
}

/// One plot of a figure.
pub struct Panel<'a> {
    /// Caption above the panel (empty: none; a one-panel figure has its title).
    pub caption: &'a str,
    /// Horizontal axis.
    pub x: Axis<'a>,
    /// Vertical axis.
    pub y: Axis<'a>,
    /// The lines.
    pub series: &'a [Series],
}

/// Figure width, px.
pub const WIDTH: u32 = 800;
/// Height of a one-panel figure, px.
const SINGLE_HEIGHT: u32 = 500;
/// Height of each panel of a stacked figure, px.
const STACKED_PANEL_HEIGHT: u32 = 280;
/// Height of the figure's title, px.
const TITLE_HEIGHT: u32 = 40;

/// Draws `panels` stacked top to bottom under `title` and writes a PNG to `path`.
pub fn line_figure(path: &Path, title: &str, panels: &[Panel]) -> Result<()> {
    register_font();
    let height = match panels.len() {
        0 | 1 => SINGLE_HEIGHT,
        n => TITLE_HEIGHT + n as u32 * STACKED_PANEL_HEIGHT,
    };
    let mut buf = vec![255u8; (WIDTH * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, height)).into_drawing_area();
        root.fill(&WHITE).map_err(drawing)?;
        let body = root.titled(title, ("sans-serif", 22)).map_err(drawing)?;
        for (area, panel) in body
            .split_evenly((panels.len().max(1), 1))
            .iter()
            .zip(panels)
        {
            draw_panel(area, panel)?;
        }
        root.present().map_err(drawing)?;
    }
    write_rgb_png(path, WIDTH, height, buf)
}

/// Whether `v` can be placed on an axis of `scale`.
fn plottable(v: f64, scale: Scale) -> bool {
    v.is_finite() && (scale != Scale::Log || v > 0.0)
}

/// The shown range of `values` on `scale`: padded by 5% (linear) or a factor
/// 1.2 (log); a fallback when nothing is plottable.
fn axis_range(values: impl Iterator<Item = f64>, scale: Scale) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|&v| plottable(v, scale))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (if scale == Scale::Log { 0.1 } else { 0.0 }, 1.0);
    }
    match scale {
        Scale::Log => {
            let (lo, hi) = if lo == hi {
                (lo / 2.0, hi * 2.0)
            } else {
                (lo, hi)
            };
            (lo / 1.2, hi * 1.2)
        }
        Scale::Linear | Scale::Count => {
            let pad = if hi > lo {
                0.05 * (hi - lo)
            } else {
                lo.abs().max(1e-12) * 0.1
            };
            (lo - pad, hi + pad)
        }
    }
}

/// Draws one panel into `area`.
fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, panel: &Panel) -> Result<()> {
    let (xs, ys) = (panel.x.scale, panel.y.scale);
    let points: Vec<Vec<(f64, f64)>> = panel
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .copied()
                .filter(|&(x, y)| plottable(x, xs) && plottable(y, ys))
                .collect()
        })
        .collect();
    let (x0, x1) = axis_range(points.iter().flatten().map(|p| p.0), xs);
    let truths = panel.series.iter().filter_map(|s| s.truth);
    let (y0, y1) = axis_range(points.iter().flatten().map(|p| p.1).chain(truths), ys);
    let (x_ticks, y_ticks) = (ticks(x0, x1, xs), ticks(y0, y1, ys));
    let x_fmt = |v: &f64| label(*v, &x_ticks, xs);
    let y_fmt = |v: &f64| label(*v, &y_ticks, ys);
    // One body for the four combinations of linear and logarithmic axes.
    macro_rules! draw {
        ($x_range:expr, $y_range:expr) => {{
            let mut chart = ChartBuilder::on(area)
                .caption(panel.caption, ("sans-serif", 16))
                .margin(12)
                .x_label_area_size(45)
                .y_label_area_size(80)
                .build_cartesian_2d(
                    ticked($x_range, x_ticks.clone()),
                    ticked($y_range, y_ticks.clone()),
                )
                .map_err(drawing)?;
            chart
                .configure_mesh()
                .x_desc(panel.x.label)
                .y_desc(panel.y.label)
                .x_label_formatter(&x_fmt)
                .y_label_formatter(&y_fmt)
                .label_style(("sans-serif", 14))
                .axis_desc_style(("sans-serif", 16))
                .light_line_style(TRANSPARENT)
                .draw()
                .map_err(drawing)?;
            for (i, (s, p)) in panel.series.iter().zip(&points).enumerate() {
                let c = colour(i);
                chart
                    .draw_series(LineSeries::new(p.iter().copied(), c.stroke_width(2)))
                    .map_err(drawing)?
                    .label(s.name.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 18, y)], c.stroke_width(2))
                    });
                if p.len() <= 40 {
                    chart
                        .draw_series(p.iter().map(|&q| Circle::new(q, 3, c.filled())))
                        .map_err(drawing)?;
                }
                if let Some(t) = s.truth.filter(|&t| plottable(t, ys)) {
                    chart
                        .draw_series(DashedLineSeries::new(
                            [(x0, t), (x1, t)],
                            10,
                            6,
                            c.stroke_width(2),
                        ))
                        .map_err(drawing)?
                        .label(if panel.series.len() == 1 {
                            "true value".to_string()
                        } else {
                            format!("{}: true value", s.name)
                        })
                        .legend(move |(x, y)| {
                            DashedPathElement::new([(x, y), (x + 18, y)], 6, 3, c.stroke_width(2))
                        });
                }
            }
            chart
                .configure_series_labels()
                .label_font(("sans-serif", 14))
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(drawing)?;
        }};
    }
    match (xs == Scale::Log, ys == Scale::Log) {
        (false, false) => draw!(x0..x1, y0..y1),
        (false, true) => draw!(x0..x1, (y0..y1).log_scale()),
        (true, false) => draw!((x0..x1).log_scale(), y0..y1),
        (true, true) => draw!((x0..x1).log_scale(), (y0..y1).log_scale()),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixels_of(path: &Path, c: RGBColor) -> usize {
        let img = image::open(path).unwrap().to_rgb8();
        img.pixels().filter(|p| p.0 == [c.0, c.1, c.2]).count()
    }

    #[test]
    fn panels_stack_and_truth_is_drawn() {
        let dir = tempfile::tempdir().unwrap();
        let series = |truth| {
            [Series {
                name: "radius".into(),
                points: (0..=20)
                    .map(|i| (i as f64, 6.0 - 0.05 * i as f64))
                    .collect(),
                truth,
            }]
        };
        let axes = (
            Axis {
                label: "iteration",
                scale: Scale::Count,
            },
            Axis {
                label: "radius (mm)",
                scale: Scale::Linear,
            },
        );
        let (with, without) = (series(Some(5.0)), series(None));
        let panel = |s| Panel {
            caption: "",
            x: axes.0,
            y: axes.1,
            series: s,
        };
        let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
        line_figure(&a, "with truth", &[panel(&with)]).unwrap();
        line_figure(&b, "without", &[panel(&without)]).unwrap();
        let img = image::open(&a).unwrap();
        assert_eq!((img.width(), img.height()), (WIDTH, SINGLE_HEIGHT));
        // The dashed line (across the plot) adds many pixels of the series' colour.
        assert!(pixels_of(&a, colour(0)) > pixels_of(&b, colour(0)) + 500);

        let c = dir.path().join("c.png");
        line_figure(&c, "two", &[panel(&with), panel(&without)]).unwrap();
        let img = image::open(&c).unwrap();
        assert_eq!(img.height(), TITLE_HEIGHT + 2 * STACKED_PANEL_HEIGHT);
    }
}
