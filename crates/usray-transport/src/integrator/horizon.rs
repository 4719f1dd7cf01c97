//! [`Horizon`]: the end of the recorded time window, and the checks that let a
//! path skip the work that could only deposit after it.

use super::context::PathCtx;
use super::Deposit;
use crate::effects::ScattererField;
use crate::plan::SampleGrid;
use crate::scene::SceneT;
use usray_ad::Real;
use usray_geometry::Ray;

/// The end of the recorded time window: deposits arriving at `τ ≥ end` are
/// dropped by the caller (past the last sample of a record), so a trace may
/// skip what can only deposit that late (`PathCtx::late`). The renderer and the
/// gradient replay set it; the public per-path functions do not (they report
/// every deposit).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Horizon {
    /// Time (s) from which deposits are dropped.
    end: f64,
    /// The largest sound speed of the scene's media (m/s): no path or
    /// connection covers a distance `d` in less than `d / c_max`.
    c_max: f64,
    /// How much earlier (s) than that bound a deposit through a volume
    /// scatterer can arrive (0 without volume scattering): see
    /// `PathCtx::vertex_late`.
    volume_slack: f64,
}

impl Horizon {
    /// The window of records on `grid` for the media of `st`, or `None` when
    /// it cannot be bounded (no finite positive sound speed). The end is
    /// pushed out by a relative 10⁻⁹ so that rounding of the traced times
    /// (≈ 10⁻¹⁵ relative) can never skip a deposit that would land in the
    /// record.
    pub(crate) fn of<T: Real>(st: &SceneT<T>, grid: &SampleGrid) -> Option<Self> {
        let (n_samples, t0, fs) = (grid.n_samples, grid.t0_s, grid.fs_hz);
        let speeds = || {
            std::iter::once(&st.medium)
                .chain(st.objects.iter().map(|o| &o.material))
                .map(|m| m.sound_speed.value())
        };
        let c_max = speeds().fold(f64::NEG_INFINITY, f64::max);
        let c_min = speeds().fold(f64::INFINITY, f64::min);
        // A volume scatterer lies in the cell of the point on the ray that
        // selected it: at most `δ = √3·h` (the cell's diagonal) from it.
        let delta = st
            .objects
            .iter()
            .map(|o| o.material.scatterer_density_per_mm3.value())
            .chain(
                st.lumens
                    .iter()
                    .map(|l| l.scatterer_density_per_mm3.value()),
            )
            .filter_map(|density| ScattererField::new(0, density))
            .map(|f| 3f64.sqrt() * f.cell_m)
            .fold(0.0, f64::max);
        let volume_slack = 2.0 * delta / c_max + delta / c_min;
        let end = t0 + n_samples as f64 / fs * (1.0 + 1e-9);
        let ok = c_min > 0.0 && c_max.is_finite() && volume_slack.is_finite() && end.is_finite();
        ok.then_some(Self {
            end,
            c_max,
            volume_slack,
        })
    }
}

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// True when every deposit a path at `time` (s) can still make after
    /// covering at least `dist` metres arrives after the horizon, i.e. would be
    /// dropped: that takes at least `dist / c_max` (shortened by a relative 10⁻⁹
    /// for rounding, see [`Horizon::of`]).
    #[inline]
    pub(super) fn late(&self, time: f64, dist: f64) -> bool {
        self.horizon
            .is_some_and(|h| time + dist / h.c_max * (1.0 - 1e-9) >= h.end)
    }

    /// True when nothing a vertex at `time` and `depth` (m) and its
    /// continuations can deposit arrives before the horizon. Its connections
    /// and everything after it travel at least `depth` back to the array plane
    /// (triangle inequality), except deposits through a volume scatterer, which
    /// sits up to `δ` off the ray that selected it: with `c_min` the smallest
    /// speed, such a deposit arrives no earlier than
    /// `time + (depth − 2δ)/c_max − δ/c_min` (`Horizon::volume_slack`).
    #[inline]
    pub(super) fn vertex_late(&self, time: f64, depth: f64) -> bool {
        self.horizon
            .is_some_and(|h| self.late(time - h.volume_slack, depth))
    }
}
