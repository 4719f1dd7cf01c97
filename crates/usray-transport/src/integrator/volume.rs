//! Volume scattering along a segment (step 3a of the module docs of
//! [`super`]): free-flight events at the rate of a scatterer grid, each
//! scatterer connected to the receivers through its responses, traced once
//! per chunk of paths ([`super::responses`]). Two kinds of field: an object's
//! material's, along a segment inside the object, and a hollow cylinder's
//! lumen's, along the part of a segment that crosses the lumen.

use super::context::PathCtx;
use super::responses::ScattererKey;
use super::spreading::Spread;
use super::Deposit;
use crate::effects::{attenuation_and_exponent, ScattererField};
use crate::rng::{dim, PathSampler};
use crate::scene::MaterialT;
use usray_ad::Real;
use usray_geometry::{MediumStack, Ray, Vec3};

/// Maximum volume-scattering events per segment (bounds the work; at most
/// densities the expected count is far below).
const MAX_VOLUME_EVENTS: u32 = 256;

/// A field of scatterers met along a segment: its grid and, in `T`, the
/// density and strength that weight each event.
pub(super) struct Scatterers<T> {
    pub field: ScattererField,
    pub density_per_mm3: T,
    pub strength: T,
}

impl<T: Real> Scatterers<T> {
    /// The field of `key` with `density_per_mm3` and `strength`, or `None` when
    /// either is zero (no events); cut at `y = 0` when `planar`.
    pub fn new(key: u64, density_per_mm3: T, strength: T, planar: bool) -> Option<Self> {
        if strength.value() == 0.0 {
            return None;
        }
        let field = ScattererField::keyed(key, density_per_mm3.value())?;
        let field = if planar { field.planar() } else { field };
        Some(Self {
            field,
            density_per_mm3,
            strength,
        })
    }
}

/// Where a segment runs: its medium (speed and attenuation), the medium stack
/// and the span `[s₀, s₁]` (m along `dir` from `origin`) the field fills.
pub(super) struct Span<'a, T> {
    pub medium: &'a MaterialT<T>,
    pub stack: MediumStack,
    pub origin: Vec3<T>,
    pub dir: Vec3<T>,
    pub s: (f64, f64),
    /// The 2-D ray tube at `origin` (`None` in 3-D).
    pub spread: Option<Spread<T>>,
}

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// The scatterers of `src` along `span`, path amplitude `w`, attenuation
    /// exponent `beta` and time `tau` at the segment's origin.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn volume(
        &mut self,
        src: &Scatterers<T>,
        span: &Span<'_, T>,
        w: T,
        beta: T,
        tau: T,
        sampler: &PathSampler,
        bounce: u32,
    ) {
        let Span {
            medium,
            stack,
            origin,
            dir,
            s: (s0, s1),
            spread,
        } = *span;
        let field = &src.field;
        // √(ρ/ρ_g)·(1 mm/h)²: the density's (differentiable) share of each
        // event's amplitude, and the cell's cross-section (see ScattererField).
        let density_weight = field.event_weight(src.density_per_mm3);
        let mu = 1.0 / field.cell_m;
        let mut s = s0;
        for k in 0..MAX_VOLUME_EVENTS {
            let u = sampler.uniform(bounce, dim::VOLUME_BASE + 2 * k);
            s += -(1.0 - u).ln() / mu;
            if s >= s1 {
                return;
            }
            let on_line = origin.to_f64() + dir.to_f64().scale(s);
            let cell = field.cell_of(on_line.value());
            let (q, g) = field.scatterer_in::<T>(cell);
            // Time at the scatterer: along the ray to its projection, then across.
            let along = (q - origin).dot(dir);
            let t_q = tau + along / medium.sound_speed;
            let (k_q, b_q) = attenuation_and_exponent(
                medium.attenuation_db_cm_mhz,
                self.st.center_frequency,
                along,
            );
            let (a_q, beta_q) = (w * k_q, beta + b_q);
            let f = (src.strength * density_weight).scale(g / field.full_angle());
            // A scatterer is a new point source lit by the tube at `q`: its echo
            // carries the incident tube's pressure factor.
            let tube = spread.map(|sp| sp.advanced(along));
            let ue = sampler.uniform(bounce, dim::VOLUME_BASE + 2 * k + 1);
            let settings = self.settings;
            // What reached the scatterer, times each element's response.
            let lit = a_q * f;
            if lit.value() == 0.0 {
                continue;
            }
            let lit = match tube {
                Some(tube) => lit * tube.pressure_factor(),
                None => lit,
            };
            let n_el = self.st.n_elements;
            let slots = self.responses.scatterer(
                ScattererKey {
                    field: field.key,
                    cell,
                    stack,
                },
                n_el,
            );
            for (e, sel_w) in settings.receivers(n_el, ue) {
                let known = slots.and_then(|at| self.responses.get(at + e));
                let response = match known {
                    Some(response) => response,
                    None => {
                        let Some(aim) = self.aim(q.to_f64(), e, t_q.value()) else {
                            continue;
                        };
                        let traced = self.scatterer_response(q, stack, &self.link(q, &aim));
                        if let Some(at) = slots {
                            self.responses.set(at + e, traced);
                        }
                        traced
                    }
                };
                if let Some(r) = response {
                    self.deposit(
                        e,
                        lit * r.amplitude.scale(sel_w),
                        beta_q + r.beta,
                        t_q + r.time,
                    );
                }
            }
        }
    }
}
