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
//! - visible-normal sampling: Heitz 2018, "Sampling the GGX Distribution of Visible
//!   Normals", JCGT 7(4), listing 1, density `D_i(h) = G1(i) max(0, i·h) D(h) / (i·n)`;
//! - reflection `f_r = F·D·G2 / (4 |i·n| |o·n|)`, transmission
//!   `f_t = |i·h||o·h|/(|i·n||o·n|) · η_o² (1−F)·D·G2 / (η_i (i·h) + η_o (o·h))²`
//!   (Walter 2007 eqs. 20 and 21) with the refractive index of a medium taken as
//!   `η = 1/c` (so Snell is `sin θt = (c2/c1) sin θi`), and the half-vector
//!   Jacobians `1/(4|o·h|)` and `η_o²|o·h|/(η_i(i·h) + η_o(o·h))²` (Walter eqs. 14, 17).
//!
//! The Fresnel factor is the acoustic **pressure amplitude** of [`crate::fresnel`]:
//! `F → R` for reflection and `(1 − F) → T = 1 + R` for transmission, evaluated at
//! the microfacet normal. The reflect/transmit choice has probability `R²` /
//! `1 − R²`; the sampled weight is `f·|o·n| / pdf` with the pdf **detached**, whose
//! value is `(R / R²)·G2/G1` or `(T / (1 − R²))·G2/G1`.
//!
//! Conventions: `wi` points *away* from the surface into the incident medium
//! (`wi = −d` for a ray travelling along `d`), `n` is the unit macro normal on the
//! incident side (`wi·n > 0`); `wo` points away from the surface.
//! A roughness below [`SMOOTH_ALPHA`] is treated as a perfectly smooth (delta)
//! interface.

use crate::fresnel::{fresnel, reflect, refract};
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

