//! GGX (Trowbridge–Reitz) microfacet interface: rough reflection **and**
//! transmission between two fluids, sampled from the distribution of visible
//! normals and evaluated for receiver connections.
//!
//! Sources:
//! - normal distribution `D(h) = α² / (π ((n·h)²(α² − 1) + 1)²)`: paper eq. `GGX_PDF`
//!   (Walter, Marschner, Li & Torrance 2007, "Microfacet models for refraction
//!   through rough surfaces", eq. 33), `α` = the material's `roughness`;
//! - Smith `Λ(ω) = (−1 + √(1 + α² tan²θ))/2`, `G1 = 1/(1 + Λ)`, height-correlated
//!   `G2 = 1/(1 + Λ(i) + Λ(o))` (Heitz 2014, "Understanding the masking-shadowing
//!   function", eq. 99);
//! - visible-normal sampling with density `D_i(h) = G1(i) max(0, i·h) D(h) / (i·n)`
//!   (Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4),
//!   eq. 2), drawn by the spherical-cap method (Dupuy & Benyoub 2023);
//! - reflection `f_r = F·D·G2 / (4 |i·n| |o·n|)`, transmission
//!   `f_t = |i·h||o·h|/(|i·n||o·n|) · η_o² (1−F)·D·G2 / (η_i (i·h) + η_o (o·h))²`
//!   (Walter 2007 eqs. 20 and 21) with the refractive index of a medium taken as
//!   `η = 1/c` (so Snell is `sin θt = (c2/c1) sin θi`), and the half-vector
//!   Jacobians `1/(4|o·h|)` and `η_o²|o·h|/(η_i(i·h) + η_o(o·h))²` (Walter eqs. 14, 17).
//!
//! The Fresnel factor is the acoustic **pressure amplitude** of [`crate::fresnel`]:
//! `F → R` for reflection and `(1 − F) → T = 1 + R` for transmission, evaluated at
//! the microfacet normal. An interaction **splits** into both continuations
//! (reflection with weight `R·G2/G1`, transmission with `T·G2/G1`) instead of
//! choosing one with probability `R²`: see [`Interface::scatter`].
//!
//! Conventions: `wi` points *away* from the surface into the incident medium
//! (`wi = −d` for a ray travelling along `d`), `n` is the unit macro normal on the
//! incident side (`wi·n > 0`); `wo` points away from the surface.
//! A roughness below [`SMOOTH_ALPHA`] is treated as a perfectly smooth (delta)
//! interface. With [`Interface::planar`] (`acquisition.dimensions = 2`) the
//! normal distribution, its sampler and the Jacobians are the flatland ones of
//! [`crate::ggx_planar`], per radian; the weights and the code paths are these.

use crate::fresnel::{fresnel, fresnel_ratio, reflect, refract};
use crate::ggx_planar as planar;
use crate::thin_layer::{frustrated_transmission, Layer};
use usray_ad::Real;
use usray_geometry::Vec3;

/// Roughness below which an interface is perfectly smooth (specular delta lobes).
pub const SMOOTH_ALPHA: f64 = 1e-3;

/// The two media and the roughness of one interface, in any [`Real`].
#[derive(Clone, Copy, Debug)]
pub struct Interface<T> {
    /// Sound speed of the incident medium, m/s.
    pub c1: T,
    /// Sound speed of the medium on the other side, m/s.
    pub c2: T,
    /// Impedance of the incident medium (MRayl).
    pub z1: T,
    /// Impedance of the other medium (MRayl).
    pub z2: T,
    /// GGX roughness `α` (dimensionless).
    pub alpha: T,
    /// The 2-D (flatland) model of [`crate::ggx_planar`]: normals, directions
    /// and densities in the `xz` plane (`acquisition.dimensions = 2`).
    pub planar: bool,
}

/// An orthonormal frame around a unit normal `n` (Duff et al. 2017,
/// "Building an orthonormal basis, revisited").
#[derive(Clone, Copy, Debug)]
pub struct Frame<T> {
    /// First tangent.
    pub s: Vec3<T>,
    /// Second tangent.
    pub t: Vec3<T>,
    /// The normal.
    pub n: Vec3<T>,
}

