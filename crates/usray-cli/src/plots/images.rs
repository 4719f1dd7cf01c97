//! Image figures: a raster on the imaging grid with axes in millimetres
//! (lateral x across, depth z increasing downward, the grid's true aspect
//! ratio), a title and, where the colours stand for numbers, a colour bar with
//! its unit. Written as PNG, or SVG when the path ends in `.svg`.
//!
//! Pixel `(iz, ix)` of an `[nz, nx]` image covers the grid cell centred at
//! `(x_m[ix], z_m[iz])` of `ImagingSettings::grid`, so the axes span the
//! centres' range widened by half a pixel on each side.

use super::ticks::{label, ticked, ticks};
use super::{drawing, png_bytes, register_font, write_bytes, Scale};
use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;
use usray_signal::ImagingSettings;

/// The extent of an image on the imaging grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Rows (depths).
    pub nz: usize,
    /// Columns (lateral positions).
    pub nx: usize,
    /// Left and right edges of the image, mm.
    pub x_mm: [f64; 2],
    /// Top (shallowest) and bottom (deepest) edges of the image, mm.
    pub z_mm: [f64; 2],
}

impl Grid {
    /// The grid `settings` image on (its pixel centres widened by half a pixel).
    pub fn from_settings(settings: &ImagingSettings) -> Result<Grid> {
        let (x_m, z_m) = settings.grid().context("the imaging grid")?;
        Ok(Grid {
            nz: z_m.len(),
            nx: x_m.len(),
            x_mm: edges_mm(&x_m, settings.pixel_m),
            z_mm: edges_mm(&z_m, settings.pixel_m),
        })
    }

    fn pixels(&self) -> usize {
        self.nz * self.nx
    }
}

/// First and last cell edges of pixel centres `centres_m`, mm (a lone pixel
/// is `pixel_m` wide).
fn edges_mm(centres_m: &[f64], pixel_m: f64) -> [f64; 2] {
    let (first, last) = (centres_m[0], centres_m[centres_m.len() - 1]);
    let step_m = if centres_m.len() > 1 {
        (last - first) / (centres_m.len() - 1) as f64
    } else {
        pixel_m
    };
    [1e3 * (first - step_m / 2.0), 1e3 * (last + step_m / 2.0)]
}

/// A colour bar: what the colours of the image stand for.
struct ColourBar {
    /// Axis title with its unit.
    label: String,
    /// Value at the bottom and the top of the bar.
    bottom: f64,
    top: f64,
    /// Colours of equal steps from `bottom` (first) to `top` (last).
    colours: Vec<[u8; 3]>,
}

/// Everything an image figure shows.
struct ImageFigure<'a> {
    title: &'a str,
    grid: &'a Grid,
    /// `[nz, nx]` RGB pixels, row-major (row = depth).
    rgb: Vec<u8>,
    bar: Option<ColourBar>,
}

/// Where the image and the colour bar landed, figure pixels (end exclusive).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Layout {
    width: u32,
    height: u32,
    plot: Rect,
    bar: Option<Rect>,
}

/// A pixel rectangle `[x0, x1) × [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Rect {
    x0: u32,
    x1: u32,
    y0: u32,
    y1: u32,
}

impl Rect {
    fn from_range((x, y): (std::ops::Range<i32>, std::ops::Range<i32>)) -> Rect {
        let u = |v: i32| v.max(0) as u32;
        Rect {
            x0: u(x.start),
            x1: u(x.end),
            y0: u(y.start),
            y1: u(y.end),
        }
    }
}

/// Largest plot area, px: the image is scaled to fit, keeping its aspect ratio.
const PLOT_MAX_W: f64 = 560.0;
const PLOT_MAX_H: f64 = 620.0;
/// Title strip, margins, axis label areas and colour-bar strip, px.
const TITLE_H: u32 = 40;
const MARGIN: u32 = 15;
const LEFT_LABELS: u32 = 75;
const BOTTOM_LABELS: u32 = 55;
const BAR_GAP: u32 = 25;
const BAR_W: u32 = 22;
const BAR_LABELS: u32 = 85;
/// Narrowest figure, px.
const MIN_WIDTH: u32 = 600;
/// Steps of a colour bar.
const BAR_STEPS: usize = 128;