/// Heitz 2018 listing 1: a microfacet normal (local frame, `n = +z`) visible from
/// the local direction `wi` (`wi.z > 0`), for roughness `alpha`, from two uniforms.
/// Plain `f64`: sampling is done with detached values (`DESIGN.md`).
pub fn sample_vndf(wi: [f64; 3], alpha: f64, u1: f64, u2: f64) -> [f64; 3] {
    // Section 3.2: transform the view direction to the hemisphere configuration.
    let vh = {
        let v = [alpha * wi[0], alpha * wi[1], wi[2]];
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    };
    // Section 4.1: orthonormal basis (with special case if cross product is zero).
    let lensq = vh[0] * vh[0] + vh[1] * vh[1];
    let t1 = if lensq > 0.0 {
        let il = 1.0 / lensq.sqrt();
        [-vh[1] * il, vh[0] * il, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let t2 = [
        vh[1] * t1[2] - vh[2] * t1[1],
        vh[2] * t1[0] - vh[0] * t1[2],
        vh[0] * t1[1] - vh[1] * t1[0],
    ];
    // Section 4.2: parameterization of the projected area.
    let r = u1.sqrt();
    let phi = 2.0 * core::f64::consts::PI * u2;
    let p1 = r * phi.cos();
    let mut p2 = r * phi.sin();
    let s = 0.5 * (1.0 + vh[2]);
    p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
    // Section 4.3: reprojection onto the hemisphere.
    let pz = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    let nh = [
        p1 * t1[0] + p2 * t2[0] + pz * vh[0],
        p1 * t1[1] + p2 * t2[1] + pz * vh[1],
        p1 * t1[2] + p2 * t2[2] + pz * vh[2],
    ];
    // Section 3.4: transform the normal back to the ellipsoid configuration.
    let ne = [alpha * nh[0], alpha * nh[1], nh[2].max(1e-12)];
    let l = (ne[0] * ne[0] + ne[1] * ne[1] + ne[2] * ne[2]).sqrt();
    [ne[0] / l, ne[1] / l, ne[2] / l]
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

/// One sampled scattering at an interface.
#[derive(Clone, Copy, Debug)]
pub struct Sample<T> {
    /// Outgoing unit direction (away from the surface).
    pub wo: Vec3<T>,
    /// Pressure-amplitude weight `f·|o·n| / pdf` (pdf detached).
    pub weight: T,
    /// True for reflection, false for transmission into the other medium.
    pub reflected: bool,
    /// True when the lobe was a delta (smooth interface).
    pub specular: bool,
}

impl<T: Real> Interface<T> {
    fn smooth(&self) -> bool {
        self.alpha.value() < SMOOTH_ALPHA
    }

    /// Sample the outgoing direction for incident `wi` (away from the surface) at
    /// a surface with incident-side unit normal `n`, from uniforms `u1, u2` (the
    /// microfacet normal) and `u_split` (reflect with probability `R²`).
    /// `None` when the sample leaves the valid hemisphere (the path ends; this is
    /// the usual unbiased treatment of microfacet samples).
    pub fn sample(
        &self,
        wi: Vec3<T>,
        n: Vec3<T>,
        u1: f64,
        u2: f64,
        u_split: f64,
    ) -> Option<Sample<T>> {
        let cos_i = wi.dot(n);
        if cos_i.value() <= 0.0 {
            return None;
        }
        let smooth = self.smooth();
        // Step 1: the microfacet normal (the macro normal for a smooth interface).
        let frame = Frame::new(n);
        let (h, pdf_h) = if smooth {
            (n, T::one())
        } else {
            let wl = frame.to_local(wi).value();
            let a = self.alpha.value();
            let hl = sample_vndf(wl, a, u1, u2);
            let hl_t = Vec3::from_f64s(hl);
            // Local h is a constant; the world h follows the (differentiable) frame.
            let pdf = vndf_pdf(frame.to_local(wi), hl_t, self.alpha);
            (frame.to_world(hl_t), pdf)
        };
        let cos_ih = wi.dot(h);
        if cos_ih.value() <= 0.0 {
            return None;
        }
        // Step 2: Fresnel at the microfacet (Kinsler §6.3) and the R² split.
        let f = fresnel(cos_ih, self.c1, self.c2, self.z1, self.z2);
        let p_r = if f.tir { 1.0 } else { (f.r * f.r).value() };
        let reflected = u_split < p_r;
        let d = -wi;
        let (wo, amp, p_choice) = if reflected {
            (reflect(d, h), f.r, p_r)
        } else {
            (refract(d, h, self.c2 / self.c1, f.cos_t), f.t, 1.0 - p_r)
        };
        let cos_o = wo.dot(n);
        if (reflected && cos_o.value() <= 0.0) || (!reflected && cos_o.value() >= 0.0) {
            return None;
        }
        if p_choice <= 0.0 {
            return None;
        }
        let choice = T::from_f64(p_choice);
        if smooth {
            return Some(Sample {
                wo,
                weight: amp / choice,
                reflected,
                specular: true,
            });
        }
        // Step 3: f·|o·n| / pdf, pdf detached (value: amp·G2/G1 / p_choice).
        let ca = cos_i;
        let co = cos_o.abs();
        let d_h = ndf(h.dot(n), self.alpha);
        let g = g2(ca, co, self.alpha);
        let weight = if reflected {
            let f_cos = amp * d_h * g / (ca * T::from_f64(4.0));
            let pdf = pdf_h / (cos_ih * T::from_f64(4.0));
            f_cos / pdf.detach()
        } else {
            let (ei, eo) = (self.c1.recip(), self.c2.recip());
            let oh = wo.dot(h);
            let den = ei * cos_ih + eo * oh;
            let den2 = den * den;
            let f_cos = amp * cos_ih * oh.abs() / ca * eo * eo * d_h * g / den2;
            let pdf = pdf_h * eo * eo * oh.abs() / den2;
            f_cos / pdf.detach()
        };
        Some(Sample {
            wo,
            weight: weight / choice,
            reflected,
            specular: false,
        })
    }

    /// `f(wi, wo)·|wo·n|` (1/sr) for a connection direction `wo`: reflection when
    /// `wo` is on the incident side, transmission otherwise. Zero for a smooth
    /// interface (delta lobes cannot be hit by a chosen direction).
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
            f.r * ndf(h.dot(n), self.alpha) * g2(cos_i, cos_o, self.alpha)
                / (cos_i * T::from_f64(4.0))
        } else {
            let (ei, eo) = (self.c1.recip(), self.c2.recip());
            let mut h = -(wi * ei + wo * eo).normalize();
            if h.dot(n).value() < 0.0 {
                h = -h;
            }
            let ih = wi.dot(h);
            let oh = wo.dot(h);
            if ih.value() <= 0.0 || oh.value() >= 0.0 {
                return T::zero();
            }
            let f = fresnel(ih, self.c1, self.c2, self.z1, self.z2);
            if f.tir {
                return T::zero();
            }
            let den = ei * ih + eo * oh;
            let co = cos_o.abs();
            f.t * ih * oh.abs() / cos_i
                * eo
                * eo
                * ndf(h.dot(n), self.alpha)
                * g2(cos_i, co, self.alpha)
                / (den * den)
        }
    }

    /// Total density of [`Interface::sample`] producing `wo` (1/sr), including the
    /// `R²` choice; for tests and diagnostics.
    pub fn pdf(&self, wi: Vec3<T>, wo: Vec3<T>, n: Vec3<T>) -> f64 {
        let frame = Frame::new(n);
        let wil = frame.to_local(wi);
        let cos_o = wo.dot(n).value();
        if self.smooth() || wil.z.value() <= 0.0 || cos_o == 0.0 {
            return 0.0;
        }
        if cos_o > 0.0 {
            let h = (wi + wo).normalize();
            let ih = wi.dot(h);
            let f = fresnel(ih, self.c1, self.c2, self.z1, self.z2);
            let pr = if f.tir { 1.0 } else { (f.r * f.r).value() };
            let ph = vndf_pdf(wil, frame.to_local(h), self.alpha).value();
            pr * ph / (4.0 * ih.value())
        } else {
            let (ei, eo) = (1.0 / self.c1.value(), 1.0 / self.c2.value());
            let mut h = -(wi.scale(ei) + wo.scale(eo)).normalize();
            if h.dot(n).value() < 0.0 {
                h = -h;
            }
            let ih = wi.dot(h).value();
            let oh = wo.dot(h).value();
            if ih <= 0.0 || oh >= 0.0 {
                return 0.0;
            }
            let f = fresnel(wi.dot(h), self.c1, self.c2, self.z1, self.z2);
            if f.tir {
                return 0.0;
            }
            let pt = 1.0 - (f.r * f.r).value();
            let ph = vndf_pdf(wil, frame.to_local(h), self.alpha).value();
            let den = ei * ih + eo * oh;
            pt * ph * eo * eo * oh.abs() / (den * den)
        }
    }
}
