//! Step 3b of the path loop: a branch that reaches the array's surface before
//! any interface deposits on the element it lands on, MIS-weighted against the
//! receiver connection of its last rough vertex.

use super::branch::Branch;
use super::connection::power_heuristic;
use super::context::PathCtx;
use super::Deposit;
use crate::effects::attenuation_and_exponent;
use crate::probe::{along_width, centre3, cos_to_normal, element_at};
use crate::scene::MaterialT;
use usray_ad::Real;
use usray_geometry::Ray;

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// Step 3b: branch `b` (its ray `r`, in `medium`) meets no interface
    /// before the array's surface at distance `t_array` (infinite: it
    /// escapes). Outside every object, it deposits on the element it lands on
    /// if its interactions so far were all smooth or its last one was rough
    /// (the `integrator` module docs, "Double counting and MIS").
    #[inline]
    pub(super) fn arrive(&mut self, b: Branch<T>, medium: &MaterialT<T>, r: &Ray<T>, t_array: T) {
        let st = self.st;
        let settings = self.settings;
        let n_el = st.n_elements;
        let Branch {
            origin,
            dir,
            w,
            beta,
            time,
            stack,
            specular_chain,
            last_rough,
            spread,
            ..
        } = b;
        let direct = specular_chain || last_rough.is_some();
        if t_array.value().is_finite() && direct && stack.is_empty() {
            let p = r.at(t_array);
            let pv = p.value();
            if let Some(e) = element_at(&st.array, st.elevation, pv) {
                let element = &st.elements[e];
                // After a rough vertex: MIS against its receiver connection
                // (density 1/(sel_w·Ω_e) of the element's solid angle, or angle in 2-D).
                let mis = match last_rough {
                    Some(p_b) if !specular_chain => {
                        let v = centre3(element) - origin;
                        let r2 = v.length_squared();
                        let cos_e = -cos_to_normal(st.array.kind, &element.normal, v) / r2.sqrt();
                        let solid = st.element_measure(cos_e, r2);
                        let sel_w = settings.receiver_weight(n_el, e);
                        power_heuristic(p_b, solid.scale(sel_w).recip())
                    }
                    _ => T::one(),
                };
                let fd = self
                    .receiver
                    .eval(-cos_to_normal(st.array.kind, &element.normal, dir), || {
                        along_width(st.array.kind, &element.normal, dir)
                    });
                let tau = time + t_array / medium.sound_speed;
                let (k, b) = attenuation_and_exponent(
                    medium.attenuation_db_cm_mhz,
                    st.center_frequency,
                    t_array,
                );
                let mut a = w * fd * mis * k;
                if let Some(tube) = spread {
                    a *= tube.advanced(t_array).pressure_factor();
                }
                self.deposit(e, a, beta + b, tau);
            }
        }
    }
}