/// Figure size and plot size for `grid` at its true aspect ratio.
fn figure_size(grid: &Grid, with_bar: bool) -> (u32, u32, u32, u32) {
    let width_mm = (grid.x_mm[1] - grid.x_mm[0]).abs();
    let depth_mm = (grid.z_mm[1] - grid.z_mm[0]).abs();
    let aspect = (width_mm / depth_mm).clamp(1e-3, 1e3);
    let plot_w = PLOT_MAX_W.min(PLOT_MAX_H * aspect);
    let plot_h = plot_w / aspect;
    let (plot_w, plot_h) = (
        plot_w.round().max(1.0) as u32,
        plot_h.round().max(1.0) as u32,
    );
    let bar = if with_bar {
        BAR_GAP + BAR_W + BAR_LABELS + MARGIN
    } else {
        0
    };
    let width = (2 * MARGIN + LEFT_LABELS + plot_w + bar).max(MIN_WIDTH);
    let height = TITLE_H + 2 * MARGIN + plot_h + BOTTOM_LABELS;
    (width, height, plot_w, plot_h)
}

/// Draws the title, axes and colour bar of `fig` (not the image itself, which
/// each back end places into the returned plot rectangle).
fn draw_frame<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &ImageFigure,
) -> Result<Layout> {
    let (width, height, plot_w, _) = figure_size(fig.grid, fig.bar.is_some());
    root.fill(&WHITE).map_err(drawing)?;
    let (title_area, body) = root.split_vertically(TITLE_H);
    title_area
        .draw_text(
            fig.title,
            &("sans-serif", 20)
                .into_font()
                .into_text_style(&title_area)
                .pos(Pos::new(HPos::Center, VPos::Center)),
            (width as i32 / 2, TITLE_H as i32 / 2),
        )
        .map_err(drawing)?;
    let (main, right) = body.split_horizontally(2 * MARGIN + LEFT_LABELS + plot_w);
    let g = fig.grid;
    let (x_ticks, z_ticks) = (
        ticks(g.x_mm[0], g.x_mm[1], Scale::Linear),
        ticks(g.z_mm[0], g.z_mm[1], Scale::Linear),
    );
    let mut chart = ChartBuilder::on(&main)
        .margin(MARGIN)
        .x_label_area_size(BOTTOM_LABELS)
        .y_label_area_size(LEFT_LABELS)
        // Deepest at the bottom: depth increases downward.
        .build_cartesian_2d(
            ticked(g.x_mm[0]..g.x_mm[1], x_ticks.clone()),
            ticked(g.z_mm[1]..g.z_mm[0], z_ticks.clone()),
        )
        .map_err(drawing)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("lateral x (mm)")
        .y_desc("depth z (mm)")
        .x_label_formatter(&|v| label(*v, &x_ticks, Scale::Linear))
        .y_label_formatter(&|v| label(*v, &z_ticks, Scale::Linear))
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(drawing)?;
    let plot = Rect::from_range(chart.plotting_area().get_pixel_range());
    let bar = match &fig.bar {
        Some(bar) => Some(draw_bar(&right, bar)?),
        None => None,
    };
    Ok(Layout {
        width,
        height,
        plot,
        bar,
    })
}

/// Draws `bar` in the strip right of the image, level with the plot area.
fn draw_bar<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, bar: &ColourBar) -> Result<Rect> {
    let bar_ticks = ticks(bar.bottom, bar.top, Scale::Linear);
    let mut chart = ChartBuilder::on(area)
        .margin_top(MARGIN)
        .margin_bottom(MARGIN)
        .margin_left(BAR_GAP)
        .margin_right(MARGIN)
        .x_label_area_size(BOTTOM_LABELS)
        .set_label_area_size(LabelAreaPosition::Right, BAR_LABELS)
        .build_cartesian_2d(0.0..1.0, ticked(bar.bottom..bar.top, bar_ticks.clone()))
        .map_err(drawing)?;
    let step = (bar.top - bar.bottom) / bar.colours.len() as f64;
    chart
        .draw_series(bar.colours.iter().enumerate().map(|(i, c)| {
            let v = bar.bottom + i as f64 * step;
            Rectangle::new(
                [(0.0, v), (1.0, v + step)],
                RGBColor(c[0], c[1], c[2]).filled(),
            )
        }))
        .map_err(drawing)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(bar.label.as_str())
        .y_label_formatter(&|v| label(*v, &bar_ticks, Scale::Linear))
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(drawing)?;
    chart
        .plotting_area()
        .draw(&Rectangle::new([(0.0, bar.bottom), (1.0, bar.top)], BLACK))
        .map_err(drawing)?;
    Ok(Rect::from_range(chart.plotting_area().get_pixel_range()))
}

