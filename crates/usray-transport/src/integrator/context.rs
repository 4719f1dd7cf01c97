//! `PathCtx`: the state shared by the steps of one path, how it casts a ray
//! and how it deposits an echo.

use super::horizon::Horizon;
use super::responses::Responses;
use super::settings::TraceSettings;
use super::{Deposit, TraceCounters, T_MIN};
use crate::effects::depth_gain;
use crate::probe::Receiver;
use crate::scene::SceneT;
use usray_ad::Real;
use usray_geometry::{Hit, Ray};

/// State shared by the steps of one path.
pub(super) struct PathCtx<'a, T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> {
    pub(super) st: &'a SceneT<T>,
    pub(super) settings: &'a TraceSettings,
    pub(super) norm: T,
    /// The largest down-shift placed, in `σ_f` ([`SceneT::max_shift`]).
    pub(super) max_shift: f64,
    /// The elements' receive directivity.
    pub(super) receiver: Receiver<T>,
    /// Deposits from this time on are dropped by the caller (`None`: keep all).
    pub(super) horizon: Option<Horizon>,
    pub(super) counters: TraceCounters,
    /// The volume scatterers' receiver responses traced so far (shared by the
    /// paths of a chunk, [`super::responses`]).
    pub(super) responses: &'a mut Responses<T>,
    pub(super) out: F,
    pub(super) cast: C,
}

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// Cast `ray` through the scene (`t ∈ [T_MIN, t_max]`): counted, reported to
    /// the `cast` hook, then [`usray_geometry::Geometry::intersect`].
    #[inline(always)]
    pub(super) fn intersect(&mut self, ray: &Ray<T>, t_max: f64) -> Option<Hit<T>> {
        self.counters.rays += 1;
        (self.cast)(ray, T_MIN, t_max);
        self.st.geometry.intersect(ray, T_MIN, t_max)
    }

    /// Deposit on element `e` an echo of amplitude `a` (attenuated at `f_c`)
    /// whose path has the attenuation exponent `beta` (Np/Hz), at time `tau`:
    /// applies the depth gain, the `1/rays` norm and the down-shift's
    /// amplitude factor `e^{x²/2}`, `x = −βσ_f` ([`crate::downshift`]).
    pub(super) fn deposit(&mut self, e: usize, a: T, beta: T, tau: T) {
        let st = self.st;
        let g = depth_gain(st.depth_gain_db_per_cm, st.imaging_sound_speed, tau);
        // Beyond the model's largest shift (`downshift::max_shift`) the echo is
        // placed at it, and its factor is taken there (bounded by e^{s²/2}).
        let shift = (-(beta * st.pulse_bandwidth)).max(T::from_f64(-self.max_shift));
        let mut amplitude = a * g * self.norm;
        if shift.value() != 0.0 {
            // At x = 0 the factor is 1 with zero derivative: skipped.
            amplitude *= (shift * shift).scale(0.5).exp();
        }
        if amplitude.value() == 0.0 || !amplitude.is_finite() || !tau.is_finite() {
            return;
        }
        self.counters.deposits += 1;
        (self.out)(Deposit {
            element: e as u32,
            amplitude,
            time: tau,
            shift,
        });
    }
}
