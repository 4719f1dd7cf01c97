//! Tick positions and labels an axis prints: "nice" steps (1, 2 or 5 × 10ᵏ),
//! whole numbers on count axes (iterations: 0, 5, 10 — never "1.000e1"), decades
//! on logarithmic axes, and labels with as many decimals as the step needs.

use super::Scale;
use plotters::coord::ranged1d::{AsRangedCoord, DefaultFormatting, KeyPointHint, Ranged};
use std::ops::Range;

/// A plotters axis whose bold ticks are given (none light), so that the mesh
/// labels exactly the ticks of [`ticks`] with [`label`].
pub struct Ticked<R> {
    inner: R,
    ticks: Vec<f64>,
}

/// `range` (a `lo..hi` or its `.log_scale()`) with `ticks`.
pub fn ticked<R>(range: R, ticks: Vec<f64>) -> Ticked<R::CoordDescType>
where
    R: AsRangedCoord<Value = f64>,
    R::CoordDescType: Ranged<ValueType = f64>,
{
    Ticked {
        inner: range.into(),
        ticks,
    }
}

impl<R: Ranged<ValueType = f64>> Ranged for Ticked<R> {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.inner.map(value, limit)
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.inner.range()
    }

    fn axis_pixel_range(&self, limit: (i32, i32)) -> Range<i32> {
        self.inner.axis_pixel_range(limit)
    }
}

/// At most this many intervals between ticks (so at most one more tick), so
/// that labels never overlap.
const MAX_TICKS: usize = 8;

/// The ticks of an axis spanning `lo..=hi` (either order) on `scale`, in order.
pub fn ticks(lo: f64, hi: f64, scale: Scale) -> Vec<f64> {
    let (lo, hi) = (lo.min(hi), lo.max(hi));
    match scale {
        Scale::Log => log_ticks(lo, hi),
        Scale::Linear => linear_ticks(lo, hi, nice_step((hi - lo) / MAX_TICKS as f64)),
        Scale::Count => linear_ticks(lo, hi, nice_step((hi - lo) / MAX_TICKS as f64).max(1.0)),
    }
}

/// The label of tick `v` among `ticks` of an axis on `scale`.
pub fn label(v: f64, ticks: &[f64], scale: Scale) -> String {
    match scale {
        Scale::Count => format!("{}", v.round() as i64),
        Scale::Log => log_label(v, ticks),
        Scale::Linear => linear_label(v, ticks),
    }
}

/// The smallest 1, 2 or 5 × 10ᵏ at least `raw` (1 for a non-positive `raw`).
fn nice_step(raw: f64) -> f64 {
    if !(raw.is_finite() && raw > 0.0) {
        return 1.0;
    }
    let decade = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * decade)
        .find(|s| *s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * decade)
}

/// Multiples of `step` within `lo..=hi`.
fn linear_ticks(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// Powers of ten within `lo..=hi` (`lo > 0`); with fewer than three of them,
/// also their 2× and 5× multiples, so that a short log axis still has labels.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi.is_finite()) {
        return Vec::new();
    }
    let (k0, k1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let within = |v: &f64| *v >= lo * (1.0 - 1e-9) && *v <= hi * (1.0 + 1e-9);
    // Parsing "Me-K" gives the exactly rounded value, so labels print short.
    let at = |m: u32, k: i32| format!("{m}e{k}").parse::<f64>().unwrap_or(f64::NAN);
    let decades: Vec<f64> = (k0..=k1).map(|k| at(1, k)).filter(within).collect();
    if decades.len() >= 3 {
        // Many decades: every one, thinned to at most MAX_TICKS.
        let every = decades.len().div_ceil(MAX_TICKS);
        return decades.into_iter().step_by(every).collect();
    }
    (k0..=k1)
        .flat_map(|k| [at(1, k), at(2, k), at(5, k)])
        .filter(within)
        .collect()
}

/// `0.001` … `5000` as plain decimals when every tick of the axis is in that
/// range, else all as `1e-5`, so that one axis reads one way.
fn log_label(v: f64, ticks: &[f64]) -> String {
    if ticks.iter().all(|t| (1e-3..1e4).contains(t)) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// A linear tick with the decimals the step between `ticks` needs; scientific
/// (`2.5e-5`) when the axis's largest magnitude is below 10⁻³ or from 10⁵ up.
fn linear_label(v: f64, ticks: &[f64]) -> String {
    let step = match ticks {
        [a, b, ..] => (b - a).abs(),
        _ => v.abs().max(f64::MIN_POSITIVE),
    };
    if v.abs() < step * 1e-6 {
        return "0".into();
    }
    // The step's decade, robust to the step's rounding (0.00999… is 10⁻²).
    let step_exp = (step.log10() + 1e-6).floor() as i32;
    let biggest = ticks.iter().fold(0.0f64, |m, t| m.max(t.abs()));
    if !(1e-3..1e5).contains(&biggest) {
        let digits = (v.abs().log10().floor() as i32 - step_exp).max(0) as usize;
        format!("{v:.digits$e}")
    } else {
        let decimals = (-step_exp).max(0) as usize;
        format!("{v:.decimals$}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(lo: f64, hi: f64, scale: Scale) -> Vec<String> {
        let t = ticks(lo, hi, scale);
        t.iter().map(|&v| label(v, &t, scale)).collect()
    }

    #[test]
    fn count_axes_are_labelled_with_whole_numbers() {
        assert_eq!(
            labels(-0.5, 10.5, Scale::Count),
            ["0", "2", "4", "6", "8", "10"]
        );
        assert_eq!(labels(-5.0, 105.0, Scale::Count)[..3], ["0", "20", "40"]);
        // A short fit (3 iterations): steps of 1, not 0.5.
        assert_eq!(labels(-0.1, 3.1, Scale::Count), ["0", "1", "2", "3"]);
        for l in labels(0.0, 150.0, Scale::Count) {
            assert!(l.parse::<i64>().is_ok(), "{l} is not an integer");
        }
    }

    #[test]
    fn linear_and_log_labels_are_short_and_few() {
        assert_eq!(
            labels(-20.0, 20.0, Scale::Linear),
            ["-20", "-15", "-10", "-5", "0", "5", "10", "15", "20"][..]
        );
        assert_eq!(labels(0.0, 0.35, Scale::Linear)[..3], ["0", "0.05", "0.10"]);
        assert_eq!(labels(1e-6, 4e-6, Scale::Linear)[..2], ["1.0e-6", "1.5e-6"]);
        assert_eq!(labels(1e-9, 1e-2, Scale::Log)[..2], ["1e-9", "1e-8"]);
        assert_eq!(
            labels(0.02, 0.3, Scale::Log),
            ["0.02", "0.05", "0.1", "0.2"]
        );
        assert_eq!(labels(1e-9, 2e-3, Scale::Log)[6..], ["1e-3"]);
        assert_eq!(labels(4.98, 5.07, Scale::Linear)[..2], ["4.98", "5.00"]);
        for (lo, hi) in [(0.0, 1.0), (-3.3, 7.7), (1e3, 9e5)] {
            let n = ticks(lo, hi, Scale::Linear).len();
            assert!((2..=MAX_TICKS + 1).contains(&n), "{n} ticks on {lo}..{hi}");
        }
    }
}