/// Writes `fig` to `path`: SVG if its extension is `svg`, else PNG.
fn write_image_figure(path: &Path, fig: &ImageFigure) -> Result<Layout> {
    anyhow::ensure!(
        fig.rgb.len() == 3 * fig.grid.pixels() && fig.grid.pixels() > 0,
        "writing {}: an image of {} × {} pixels needs {} RGB values, got {}",
        path.display(),
        fig.grid.nz,
        fig.grid.nx,
        3 * fig.grid.pixels(),
        fig.rgb.len()
    );
    register_font();
    let (width, height, _, _) = figure_size(fig.grid, fig.bar.is_some());
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
    {
        let mut svg = String::new();
        let layout = {
            let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
            let layout = draw_frame(&root, fig)?;
            root.present().map_err(drawing)?;
            layout
        };
        let svg = with_embedded_image(&svg, &layout.plot, fig)?;
        write_bytes(path, svg.as_bytes())?;
        Ok(layout)
    } else {
        let mut buf = vec![255u8; (width * height * 3) as usize];
        let layout = {
            let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
            let layout = draw_frame(&root, fig)?;
            root.present().map_err(drawing)?;
            layout
        };
        paint(&mut buf, width, &layout.plot, fig);
        write_bytes(path, &png_bytes(width, height, buf)?)?;
        Ok(layout)
    }
}

/// Fills `rect` of the `width`-wide RGB buffer with the image, nearest pixel.
fn paint(buf: &mut [u8], width: u32, rect: &Rect, fig: &ImageFigure) {
    let (w, h) = (rect.x1 - rect.x0, rect.y1 - rect.y0);
    let (nz, nx) = (fig.grid.nz, fig.grid.nx);
    let source = |p: u32, n_px: u32, n: usize| {
        (((p as f64 + 0.5) * n as f64 / n_px as f64) as usize).min(n - 1)
    };
    for py in 0..h {
        let iz = source(py, h, nz);
        for px in 0..w {
            let ix = source(px, w, nx);
            let from = 3 * (iz * nx + ix);
            let to = 3 * ((rect.y0 + py) as usize * width as usize + (rect.x0 + px) as usize);
            buf[to..to + 3].copy_from_slice(&fig.rgb[from..from + 3]);
        }
    }
}

/// `svg` with the image embedded as a PNG (`nx × nz` pixels, scaled without
/// smoothing) over the plot rectangle.
fn with_embedded_image(svg: &str, rect: &Rect, fig: &ImageFigure) -> Result<String> {
    let png = png_bytes(fig.grid.nx as u32, fig.grid.nz as u32, fig.rgb.clone())?;
    let element = format!(
        r#"<image x="{}" y="{}" width="{}" height="{}" preserveAspectRatio="none" style="image-rendering:pixelated" href="data:image/png;base64,{}"/>"#,
        rect.x0,
        rect.y0,
        rect.x1 - rect.x0,
        rect.y1 - rect.y0,
        base64(&png)
    );
    let end = svg
        .rfind("</svg>")
        .context("internal: the SVG back end wrote no </svg>")?;
    Ok(format!("{}{element}\n{}", &svg[..end], &svg[end..]))
}

/// Standard base64 with padding (RFC 4648), for a data URI.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Grey level 0–255 of a B-mode value in `[0, 1]` (clamped; non-finite is 0),
/// as `usray_signal::io::write_bmode_png` writes it.
fn grey(v: f64) -> u8 {
    let v = if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    };
    (v * 255.0).round() as u8
}

