//! The GGX microfacet interface in two dimensions (`acquisition.dimensions =
//! 2`): a rough curve in the `xz` plane, for data that are themselves 2-D
//! (k-Wave's 2-D solver, PyMUST's `simus`), where nothing is scattered out of
//! the plane.
//!
//! A 3-D rough surface spreads an echo in elevation too, and an element of
//! finite height receives only part of it, less the farther the surface; in 2-D
//! all of it stays in the plane. The planar model keeps the 3-D model's
//! structure and changes only the distribution of microfacet normals and the
//! Jacobians, so the lobe weights of [`crate::ggx::Interface::scatter`] stay
//! `R·G2/G1` and `T·G2/G1`. Angles are measured in the plane, densities are per
//! radian.
//!
//! Sources (the "flatland" microfacet model: the 3-D derivations of Walter et
//! al. 2007 and Heitz 2014/2018 with one dimension fewer):
//! - slopes `s = tan θh` distributed as the 1-D marginal of the GGX slope
//!   distribution, `P(s) = 1/(2α) · (1 + s²/α²)^{−3/2}` (Heitz 2014, eq. 79
//!   integrated over the other slope), so the normal distribution per radian is
//!   `D₂(θh) = P(tan θh)/cos³θh = (α²/2)(α² cos²θh + sin²θh)^{−3/2}`, normalised as
//!   `∫ D₂ cos θh dθh = 1` (projected length, Heitz 2014 eq. 4 in the plane);
//! - Smith `Λ` depends only on the 1-D slope distribution in the plane of the
//!   direction (Heitz 2014, §5.3), so `Λ`, `G1` and `G2` are the 3-D functions
//!   of [`crate::ggx`];
//! - visible normals `D_i(h) = G1(i)·max(0, i·h)·D₂(h)/(i·n)` (Heitz 2018 eq. 2,
//!   per radian), sampled by stretching to `α = 1`, where the microsurface is a
//!   half circle whose visible normals from `i` have density `∝ cos(θh − θi)`
//!   (so `sin(θh − θi)` is uniform on the visible arc), and unstretching;
//! - half-angle Jacobians `|dθh/dθo|`: `1/2` for reflection (`θo = 2θh − θi`),
//!   `η_o|o·h| / |η_i(i·h) + η_o(o·h)|` for refraction (Walter 2007 eq. 17 with one
//!   dimension fewer; it is `1/2` at `η_i = η_o`, as it must be).

use usray_ad::Real;
use usray_geometry::Vec3;

/// The in-plane frame of a unit normal `n` lying in the `xz` plane: the
/// tangent `t = (n_z, 0, −n_x)` and `n`. A direction `v` in the plane has local
/// coordinates `(v·t, v·n)`.
#[derive(Clone, Copy, Debug)]
pub struct PlanarFrame<T> {
    /// In-plane tangent.
    pub t: Vec3<T>,
    /// The normal.
    pub n: Vec3<T>,
}

impl<T: Real> PlanarFrame<T> {
    /// The frame of `n` (its `y` component is taken to be 0).
    pub fn new(n: Vec3<T>) -> Self {
        Self {
            t: Vec3::new(n.z, T::zero(), -n.x),
            n,
        }
    }
    /// World → local `(along t, along n)`.
    pub fn to_local(&self, v: Vec3<T>) -> [T; 2] {
        [v.dot(self.t), v.dot(self.n)]
    }
    /// Local → world.
    pub fn to_world(&self, v: [T; 2]) -> Vec3<T> {
        self.t * v[0] + self.n * v[1]
    }
}

/// `D₂(h)` (1/rad) for `cos θh = n·h`: `(α²/2)(α² cos²θh + sin²θh)^{−3/2}`, 0
/// for `cos θh ≤ 0`.
///
/// ```
/// use usray_transport::ggx_planar::ndf;
/// // ∫ D₂(θ) cos θ dθ over (−π/2, π/2) is 1 (midpoint rule).
/// let (alpha, n) = (0.3_f64, 20_000);
/// let d = std::f64::consts::PI / n as f64;
/// let total: f64 = (0..n)
///     .map(|k| {
///         let th = -std::f64::consts::FRAC_PI_2 + (k as f64 + 0.5) * d;
///         ndf(th.cos(), alpha) * th.cos() * d
///     })
///     .sum();
/// assert!((total - 1.0).abs() < 1e-6, "{total}");
/// ```
pub fn ndf<T: Real>(cos_h: T, alpha: T) -> T {
    if cos_h.value() <= 0.0 {
        return T::zero();
    }
    let a2 = alpha * alpha;
    let c2 = cos_h * cos_h;
    let k = a2 * c2 + (T::one() - c2).max(T::zero());
    a2.scale(0.5) / (k * k.sqrt())
}

/// A microfacet normal visible from the local direction `wi = (sin θi, cos θi)`
/// (`wi[1] > 0`), in local coordinates, for roughness `alpha`, from one uniform:
/// stretch `wi` to `α = 1`, draw `sin δ` uniformly on the arc of the half
/// circle's visible normals (`θh = θi + δ` with `|δ| < π/2` and `|θh| < π/2`),
/// unstretch. Smooth in `wi` and `alpha` for a fixed `u` (the two forms of the
/// arc agree to first order at `θi = 0`), so it is differentiated.
pub fn sample_vndf<T: Real>(wi: [T; 2], alpha: T, u: f64) -> [T; 2] {
    let (sx, sz) = (alpha * wi[0], wi[1]);
    let len = (sx * sx + sz * sz).sqrt();
    let (s, c) = (sx / len, sz / len);
    // sin δ on the visible arc: (−1, cos θi) for θi ≥ 0, (−cos θi, 1) below.
    let v = if s.value() >= 0.0 {
        (T::one() + c).scale(u) - T::one()
    } else {
        (T::one() + c).scale(u) - c
    };
    let cd = (T::one() - v * v).max(T::zero()).safe_sqrt();
    // Rotate (sin θi, cos θi) by δ.
    let hx = s * cd + c * v;
    let hz = (c * cd - s * v).max(T::from_f64(1e-12));
    let (ux, uz) = (alpha * hx, hz);
    let l = (ux * ux + uz * uz).sqrt();
    [ux / l, uz / l]
}

/// Density of [`sample_vndf`] over the normal's angle (1/rad):
/// `D_i(h) = G1(i)·max(0, i·h)·D₂(h)/(i·n)`, local coordinates.
pub fn vndf_pdf<T: Real>(wi: [T; 2], h: [T; 2], alpha: T) -> T {
    let ih = wi[0] * h[0] + wi[1] * h[1];
    if ih.value() <= 0.0 || wi[1].value() <= 0.0 {
        return T::zero();
    }
    crate::ggx::g1(wi[1], alpha) * ih * ndf(h[1], alpha) / wi[1]
}

/// `|dθh/dθo|` of a reflection: `1/2`.
pub fn reflection_jacobian<T: Real>() -> T {
    T::from_f64(0.5)
}

/// `|dθh/dθo|` of a refraction from `i` to `o` through `h` with refractive
/// indices `η_i = ei`, `η_o = eo` (`ih = i·h > 0 > oh = o·h`):
/// `η_o|o·h| / |η_i(i·h) + η_o(o·h)|`.
pub fn refraction_jacobian<T: Real>(ih: T, oh: T, ei: T, eo: T) -> T {
    eo * oh.abs() / (ei * ih + eo * oh).abs()
}
