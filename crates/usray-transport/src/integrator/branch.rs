//! [`Branch`], what the path loop carries from vertex to vertex, and the trace
//! of one branch to its next interaction (steps 2–5 of the module docs of
//! [`super`]: 3b and 5 in their own files).

use super::context::PathCtx;
use super::spreading::Spread;
use super::volume::{Scatterers, Span};
use super::Deposit;
use crate::effects::{attenuation_and_exponent, ScattererField};
use crate::probe::{array_surface_t, distance_bound_m};
use crate::rng::PathSampler;
use usray_ad::Real;
use usray_geometry::{MediumStack, Ray, Vec3};

/// One branch of a path: what the path loop carries from vertex to vertex. A
/// split interaction (reflection and transmission) continues as two branches.
#[derive(Clone, Copy)]
pub(super) struct Branch<T> {
    pub(super) origin: Vec3<T>,
    pub(super) dir: Vec3<T>,
    /// Path amplitude so far.
    pub(super) w: T,
    /// Attenuation exponent so far, Np/Hz
    /// ([`attenuation_exponent`](crate::effects::attenuation_exponent)).
    pub(super) beta: T,
    /// Time stamp at `origin`, s.
    pub(super) time: T,
    pub(super) stack: MediumStack,
    /// Every interaction so far was a delta lobe.
    pub(super) specular_chain: bool,
    /// Density (1/sr) of the continuation sampled at the previous vertex when it
    /// was rough and is the last interaction so far (for the MIS'd direct hit).
    pub(super) last_rough: Option<T>,
    /// Rough vertices so far (connections through boundaries cover later
    /// transmissions; see the `integrator` module docs).
    pub(super) rough_vertices: u32,
    /// The 2-D ray tube at `origin` (`None` in 3-D; see [`super::spreading`]).
    pub(super) spread: Option<Spread<T>>,
    /// Index of the vertex this branch is heading to (1 = first interaction).
    pub(super) bounce: u32,
    /// Random numbers of this branch (keyed by the branch choices so far).
    pub(super) sampler: PathSampler,
}

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// Trace `branch` to its next interaction (steps 2–5 of the `integrator`
    /// module docs) and push its continuations onto `pending`.
    #[inline]
    pub(super) fn trace_branch(&mut self, branch: Branch<T>, pending: &mut Vec<Branch<T>>) {
        let st = self.st;
        let settings = self.settings;
        let Branch {
            origin,
            dir,
            mut w,
            mut beta,
            mut time,
            stack,
            spread,
            bounce,
            sampler,
            ..
        } = branch;
        let medium = *st.medium_of(stack.top());
        // Step 2: the next interface.
        let r = Ray::new(origin, dir);
        let hit = self.intersect(&r, f64::INFINITY);
        // The array's surface (the plane z = 0 or a convex arc), if reached.
        let t_array = array_surface_t(&st.array, origin, dir);
        let hit_first = hit.as_ref().is_some_and(|h| h.t.value() < t_array.value());
        let seg_len = match (&hit, hit_first) {
            (Some(h), true) => h.t.value(),
            _ => t_array.value(),
        };

        // Step 3a: volume scatterers along the segment — the material's, inside
        // an object, and those of any lumen the segment crosses in the medium
        // that fills it.
        if seg_len.is_finite() {
            let span = |s| Span {
                medium: &medium,
                stack,
                origin,
                dir,
                s,
                spread,
            };
            if let Some(obj) = stack.top() {
                let src = Scatterers::new(
                    ScattererField::material_key(obj),
                    medium.scatterer_density_per_mm3,
                    medium.scatterer_strength,
                    st.planar,
                );
                if let Some(src) = src {
                    self.volume(&src, &span((0.0, seg_len)), w, beta, time, &sampler, bounce);
                }
            }
            for lumen in st.lumens.iter().filter(|l| l.enclosing == stack.top()) {
                let Some(s) = lumen.chord(origin.value(), dir.value(), seg_len) else {
                    continue;
                };
                let src = Scatterers::new(
                    ScattererField::lumen_key(lumen.object),
                    lumen.scatterer_density_per_mm3,
                    lumen.scatterer_strength,
                    st.planar,
                );
                if let Some(src) = src {
                    self.volume(&src, &span(s), w, beta, time, &sampler, bounce);
                }
            }
        }

        let Some(hit) = hit.filter(|_| hit_first) else {
            // Step 3b: escape, or arrival at the array's surface.
            self.arrive(branch, &medium, &r, t_array);
            return;
        };

        // Step 4: advance to the interface.
        time += hit.t / medium.sound_speed;
        let (k, b) =
            attenuation_and_exponent(medium.attenuation_db_cm_mhz, st.center_frequency, hit.t);
        w *= k;
        beta += b;
        if bounce > settings.max_bounces {
            return;
        }
        // Whatever this vertex and its continuations deposit still has to reach
        // the array, at least `distance_bound_m` away: past the horizon, none
        // of it would be kept.
        let to_array = distance_bound_m(&st.array, hit.point.z.value());
        if self.vertex_late(time.value(), to_array) {
            return;
        }

        // Step 5, with the amplitude, exponent and time at the interface.
        self.interact(
            Branch {
                w,
                beta,
                time,
                spread: spread.map(|sp| sp.advanced(hit.t)),
                ..branch
            },
            &medium,
            &hit,
            pending,
        );
    }
}
