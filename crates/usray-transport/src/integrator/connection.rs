//! Receiver connections (paper, "Transducer Sampling"; module docs of
//! [`super`]): the straight line from a vertex to an element's centre, traced
//! through every boundary it crosses, and the MIS weight of an unobstructed one
//! against the vertex's continuation hitting the element directly.

use super::context::PathCtx;
use super::responses::Response;
use super::spreading::Spread;
use super::{Deposit, T_MIN};
use crate::effects::attenuation_and_exponent;
use crate::fresnel::fresnel;
use crate::probe::{along_width, centre3, cos_to_normal};
use crate::thin_layer::frustrated_transmission;
use usray_ad::Real;
use usray_geometry::{MediumStack, Ray, Vec3};

/// Maximum boundaries a receiver connection crosses before it is dropped.
const MAX_CONNECTION_CROSSINGS: usize = 32;

/// Power-heuristic MIS weight (β = 2) of a strategy with density `p` against one
/// with density `q` (Veach 1997, §9.2.3): `p²/(p² + q²)`. Differentiated (the
/// weights of the two strategies sum to one for any parameters, so the estimate
/// stays unbiased and its fixed-seed derivative is exact).
#[inline]
pub(super) fn power_heuristic<T: Real>(p: T, q: T) -> T {
    let (p2, q2) = (p * p, q * q);
    let s = p2 + q2;
    if s.value() > 0.0 && s.is_finite() {
        p2 / s
    } else if p.value().is_infinite() {
        T::one()
    } else {
        T::zero()
    }
}

/// The straight line of a receiver connection (see `PathCtx::link`).
#[derive(Clone, Copy)]
pub(super) struct Link<T> {
    /// Receiving element.
    pub(super) e: usize,
    /// Unit direction towards the element's centre.
    pub(super) wo: Vec3<T>,
    /// Distance to it, metres.
    pub(super) r: T,
}

/// The values of a receiver connection's line that passed the checks of
/// `PathCtx::aim`.
#[derive(Clone, Copy)]
pub(super) struct Aim {
    /// Receiving element.
    pub(super) e: usize,
    /// Unit direction towards the element's centre (values).
    pub(super) wo: Vec3<f64>,
}

