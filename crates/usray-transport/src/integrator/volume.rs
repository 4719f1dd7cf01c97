//! Volume scattering along a segment (step 3a of the module docs of
//! [`super`]): free-flight events at the rate of the medium's scatterer grid,
//! each scatterer connected to the receivers.

use super::context::PathCtx;
use super::Deposit;
use crate::effects::{attenuation_and_exponent, ScattererField};
use crate::rng::{dim, PathSampler};
use crate::scene::MaterialT;
use usray_ad::Real;
use usray_geometry::{MediumStack, Ray, Vec3};

/// Maximum volume-scattering events per segment (bounds the work; at most
/// densities the expected count is far below).
const MAX_VOLUME_EVENTS: u32 = 256;

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// Volume scatterers along a segment of length `len` from `origin` along `dir`
    /// in `medium` (inside object `obj`), path amplitude `w`, attenuation
    /// exponent `beta` and time `tau` at origin.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn volume(
        &mut self,
        obj: usize,
        medium: &MaterialT<T>,
        stack: MediumStack,
        origin: Vec3<T>,
        dir: Vec3<T>,
        len: f64,
        w: T,
        beta: T,
        tau: T,
        sampler: &PathSampler,
        bounce: u32,
    ) {
        let Some(field) = ScattererField::new(obj, medium.scatterer_density_per_mm3.value()) else {
            return;
        };
        if medium.scatterer_strength.value() == 0.0 {
            return;
        }
        // √(ρ/ρ_g)·(1 mm/h)²: the density's (differentiable) share of each
        // event's amplitude, and the cell's cross-section (see ScattererField).
        let density_weight = field.event_weight(medium.scatterer_density_per_mm3);
        let mu = 1.0 / field.cell_m;
        let mut s = 0.0;
        for k in 0..MAX_VOLUME_EVENTS {
            let u = sampler.uniform(bounce, dim::VOLUME_BASE + 2 * k);
            s += -(1.0 - u).ln() / mu;
            if s >= len {
                return;
            }
            let on_line = origin.to_f64() + dir.to_f64().scale(s);
            let (q, g) = field.scatterer_near::<T>(on_line.value());
            // Time at the scatterer: along the ray to its projection, then across.
            let along = (q - origin).dot(dir);
            let t_q = tau + along / medium.sound_speed;
            let (k_q, b_q) = attenuation_and_exponent(
                medium.attenuation_db_cm_mhz,
                self.st.center_frequency,
                along,
            );
            let (a_q, beta_q) = (w * k_q, beta + b_q);
            let f = (medium.scatterer_strength * density_weight)
                .scale(g / (4.0 * core::f64::consts::PI));
            let ue = sampler.uniform(bounce, dim::VOLUME_BASE + 2 * k + 1);
            let settings = self.settings;
            for (e, sel_w) in settings.receivers(self.st.n_elements, ue) {
                if let Some(aim) = self.aim(q.to_f64(), e, t_q.value()) {
                    let link = self.link(q, &aim);
                    self.connect(q, stack, a_q, beta_q, f, t_q, &link, sel_w, T::zero());
                }
            }
        }
    }
}