/// A B-mode figure: grey image, colour bar from 0 dB (white, top) down to
/// −`dynamic_range_db` (black), since grey = (dB + D)/D.
fn bmode_image<'a>(
    grid: &'a Grid,
    data: &[f64],
    dynamic_range_db: f64,
    title: &'a str,
) -> ImageFigure<'a> {
    ImageFigure {
        title,
        grid,
        rgb: data.iter().flat_map(|&v| [grey(v); 3]).collect(),
        bar: Some(ColourBar {
            label: "echo level (dB)".into(),
            bottom: -dynamic_range_db,
            top: 0.0,
            colours: (0..BAR_STEPS)
                .map(|i| [grey((i as f64 + 0.5) / BAR_STEPS as f64); 3])
                .collect(),
        }),
    }
}

/// Writes the B-mode `data` (`[nz, nx]`, values in `[0, 1]`) on `grid` as a
/// figure with mm axes and a dB colour bar to `path` (`.png` or `.svg`).
pub fn bmode_figure(
    path: &Path,
    grid: &Grid,
    data: &[f64],
    dynamic_range_db: f64,
    title: &str,
) -> Result<()> {
    write_image_figure(path, &bmode_image(grid, data, dynamic_range_db, title)).map(|_| ())
}

/// The paper's overlay (figure "sim_real_image_compare") as a figure:
/// simulated image in the green channel, reference in the red, so agreement
/// shows yellow.
pub fn overlay_figure(
    path: &Path,
    grid: &Grid,
    simulated: &[f64],
    reference: &[f64],
    title: &str,
) -> Result<()> {
    let rgb = simulated
        .iter()
        .zip(reference)
        .flat_map(|(&s, &r)| [grey(r), grey(s), 0])
        .collect();
    let title = format!("{title}: simulated green, reference red, both yellow");
    write_image_figure(
        path,
        &ImageFigure {
            title: &title,
            grid,
            rgb,
            bar: None,
        },
    )
    .map(|_| ())
}

