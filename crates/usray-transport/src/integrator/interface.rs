//! Step 5 of the path loop: a branch meets an interface. A rough interface
//! connects to the receivers (5a); every interface splits the branch into its
//! reflected and transmitted continuations (5b).

use super::branch::Branch;
use super::context::PathCtx;
use super::{Deposit, MIN_BRANCH_AMPLITUDE};
use crate::ggx::{Interface, SMOOTH_ALPHA};
use crate::rng::dim;
use crate::scene::MaterialT;
use crate::thin_layer::Layer;
use usray_ad::Real;
use usray_geometry::{Hit, Ray, Vec3};

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// Step 5: branch `b`, arrived at `hit` through `medium` (its amplitude,
    /// attenuation exponent and time taken at the hit), meets the interface
    /// there; its continuations are pushed onto `pending`.
    #[inline]
    pub(super) fn interact(
        &mut self,
        b: Branch<T>,
        medium: &MaterialT<T>,
        hit: &Hit<T>,
        pending: &mut Vec<Branch<T>>,
    ) {
        let st = self.st;
        let settings = self.settings;
        let n_el = st.n_elements;
        let Branch {
            dir,
            w,
            beta,
            time,
            stack,
            specular_chain,
            rough_vertices,
            spread,
            bounce,
            sampler,
            ..
        } = b;
        // Step 5: the interface between the current medium and the other side.
        let entering = hit.entering(&dir);
        let other = if entering {
            st.objects[hit.object].material
        } else {
            *st.medium_of(stack.after_exit(hit.object))
        };
        let iface = Interface {
            c1: medium.sound_speed,
            c2: other.sound_speed,
            z1: medium.impedance,
            z2: other.impedance,
            alpha: st.objects[hit.object].material.roughness,
            planar: st.planar,
        };
        let n_inc = if entering { hit.normal } else { -hit.normal };
        // In 2-D the surface is its cut at y = 0: its normal in the plane.
        let n_inc = if st.planar {
            Vec3::new(n_inc.x, T::zero(), n_inc.z).normalize()
        } else {
            n_inc
        };
        let wi = -dir;
        // In 2-D, the ray tube's reflection and refraction here (see
        // `spreading`), with the surface's curvature as seen from `wi`.
        let tube_after = spread.map(|tube| {
            let kappa = st.geometry.in_plane_curvature(hit);
            let kappa = if entering { kappa } else { -kappa };
            move |wo: Vec3<T>, reflected: bool| {
                if reflected {
                    tube.reflected(wi, wo, kappa)
                } else {
                    tube.refracted(wi, wo, iface.c1, iface.c2, kappa)
                }
            }
        });

        // The rough interface as seen from `wi`: BSDF and density terms shared by
        // every receiver connection and both continuations of this vertex.
        let incident = (iface.alpha.value() >= SMOOTH_ALPHA).then(|| iface.incident(wi, n_inc));

        // Step 5a: receiver connection from a rough interface.
        if let Some(inc) = &incident {
            let ue = sampler.uniform(bounce, dim::ELEMENT);
            let (p_v, n_v, time_v) = (hit.point.to_f64(), n_inc.to_f64(), time.value());
            for (e, sel_w) in settings.receivers(n_el, ue) {
                let Some(aim) = self.aim(p_v, e, time_v) else {
                    continue;
                };
                let transmitted = aim.wo.dot(n_v) < 0.0;
                if rough_vertices > 0 && transmitted {
                    // Transmission-side arrival after an earlier rough vertex:
                    // already counted by that vertex's connection through this
                    // boundary (`integrator` module docs, "Double counting").
                    continue;
                }
                let link = self.link(hit.point, &aim);
                let (f_cos, p_b) = inc.eval_pdf(link.wo);
                if f_cos.value() != 0.0 {
                    // The connection leaves into the incident medium (reflection)
                    // or the other one (transmission).
                    let mut cstack = stack;
                    if transmitted {
                        cstack.cross(hit.object, entering);
                    }
                    let tube = tube_after.map(|after| after(link.wo, !transmitted));
                    self.connect(
                        hit.point, cstack, w, beta, f_cos, time, &link, sel_w, p_b, tube,
                    );
                }
            }
        }

        // Step 5b: split into the reflected and the transmitted continuation.
        // Entering a layer (a tube's wall, a slab) whose far side holds the
        // medium the branch is in, a wave beyond the critical angle tunnels
        // through it in part where the scene asks for it (`thin_layer`).
        let layer = st
            .tunnelling_layer(hit.object, entering)
            .map(|thickness_m| Layer {
                thickness_m,
                frequency_hz: st.center_frequency,
            });
        let Some(s) = iface.scatter_through(
            wi,
            n_inc,
            sampler.uniform(bounce, dim::GGX_U1),
            sampler.uniform(bounce, dim::GGX_U2),
            layer,
        ) else {
            return;
        };
        let rough = !s.specular;
        for (branch, lobe, reflected) in [(1, s.transmitted, false), (0, s.reflected, true)] {
            let Some(lobe) = lobe else { continue };
            let w_child = w * lobe.weight;
            if !w_child.is_finite() || w_child.value().abs() < MIN_BRANCH_AMPLITUDE {
                continue;
            }
            let tunnelled = !reflected && s.tunnelled;
            let mut child_stack = stack;
            if !reflected && !tunnelled {
                child_stack.cross(hit.object, entering);
            }
            // A tunnelled branch leaves from the layer's far surface, the
            // thickness along the inward normal, in the medium it came from
            // (crossing the wall in and out leaves the stack as it was); the
            // evanescent crossing takes no time and leaves its tube as it was.
            let origin = match layer.filter(|_| tunnelled) {
                Some(l) => hit.point - n_inc * l.thickness_m,
                None => hit.point,
            };
            let spread = if tunnelled {
                spread
            } else {
                tube_after.map(|after| after(lobe.wo, reflected))
            };
            pending.push(Branch {
                origin,
                dir: lobe.wo,
                w: w_child,
                beta,
                time,
                stack: child_stack,
                specular_chain: specular_chain && !rough,
                last_rough: incident
                    .as_ref()
                    .filter(|_| rough && !tunnelled && (reflected || rough_vertices == 0))
                    .map(|inc| inc.eval_pdf(lobe.wo).1),
                rough_vertices: rough_vertices + u32::from(rough),
                spread,
                bounce: bounce + 1,
                sampler: sampler.branch(branch),
            });
        }
    }
}