/// The unit direction from `p` to the element centre `target` and the
/// distance, in any number type (`PathCtx::aim` in values, `PathCtx::link` in
/// `T`).
#[inline]
fn line<U: Real>(target: Vec3<U>, p: Vec3<U>) -> (Vec3<U>, U) {
    let v = target - p;
    let r = v.length();
    (v * r.recip(), r)
}

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// The line from `p` to element `e`'s centre in values (the values of
    /// [`PathCtx::link`]'s, bit for bit), or `None` when no connection is made:
    /// closer than [`T_MIN`], beyond the element's receive cutoff (where its
    /// directivity is 0), or certainly arriving after the horizon from `time`.
    /// Checked before any `T` arithmetic, which rejected connections then skip.
    #[inline]
    pub(super) fn aim(&self, p: Vec3<f64>, e: usize, time: f64) -> Option<Aim> {
        let st = self.st;
        let el = &st.elements[e];
        let (wo, r) = line(centre3(el).to_f64(), p);
        let n = [el.normal[0].value(), el.normal[1].value()];
        let facing = cos_to_normal(st.array.kind, &n, wo);
        if r <= T_MIN || !self.receiver.may_receive(-facing) || self.late(time, r) {
            return None;
        }
        Some(Aim { e, wo })
    }

    /// The straight line from `p` to the element of `aim` in `T`.
    #[inline]
    pub(super) fn link(&self, p: Vec3<T>, aim: &Aim) -> Link<T> {
        let (wo, r) = line(centre3(&self.st.elements[aim.e]), p);
        Link { e: aim.e, wo, r }
    }

    /// Receiver connection from `p` along `link` (medium stack `stack` on the
    /// side the connection leaves into) with scattering factor `f_cos` (1/sr)
    /// and path amplitude `w` and attenuation exponent `beta` at time `tau`,
    /// estimator weight `sel_w` (see
    /// [`TraceSettings::receivers`](super::TraceSettings::receivers)). `p_bsdf`
    /// is the density (1/sr) with which the vertex's own continuation sampling
    /// would produce the connection direction: an unobstructed connection is
    /// then MIS-weighted against a direct array hit of that continuation.
    /// `tube` is the 2-D ray tube leaving `p` towards the element (`None` in
    /// 3-D): the deposit takes its pressure factor at the element
    /// ([`super::spreading`]; boundaries the line crosses are crossed
    /// straight, as by the amplitude). Volume scatterers connect through
    /// [`PathCtx::scatterer_response`] instead.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn connect(
        &mut self,
        p: Vec3<T>,
        stack: MediumStack,
        w: T,
        beta: T,
        f_cos: T,
        tau: T,
        link: &Link<T>,
        sel_w: f64,
        p_bsdf: T,
        tube: Option<Spread<T>>,
    ) {
        if f_cos.value() == 0.0 {
            return;
        }
        let Some((cos_e, fd)) = self.directivity(link) else {
            return;
        };
        let Some(line) = self.cross(p, stack, link, w * f_cos, beta, tau) else {
            return;
        };
        let Link { e, r, .. } = *link;
        let solid = self.st.element_measure(cos_e, r * r);
        // Unobstructed: the continuation could have hit the element too.
        let mis = if line.unobstructed && p_bsdf.value() > 0.0 {
            power_heuristic((solid.scale(sel_w)).recip(), p_bsdf)
        } else {
            T::one()
        };
        let mut a = line.amplitude * solid * fd.scale(sel_w) * mis;
        if let Some(tube) = tube {
            a *= tube.advanced(r).pressure_factor();
        }
        self.deposit(e, a, line.beta, line.time);
    }

    /// The response of a volume scatterer at `p` (medium stack `stack`) on
    /// the element of `link` ([`super::responses`]): what the line to the
    /// element does to an echo of unit amplitude leaving `p` at time 0 — its
    /// boundary transmissions, attenuation, the element's solid angle and
    /// directivity and, in a planar scene, the spreading of the point source
    /// the scatterer is (the incident tube's factor is the event's). `None`
    /// where the connection is blocked.
    pub(super) fn scatterer_response(
        &mut self,
        p: Vec3<T>,
        stack: MediumStack,
        link: &Link<T>,
    ) -> Option<Response<T>> {
        let (cos_e, fd) = self.directivity(link)?;
        let line = self.cross(p, stack, link, T::one(), T::zero(), T::zero())?;
        let r = link.r;
        let mut amplitude = line.amplitude * self.st.element_measure(cos_e, r * r) * fd;
        if self.st.planar {
            amplitude *= Spread::point_source().advanced(r).pressure_factor();
        }
        Some(Response {
            amplitude,
            beta: line.beta,
            time: line.time,
        })
    }

    /// The cosine at the element of `link` and its receive directivity there,
    /// or `None` where the directivity is 0.
    fn directivity(&self, link: &Link<T>) -> Option<(T, T)> {
        let st = self.st;
        let normal = &st.elements[link.e].normal;
        let cos_e = -cos_to_normal(st.array.kind, normal, link.wo);
        let fd = self
            .receiver
            .eval(cos_e, || along_width(st.array.kind, normal, link.wo));
        (fd.value() != 0.0).then_some((cos_e, fd))
    }

    /// The straight line of `link` from `p` (medium stack `stack`) traced
    /// through every boundary it crosses, for an echo of amplitude `amp`,
    /// attenuation exponent `beta` and time `tau` at `p`: the echo at the
    /// element, or `None` where a crossing reflects totally or the line
    /// crosses more than [`MAX_CONNECTION_CROSSINGS`] boundaries.
    fn cross(
        &mut self,
        p: Vec3<T>,
        mut stack: MediumStack,
        link: &Link<T>,
        mut amp: T,
        mut beta: T,
        tau: T,
    ) -> Option<Crossed<T>> {
        let st = self.st;
        let Link { wo, r, .. } = *link;
        let mut time = tau;
        let mut origin = p;
        let mut remaining = r;
        for crossing in 0..MAX_CONNECTION_CROSSINGS {
            let medium = *st.medium_of(stack.top());
            let hit = self.intersect(&Ray::new(origin, wo), remaining.value() - T_MIN);
            let Some(hit) = hit else {
                time += remaining / medium.sound_speed;
                let (k, b) = attenuation_and_exponent(
                    medium.attenuation_db_cm_mhz,
                    st.center_frequency,
                    remaining,
                );
                return Some(Crossed {
                    amplitude: amp * k,
                    beta: beta + b,
                    time,
                    unobstructed: crossing == 0,
                });
            };
            time += hit.t / medium.sound_speed;
            let (k, b) =
                attenuation_and_exponent(medium.attenuation_db_cm_mhz, st.center_frequency, hit.t);
            amp *= k;
            beta += b;
            remaining -= hit.t;
            let entering = hit.entering(&wo);
            let other = if entering {
                st.objects[hit.object].material
            } else {
                *st.medium_of(stack.after_exit(hit.object))
            };
            let cos_i = wo.dot(hit.normal).abs();
            let f = fresnel(
                cos_i,
                medium.sound_speed,
                other.sound_speed,
                medium.impedance,
                other.impedance,
            );
            if f.tir {
                // Beyond the critical angle only a thin layer with this medium
                // on its far side lets the line through, where the scene asks
                // for it (`thin_layer`): it resumes on the far surface, the
                // stack as it was.
                let d = st.tunnelling_layer(hit.object, entering)?;
                let t2 = frustrated_transmission(
                    cos_i,
                    medium.sound_speed,
                    other.sound_speed,
                    medium.impedance,
                    other.impedance,
                    d,
                    st.center_frequency,
                )?;
                if t2.value() <= 0.0 {
                    return None;
                }
                amp *= t2.safe_sqrt();
                let step = hit.normal * -d;
                remaining -= step.dot(wo);
                origin = hit.point + step;
                continue;
            }
            amp *= f.t;
            stack.cross(hit.object, entering);
            origin = hit.point;
        }
        None
    }
}

/// An echo at the element, after [`PathCtx::cross`].
struct Crossed<T> {
    amplitude: T,
    beta: T,
    time: T,
    /// The line crossed no boundary.
    unobstructed: bool,
}