impl<T: Real> Frame<T> {
    /// The frame of unit normal `n`.
    pub fn new(n: Vec3<T>) -> Self {
        let sign = if n.z.value() >= 0.0 { 1.0 } else { -1.0 };
        let a = -(T::from_f64(sign) + n.z).recip();
        let b = n.x * n.y * a;
        let s = Vec3::new(
            T::one() + (n.x * n.x * a).scale(sign),
            b.scale(sign),
            -n.x.scale(sign),
        );
        let t = Vec3::new(b, T::from_f64(sign) + n.y * n.y * a, -n.y);
        Self { s, t, n }
    }
    /// World → local (`n` is local `+z`).
    pub fn to_local(&self, v: Vec3<T>) -> Vec3<T> {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }
    /// Local → world.
    pub fn to_world(&self, v: Vec3<T>) -> Vec3<T> {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// The half vector of a refraction from `wi` (towards the surface, outside) to
/// `wo` (inside) with inverse speeds `ei`, `eo` (Walter et al. 2007, eq. 16:
/// `h ∝ −(η_i i + η_o o)`), oriented along the normal `n`, with `i·h` and `o·h`;
/// `None` unless `i·h > 0 > o·h` (the pair is not a refraction through `h`).
#[inline]
fn refraction_half_vector<T: Real>(
    wi: Vec3<T>,
    wo: Vec3<T>,
    n: Vec3<T>,
    ei: T,
    eo: T,
) -> Option<(Vec3<T>, T, T)> {
    let mut h = -(wi * ei + wo * eo).normalize();
    if h.dot(n).value() < 0.0 {
        h = -h;
    }
    let (ih, oh) = (wi.dot(h), wo.dot(h));
    (ih.value() > 0.0 && oh.value() < 0.0).then_some((h, ih, oh))
}

/// Paper eq. `GGX_PDF`: `D(h)` for `cos θh = n·h` (1/sr).
pub fn ndf<T: Real>(cos_h: T, alpha: T) -> T {
    if cos_h.value() <= 0.0 {
        return T::zero();
    }
    let a2 = alpha * alpha;
    let k = cos_h * cos_h * (a2 - T::one()) + T::one();
    a2 / (T::pi() * k * k)
}

/// Smith `Λ(ω)` for `cos θ = |n·ω|` (Heitz 2014 eq. 72).
pub fn smith_lambda<T: Real>(cos: T, alpha: T) -> T {
    let c2 = cos * cos;
    if c2.value() <= 0.0 {
        return T::from_f64(1e30);
    }
    let tan2 = (T::one() - c2).max(T::zero()) / c2;
    ((T::one() + alpha * alpha * tan2).sqrt() - T::one()) * T::from_f64(0.5)
}

/// Smith masking `G1 = 1/(1 + Λ)`.
pub fn g1<T: Real>(cos: T, alpha: T) -> T {
    (T::one() + smith_lambda(cos, alpha)).recip()
}

/// Height-correlated masking–shadowing `G2 = 1/(1 + Λ(i) + Λ(o))`.
pub fn g2<T: Real>(cos_i: T, cos_o: T, alpha: T) -> T {
    (T::one() + smith_lambda(cos_i, alpha) + smith_lambda(cos_o, alpha)).recip()
}

/// A microfacet normal (local frame, `n = +z`) visible from the local direction
/// `wi` (`wi.z > 0`), for roughness `alpha`, from two uniforms: the spherical-cap
/// form of visible-normal sampling (Dupuy & Benyoub 2023, "Sampling Visible GGX
/// Normals with Spherical Caps", listing 3), which draws exactly Heitz's (2018)
/// density [`vndf_pdf`] and, unlike Heitz's listing 1, needs no tangent frame
/// around `wi`: the sample is a smooth function of `wi` and `alpha` everywhere
/// (no `1/sin θi` derivative near normal incidence), so it is differentiated.
///
/// Steps: stretch `wi` to the hemisphere configuration, sample the spherical cap
/// `z ∈ [−wi_std.z, 1]` uniformly, add `wi_std` (the half-vector of the
/// hemisphere configuration), unstretch.
pub fn sample_vndf<T: Real>(wi: Vec3<T>, alpha: T, u1: f64, u2: f64) -> Vec3<T> {
    let wi_std = Vec3::new(alpha * wi.x, alpha * wi.y, wi.z).normalize();
    let phi = 2.0 * core::f64::consts::PI * u1;
    let z = T::from_f64(1.0 - u2) * (T::one() + wi_std.z) - wi_std.z;
    let sin_theta = (T::one() - z * z).clamp(T::zero(), T::one()).safe_sqrt();
    let c = Vec3::new(sin_theta.scale(phi.cos()), sin_theta.scale(phi.sin()), z);
    let h_std = c + wi_std;
    let z_h = h_std.z.max(T::from_f64(1e-12));
    Vec3::new(alpha * h_std.x, alpha * h_std.y, z_h).normalize()
}

/// Density of [`sample_vndf`] over microfacet normals (1/sr):
/// `D_i(h) = G1(i) max(0, i·h) D(h) / (i·n)` (Heitz 2018 eq. 2). Local frame.
pub fn vndf_pdf<T: Real>(wi: Vec3<T>, h: Vec3<T>, alpha: T) -> T {
    let ih = wi.dot(h);
    if ih.value() <= 0.0 || wi.z.value() <= 0.0 {
        return T::zero();
    }
    g1(wi.z, alpha) * ih * ndf(h.z, alpha) / wi.z
}

/// One lobe of a scattering: an outgoing direction and its weight.
#[derive(Clone, Copy, Debug)]
pub struct Lobe<T> {
    /// Outgoing unit direction (away from the surface).
    pub wo: Vec3<T>,
    /// Pressure-amplitude weight `f·|o·n| / pdf`: `R` or `T` for a smooth
    /// interface, `R·G2/G1` or `T·G2/G1` for a rough one.
    pub weight: T,
}

/// Both continuations of one interaction: reflection and transmission from one
/// sampled microfacet normal (the path splits; no reflect-or-transmit choice).
#[derive(Clone, Copy, Debug)]
pub struct Scatter<T> {
    /// The reflected continuation (`None` when it leaves the valid hemisphere).
    pub reflected: Option<Lobe<T>>,
    /// The transmitted continuation (`None` under total internal reflection or
    /// when it leaves the valid hemisphere).
    pub transmitted: Option<Lobe<T>>,
    /// True when the lobes are deltas (smooth interface).
    pub specular: bool,
    /// True when the transmitted lobe tunnelled through a thin layer
    /// ([`Interface::scatter_through`]): it continues from the layer's far
    /// surface, in the medium it came from.
    pub tunnelled: bool,
}

impl<T: Real> Interface<T> {
    fn smooth(&self) -> bool {
        self.alpha.value() < SMOOTH_ALPHA
    }

    /// `|i·h|·D(h)·|dωh/dωo|/|i·n|` of a reflection (`i·h = o·h = ih`, `inv_cos_i
    /// = 1/|i·n|`), shared by the BSDF and its density: `D/(4|i·n|)` in 3-D
    /// (Walter 2007 eq. 14), `(i·h)·D₂/(2|i·n|)` in 2-D.
    fn reflection_common(&self, cos_h: T, ih: T, inv_cos_i: T) -> T {
        if self.planar {
            ih * planar::ndf(cos_h, self.alpha) * planar::reflection_jacobian::<T>() * inv_cos_i
        } else {
            ndf(cos_h, self.alpha) * inv_cos_i.scale(0.25)
        }
    }

    /// `|i·h|·D(h)·|dωh/dωo|/|i·n|` of a refraction (`den = η_i(i·h) +
    /// η_o(o·h)`): `|i·h||o·h|·η_o² D/(|i·n| den²)` in 3-D (Walter 2007 eq. 17),
    /// `|i·h|·D₂·η_o|o·h|/(|i·n||den|)` in 2-D.
    #[allow(clippy::too_many_arguments)]
    fn refraction_common(&self, cos_h: T, ih: T, oh: T, ei: T, eo: T, inv_cos_i: T) -> T {
        if self.planar {
            ih * inv_cos_i
                * (planar::ndf(cos_h, self.alpha) * planar::refraction_jacobian(ih, oh, ei, eo))
        } else {
            let den = ei * ih + eo * oh;
            ih * oh.abs() * inv_cos_i * eo * eo * ndf(cos_h, self.alpha) / (den * den)
        }
    }

    /// The visible-normal sample of `wi` about `n`: [`sample_vndf`] in 3-D,
    /// [`planar::sample_vndf`] in 2-D (from `u1` alone).
    fn sample_normal(&self, wi: Vec3<T>, n: Vec3<T>, u1: f64, u2: f64) -> Vec3<T> {
        if self.planar {
            let frame = planar::PlanarFrame::new(n);
            frame.to_world(planar::sample_vndf(frame.to_local(wi), self.alpha, u1))
        } else {
            let frame = Frame::new(n);
            frame.to_world(sample_vndf(frame.to_local(wi), self.alpha, u1, u2))
        }
    }

    /// Scatter incident `wi` (away from the surface) at a surface with
    /// incident-side unit normal `n`: one microfacet normal from uniforms
    /// `u1, u2`, and **both** its reflection and its transmission, each with its
    /// own weight (`None` when the interaction is degenerate).
    ///
    /// Every step is differentiated, sampling included (the microfacet normal is
    /// a smooth function of `wi`, `n` and `α` for fixed uniforms), so the
    /// derivative of a weight is exactly the derivative of the fixed-seed
    /// estimate, and there is no discrete choice whose probability depends on
    /// the parameters (the paper's `R²` split would make the fixed-seed estimate
    /// jump where the choice flips; splitting removes the jump and the
    /// `1/R` weights of rare reflections).
    ///
    /// Weights (Heitz 2018 §2, Walter 2007 eqs. 20–21 over the sampled density
    /// `D_i(h)` times the half-vector Jacobians): `D` cancels, leaving
    /// `R·G2(i,o)/G1(i)` for reflection and `T·G2(i,o)/G1(i)` for transmission;
    /// for a smooth interface simply `R` and `T`.
    pub fn scatter(&self, wi: Vec3<T>, n: Vec3<T>, u1: f64, u2: f64) -> Option<Scatter<T>> {
        self.scatter_through(wi, n, u1, u2, None)
    }

    /// [`Interface::scatter`] at the near surface of a thin `layer` of the
    /// other medium (a tube's wall, a slab) with the incident medium on its far
    /// side: where the sampled microfacet is beyond the critical angle, the
    /// fraction `|T|²` of [`frustrated_transmission`] crosses the layer in the
    /// incident direction (the transmitted lobe, [`Scatter::tunnelled`]) and
    /// the reflection keeps `√(1 − |T|²)`; elsewhere as [`Interface::scatter`].
    pub fn scatter_through(
        &self,
        wi: Vec3<T>,
        n: Vec3<T>,
        u1: f64,
        u2: f64,
        layer: Option<Layer<T>>,
    ) -> Option<Scatter<T>> {
        let cos_i = wi.dot(n);
        if cos_i.value() <= 0.0 {
            return None;
        }
        let smooth = self.smooth();
        // Step 1: the microfacet normal (the macro normal for a smooth interface).
        let h = if smooth {
            n
        } else {
            self.sample_normal(wi, n, u1, u2)
        };
        let cos_ih = wi.dot(h);
        if cos_ih.value() <= 0.0 {
            return None;
        }
        // Step 2: Fresnel at the microfacet (Kinsler §6.3).
        let f = fresnel(cos_ih, self.c1, self.c2, self.z1, self.z2);
        let d = -wi;
        // Step 3: masking–shadowing ratio G2/G1 of the outgoing direction.
        let shadow = |wo: Vec3<T>| {
            if smooth {
                T::one()
            } else {
                g2(cos_i, wo.dot(n).abs(), self.alpha) / g1(cos_i, self.alpha)
            }
        };
        // Step 4: beyond the critical angle, the part of the wave that
        // tunnels through a thin layer (thin_layer module docs).
        let tunnel = layer.filter(|_| f.tir).and_then(|l| {
            frustrated_transmission(
                cos_ih,
                self.c1,
                self.c2,
                self.z1,
                self.z2,
                l.thickness_m,
                l.frequency_hz,
            )
        });
        let r = match tunnel {
            Some(t2) => (T::one() - t2).safe_sqrt(),
            None => f.r,
        };
        let reflected = {
            let wo = reflect(d, h);
            (wo.dot(n).value() > 0.0).then(|| Lobe {
                wo,
                weight: r * shadow(wo),
            })
        };
        let transmitted = if let Some(t2) = tunnel {
            (d.dot(n).value() < 0.0 && t2.value() > 0.0).then(|| Lobe {
                wo: d,
                weight: t2.safe_sqrt() * shadow(d),
            })
        } else if f.tir {
            None
        } else {
            let wo = refract(d, h, self.c2 / self.c1, f.cos_t);
            (wo.dot(n).value() < 0.0).then(|| Lobe {
                wo,
                weight: f.t * shadow(wo),
            })
        };
        Some(Scatter {
            reflected,
            transmitted,
            specular: smooth,
            tunnelled: tunnel.is_some(),
        })
    }

    /// `f(wi, wo)·|wo·n|` (1/sr) for a connection direction `wo`: reflection when
    /// `wo` is on the incident side, transmission otherwise. Zero for a smooth
    /// interface (delta lobes cannot be hit by a chosen direction).
    ///
    /// Reference form (Walter 2007 eqs. 20–21 as written); the tracer uses the
    /// equal, cheaper [`Incident::eval_pdf`] (checked against this in
    /// `tests/ggx.rs`).
    pub fn eval(&self, wi: Vec3<T>, wo: Vec3<T>, n: Vec3<T>) -> T {
        if self.smooth() {
            return T::zero();
        }
        let cos_i = wi.dot(n);
        let cos_o = wo.dot(n);
        if cos_i.value() <= 0.0 || cos_o.value() == 0.0 {
            return T::zero();
        }
        if cos_o.value() > 0.0 {
            let h = (wi + wo).normalize();
            let cos_ih = wi.dot(h);
            if cos_ih.value() <= 0.0 {
                return T::zero();
            }
            let f = fresnel(cos_ih, self.c1, self.c2, self.z1, self.z2);
            f.r * self.reflection_common(h.dot(n), cos_ih, cos_i.recip())
                * g2(cos_i, cos_o, self.alpha)
        } else {
            let (ei, eo) = (self.c1.recip(), self.c2.recip());
            let Some((h, ih, oh)) = refraction_half_vector(wi, wo, n, ei, eo) else {
                return T::zero();
            };
            let f = fresnel(ih, self.c1, self.c2, self.z1, self.z2);
            if f.tir {
                return T::zero();
            }
            let co = cos_o.abs();
            f.t * self.refraction_common(h.dot(n), ih, oh, ei, eo, cos_i.recip())
                * g2(cos_i, co, self.alpha)
        }
    }

    /// [`Interface::eval`] and [`Interface::pdf`] of the same directions in one
    /// pass: [`Incident::eval_pdf`] of [`Interface::incident`].
    pub fn eval_pdf(&self, wi: Vec3<T>, wo: Vec3<T>, n: Vec3<T>) -> (T, T) {
        self.incident(wi, n).eval_pdf(wo)
    }

    /// The interface seen from the incident direction `wi` (normal `n` on its
    /// side): the parts of the BSDF and its density that do not depend on the
    /// outgoing direction, computed once for all receiver connections of a
    /// vertex.
    pub fn incident(&self, wi: Vec3<T>, n: Vec3<T>) -> Incident<T> {
        let cos_i = wi.dot(n);
        let valid = !self.smooth() && cos_i.value() > 0.0;
        let (lambda_i, inv_cos_i) = if valid {
            (smith_lambda(cos_i, self.alpha), cos_i.recip())
        } else {
            (T::zero(), T::zero())
        };
        Incident {
            iface: *self,
            wi,
            n,
            valid,
            lambda_i,
            g1_i: (T::one() + lambda_i).recip(),
            inv_cos_i,
            ratio: self.c2 / self.c1,
            eta: (self.c1.recip(), self.c2.recip()),
        }
    }

    /// Density (1/sr) with which [`Interface::scatter`] produces `wo` in the lobe
    /// `wo` lies in (reflection when on the incident side): the visible-normal
    /// density times the half-vector Jacobian `1/(4|o·h|)` or
    /// `η_o²|o·h|/(η_i(i·h) + η_o(o·h))²` (Walter 2007 eqs. 14, 17). Zero for a
    /// smooth interface.
    ///
    /// Reference form, derived through the local frame and [`vndf_pdf`]; the
    /// tracer's MIS weights use the equal, cheaper [`Incident::eval_pdf`]
    /// (checked against this to 1e-12 in `tests/ggx.rs`).
    pub fn pdf(&self, wi: Vec3<T>, wo: Vec3<T>, n: Vec3<T>) -> T {
        let cos_o = wo.dot(n).value();
        if self.smooth() || wi.dot(n).value() <= 0.0 || cos_o == 0.0 {
            return T::zero();
        }
        // The visible-normal density of `h` in the local frame.
        let vndf = |h: Vec3<T>| {
            if self.planar {
                let frame = planar::PlanarFrame::new(n);
                planar::vndf_pdf(frame.to_local(wi), frame.to_local(h), self.alpha)
            } else {
                let frame = Frame::new(n);
                vndf_pdf(frame.to_local(wi), frame.to_local(h), self.alpha)
            }
        };
        if cos_o > 0.0 {
            let h = (wi + wo).normalize();
            let ih = wi.dot(h);
            if ih.value() <= 0.0 {
                return T::zero();
            }
            let jacobian = if self.planar {
                planar::reflection_jacobian()
            } else {
                ih.scale(4.0).recip()
            };
            vndf(h) * jacobian
        } else {
            let (ei, eo) = (self.c1.recip(), self.c2.recip());
            let Some((h, ih, oh)) = refraction_half_vector(wi, wo, n, ei, eo) else {
                return T::zero();
            };
            if fresnel(ih, self.c1, self.c2, self.z1, self.z2).tir {
                return T::zero();
            }
            let jacobian = if self.planar {
                planar::refraction_jacobian(ih, oh, ei, eo)
            } else {
                let den = ei * ih + eo * oh;
                eo * eo * oh.abs() / (den * den)
            };
            vndf(h) * jacobian
        }
    }
}

/// An [`Interface`] seen from a fixed incident direction (see
/// [`Interface::incident`]): evaluates the BSDF and its sampling density for
/// many outgoing directions.
#[derive(Clone, Copy, Debug)]
pub struct Incident<T> {
    iface: Interface<T>,
    wi: Vec3<T>,
    n: Vec3<T>,
    /// Rough interface and `wi` on the side of `n`: else everything is 0.
    valid: bool,
    /// Smith `Λ(wi)`.
    lambda_i: T,
    /// `G1(wi) = 1/(1 + Λ(wi))`.
    g1_i: T,
    /// `1/(wi·n)`.
    inv_cos_i: T,
    /// `c2/c1`.
    ratio: T,
    /// Refractive indices `(1/c1, 1/c2)`.
    eta: (T, T),
}

impl<T: Real> Incident<T> {
    /// `f·|wo·n|` of [`Interface::eval`] (1/sr) and the density of
    /// [`Interface::pdf`] (1/sr, in `T`: differentiated like it) for the
    /// outgoing direction `wo`, sharing the half vector, Fresnel factor, `D`
    /// and `Λ(wi)`. The visible-normal density is written without a local
    /// frame: `D_i(h) = G1(i)·(i·h)·D(h)/(i·n)` only involves dot products,
    /// which the orthonormal frame of [`Interface::pdf`] preserves (also in
    /// their derivatives). Equal to `(eval, pdf)` up to rounding; both are 0
    /// where `eval` returns early (where `pdf` is 0 too).
    pub fn eval_pdf(&self, wo: Vec3<T>) -> (T, T) {
        let zero = (T::zero(), T::zero());
        let (wi, n) = (self.wi, self.n);
        let cos_o = wo.dot(n);
        if !self.valid || cos_o.value() == 0.0 {
            return zero;
        }
        let f = &self.iface;
        let g2 = |cos_o: T| (T::one() + self.lambda_i + smith_lambda(cos_o, f.alpha)).recip();
        if cos_o.value() > 0.0 {
            let h = (wi + wo).normalize();
            let cos_ih = wi.dot(h);
            if cos_ih.value() <= 0.0 {
                return zero;
            }
            let fr = fresnel_ratio(cos_ih, self.ratio, f.z1, f.z2);
            // |i·h|·D·|dωh/dωo|/|i·n|, shared by value and density (3-D: the
            // pdf is D_i(h)/(4 i·h) = G1(i)·D(h)/(4 i·n)).
            let common = f.reflection_common(h.dot(n), cos_ih, self.inv_cos_i);
            (fr.r * common * g2(cos_o), self.g1_i * common)
        } else {
            let (ei, eo) = self.eta;
            let Some((h, ih, oh)) = refraction_half_vector(wi, wo, n, ei, eo) else {
                return zero;
            };
            let fr = fresnel_ratio(ih, self.ratio, f.z1, f.z2);
            if fr.tir {
                return zero;
            }
            // |i·h|·D·|dωh/dωo|/|i·n| (3-D: |i·h||o·h|/|i·n| · η_o² D / den²).
            let common = f.refraction_common(h.dot(n), ih, oh, ei, eo, self.inv_cos_i);
            (fr.t * common * g2(cos_o.abs()), self.g1_i * common)
        }
    }
}