/// The signed residual map of [`usray_optim::residual::signed_residual_rgb`]
/// (red: simulation brighter than measurement, blue: darker) as a figure whose
/// colour bar reads the difference in dB: a grey-level difference `d` is
/// `d · D` dB where neither image is clipped (grey = (dB + D)/D). Returns the
/// grey-level difference that saturates the colours.
pub fn residual_figure(
    path: &Path,
    grid: &Grid,
    simulated: &[f64],
    measured: &[f64],
    dynamic_range_db: f64,
    title: &str,
) -> Result<f64> {
    let map =
        usray_optim::residual::signed_residual_rgb(simulated, measured, grid.nz, grid.nx, None)?;
    // The bar is the same colour map applied to a ramp of differences from
    // −scale to +scale (as simulated − measured, both within [0, scale]).
    let ramp: Vec<f64> = (0..BAR_STEPS)
        .map(|i| map.scale * (2.0 * (i as f64 + 0.5) / BAR_STEPS as f64 - 1.0))
        .collect();
    let sim: Vec<f64> = ramp.iter().map(|d| d.max(0.0)).collect();
    let meas: Vec<f64> = ramp.iter().map(|d| (-d).max(0.0)).collect();
    let bar =
        usray_optim::residual::signed_residual_rgb(&sim, &meas, BAR_STEPS, 1, Some(map.scale))?;
    let fig = ImageFigure {
        title,
        grid,
        rgb: map.rgb,
        bar: Some(ColourBar {
            label: "simulated − measured (dB)".into(),
            bottom: -map.scale * dynamic_range_db,
            top: map.scale * dynamic_range_db,
            colours: bar.rgb.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
        }),
    };
    write_image_figure(path, &fig)?;
    Ok(map.scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scene default's grid: x ∈ [−20, 20] mm, z ∈ [1, 35] mm, 0.2 mm pixels.
    fn grid() -> Grid {
        Grid::from_settings(&ImagingSettings::new([-0.02, 0.02], [0.001, 0.035], 0.2e-3)).unwrap()
    }

    fn luminance(p: &image::Rgb<u8>) -> f64 {
        p.0.iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0
    }

    #[test]
    fn grid_spans_the_pixel_cells_in_mm() {
        let g = grid();
        assert_eq!((g.nz, g.nx), (171, 201));
        assert!((g.x_mm[0] + 20.1).abs() < 1e-9 && (g.x_mm[1] - 20.1).abs() < 1e-9);
        assert!((g.z_mm[0] - 0.9).abs() < 1e-9 && (g.z_mm[1] - 35.1).abs() < 1e-9);
    }

    #[test]
    fn bmode_figure_is_wide_has_a_light_to_dark_bar_and_puts_a_target_where_the_axes_say() {
        let g = grid();
        // Grey 0.3 everywhere, a bright 3 × 3 target centred at x = +10 mm, z = 25 mm.
        let (target_x_mm, target_z_mm) = (10.0, 25.0);
        let col = ((target_x_mm - g.x_mm[0]) / 0.2) as usize;
        let row = ((target_z_mm - g.z_mm[0]) / 0.2) as usize;
        let mut data = vec![0.3; g.nz * g.nx];
        for iz in row - 1..=row + 1 {
            for ix in col - 1..=col + 1 {
                data[iz * g.nx + ix] = 1.0;
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.png");
        let layout = write_image_figure(&path, &bmode_image(&g, &data, 60.0, "test")).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert!(img.width() >= 600, "{} px wide", img.width());
        assert_eq!((img.width(), img.height()), (layout.width, layout.height));

        // The colour bar: white at the top (0 dB), black at the bottom (−60 dB),
        // never lighter further down.
        let bar = layout.bar.unwrap();
        let x = (bar.x0 + bar.x1) / 2;
        let column: Vec<f64> = (bar.y0 + 1..bar.y1 - 1)
            .map(|y| luminance(img.get_pixel(x, y)))
            .collect();
        assert!(
            column[0] > 240.0 && column[column.len() - 1] < 15.0,
            "{column:?}"
        );
        assert!(column.windows(2).all(|w| w[1] <= w[0]), "{column:?}");

        // The image region, found from the pixels alone: the rows and columns
        // left of the bar made mostly of the background grey (anti-aliased
        // text has a few such pixels too).
        let background = [grey(0.3); 3];
        let is_background = |x: u32, y: u32| img.get_pixel(x, y).0 == background;
        let cols: Vec<u32> = (0..bar.x0)
            .filter(|&x| (0..img.height()).filter(|&y| is_background(x, y)).count() > 100)
            .collect();
        let rows: Vec<u32> = (0..img.height())
            .filter(|&y| (0..bar.x0).filter(|&x| is_background(x, y)).count() > 100)
            .collect();
        let (x0, x1) = (cols[0], cols[cols.len() - 1] + 1);
        let (y0, y1) = (rows[0], rows[rows.len() - 1] + 1);
        let (w, h) = (f64::from(x1 - x0), f64::from(y1 - y0));
        // True aspect ratio: 40.2 mm across, 34.2 mm deep.
        assert!(((w / h) / (40.2 / 34.2) - 1.0).abs() < 0.02, "{w} × {h}");
        // The target's centre where the axes put x = 10 mm, z = 25 mm (depth down).
        let expected_x = f64::from(x0) + (target_x_mm - g.x_mm[0]) / (g.x_mm[1] - g.x_mm[0]) * w;
        let expected_y = f64::from(y0) + (target_z_mm - g.z_mm[0]) / (g.z_mm[1] - g.z_mm[0]) * h;
        let bright: Vec<(u32, u32)> = img
            .enumerate_pixels()
            .filter(|(x, y, p)| p.0 == [255; 3] && (x0..x1).contains(x) && (y0..y1).contains(y))
            .map(|(x, y, _)| (x, y))
            .collect();
        assert!(!bright.is_empty());
        let n = bright.len() as f64;
        let cx = bright.iter().map(|p| f64::from(p.0)).sum::<f64>() / n + 0.5;
        let cy = bright.iter().map(|p| f64::from(p.1)).sum::<f64>() / n + 0.5;
        assert!(
            (cx - expected_x).abs() < 2.0,
            "target at x px {cx}, axes say {expected_x}"
        );
        assert!(
            (cy - expected_y).abs() < 2.0,
            "target at y px {cy}, axes say {expected_y}"
        );
        // The axes' plot area is the image region.
        let found = Rect { x0, x1, y0, y1 };
        let p = layout.plot;
        assert!(
            [
                (p.x0, found.x0),
                (p.x1, found.x1),
                (p.y0, found.y0),
                (p.y1, found.y1)
            ]
            .iter()
            .all(|(a, b)| a.abs_diff(*b) <= 1),
            "plot {p:?}, image {found:?}"
        );
    }

    /// Whether every opened tag of `svg` is closed in order (a small
    /// well-formedness check: declarations and comments are skipped).
    fn tags_balance(svg: &str) -> bool {
        let mut stack: Vec<&str> = Vec::new();
        let mut rest = svg;
        while let Some(start) = rest.find('<') {
            let Some(len) = rest[start..].find('>') else {
                return false;
            };
            let tag = &rest[start + 1..start + len];
            rest = &rest[start + len + 1..];
            if tag.starts_with('?') || tag.starts_with('!') || tag.ends_with('/') {
                continue;
            }
            let name = |t: &'_ str| t.split_whitespace().next().unwrap_or("").to_string();
            if let Some(closing) = tag.strip_prefix('/') {
                if stack.pop().map(name) != Some(name(closing)) {
                    return false;
                }
            } else {
                stack.push(tag);
            }
        }
        stack.is_empty()
    }

    #[test]
    fn svg_figure_is_well_formed_and_embeds_the_image() {
        let g = grid();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.svg");
        bmode_figure(&path, &g, &vec![0.5; g.nz * g.nx], 60.0, "SVG test").unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(
            svg.starts_with("<svg") || svg.starts_with("<?xml"),
            "{}",
            &svg[..40]
        );
        assert!(svg.trim_end().ends_with("</svg>"));
        assert!(tags_balance(&svg));
        assert!(!tags_balance("<svg><g></svg></g>"));
        assert_eq!(svg.matches("<image ").count(), 1);
        assert!(svg.contains("href=\"data:image/png;base64,iVBORw0KGgo"));
        assert!(svg.contains("depth z (mm)") && svg.contains("echo level (dB)"));
    }

    #[test]
    fn base64_matches_rfc_4648() {
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(plain.as_bytes()), coded);
        }
    }

    #[test]
    fn residual_bar_runs_from_blue_through_white_to_red_and_overlay_is_yellow_where_both() {
        let g = grid();
        let dir = tempfile::tempdir().unwrap();
        let measured = vec![0.5; g.nz * g.nx];
        let simulated: Vec<f64> = (0..g.nz * g.nx)
            .map(|i| if i % 2 == 0 { 0.6 } else { 0.4 })
            .collect();
        let path = dir.path().join("r.png");
        let scale = residual_figure(&path, &g, &simulated, &measured, 60.0, "r").unwrap();
        assert!((scale - 0.1).abs() < 1e-9);
        let img = image::open(&path).unwrap().to_rgb8();
        // The bar sits right of the image: find its column from the top-right
        // red and bottom-right blue.
        let red = |p: &image::Rgb<u8>| p.0[0] > 200 && p.0[2] < 60;
        let blue = |p: &image::Rgb<u8>| p.0[2] > 200 && p.0[0] < 60;
        let bar_x = (0..img.width())
            .rev()
            .find(|&x| (0..img.height()).any(|y| red(img.get_pixel(x, y))))
            .unwrap();
        let column: Vec<&image::Rgb<u8>> =
            (0..img.height()).map(|y| img.get_pixel(bar_x, y)).collect();
        let first_red = column.iter().position(|p| red(p)).unwrap();
        let last_blue = column.iter().rposition(|p| blue(p)).unwrap();
        assert!(first_red < last_blue, "red above blue");

        let path = dir.path().join("o.png");
        overlay_figure(
            &path,
            &g,
            &vec![1.0; g.nz * g.nx],
            &vec![1.0; g.nz * g.nx],
            "o",
        )
        .unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        let yellow = img.pixels().filter(|p| p.0 == [255, 255, 0]).count();
        assert!(yellow > 100_000, "{yellow} yellow pixels");
        assert!(overlay_figure(&path, &g, &[1.0], &[1.0], "o").is_err());
    }
}
