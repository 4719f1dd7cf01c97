//! Acoustic reflection and transmission at a fluid–fluid interface.
//!
//! Source: Kinsler, Frey, Coppens & Sanders, *Fundamentals of Acoustics*, 4th ed.,
//! §6.3 ("Reflection and transmission at oblique incidence"). With medium 1
//! (impedance `Z1 = ρ1 c1`, sound speed `c1`) carrying the incident wave at angle
//! `θi` from the normal, and medium 2 (`Z2`, `c2`), Snell's law for sound speeds
//! gives `sin θt = (c2/c1)·sin θi`, and the **pressure** reflection and transmission
//! coefficients are
//!
//! `R = (Z2 cos θi − Z1 cos θt) / (Z2 cos θi + Z1 cos θt)`,  `T = 1 + R`,
//!
//! which conserve the normal energy flux:
//!
//! `R² + T²·(Z1 cos θt)/(Z2 cos θi) = 1`.
//!
//! **Note on the paper's formula.** The paper prints
//! `A_r = (Z1 cos θr − Z2 cos θt)/(Z1 cos θr + Z2 cos θt)` (the optics TE form with
//! `n → Z`). At normal incidence it is `−R` (same magnitude, so the same `R²`
//! split); at oblique incidence it does not satisfy the energy relation above with
//! `T = 1 + A_r`. usray implements Kinsler's fluid–fluid form, for which the
//! energy relation holds exactly (tested with random angles and impedances).
//!
//! Beyond the critical angle (`(c2/c1) sin θi > 1`) the reflection is total:
//! `|R| = 1` (the phase shift of the evanescent case is not modelled; `R = 1`).
//! Impedances may be in any common unit (MRayl in scenes): only ratios enter.

use usray_ad::Real;
use usray_geometry::Vec3;

/// Reflection and transmission at one interface for one incidence angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fresnel<T> {
    /// Pressure reflection coefficient `R` (signed, dimensionless).
    pub r: T,
    /// Pressure transmission coefficient `T = 1 + R` (0 under total internal reflection).
    pub t: T,
    /// `cos θt` of the transmitted ray (0 under total internal reflection).
    pub cos_t: T,
    /// `sin² θt = (c2/c1)² sin² θi`; `≥ 1` means total internal reflection.
    pub sin2_t: T,
    /// True beyond the critical angle.
    pub tir: bool,
}

/// Kinsler §6.3 coefficients for incidence cosine `cos_i ∈ [0, 1]` from medium 1
/// (`c1` m/s, `z1`) into medium 2 (`c2` m/s, `z2`).
///
/// ```
/// use usray_transport::fresnel::fresnel;
/// let f = fresnel(1.0_f64, 1500.0, 1500.0, 1.5, 4.5);
/// assert!((f.r - 0.5).abs() < 1e-12 && (f.t - 1.5).abs() < 1e-12);
/// ```
pub fn fresnel<T: Real>(cos_i: T, c1: T, c2: T, z1: T, z2: T) -> Fresnel<T> {
    fresnel_ratio(cos_i, c2 / c1, z1, z2)
}

/// [`fresnel`] with the speed ratio `ratio = c2/c1` given (for many incidence
/// angles on the same pair of media).
#[inline]
pub fn fresnel_ratio<T: Real>(cos_i: T, ratio: T, z1: T, z2: T) -> Fresnel<T> {
    let one = T::one();
    let cos_i = cos_i.clamp(T::zero(), one);
    let sin2_t = ratio * ratio * (one - cos_i * cos_i);
    if sin2_t.value() >= 1.0 {
        return Fresnel {
            r: one,
            t: T::zero(),
            cos_t: T::zero(),
            sin2_t,
            tir: true,
        };
    }
    let cos_t = (one - sin2_t).safe_sqrt();
    let a = z2 * cos_i;
    let b = z1 * cos_t;
    let den = a + b;
    if den.value() <= 0.0 {
        // Exactly grazing incidence (cos θi = 0 and cos θt = 0): everything reflects.
        return Fresnel {
            r: one,
            t: T::zero(),
            cos_t,
            sin2_t,
            tir: false,
        };
    }
    let r = (a - b) / den;
    Fresnel {
        r,
        t: one + r,
        cos_t,
        sin2_t,
        tir: false,
    }
}

/// The intensity transmission factor `(Z1 cos θt)/(Z2 cos θi)` multiplying `T²` in
/// the energy balance `R² + T²·(Z1 cos θt)/(Z2 cos θi) = 1` (Kinsler §6.3).
pub fn energy_transmission_factor<T: Real>(z1: T, z2: T, cos_i: T, cos_t: T) -> T {
    z1 * cos_t / (z2 * cos_i)
}

/// Specular reflection of the propagation direction `d` about the unit normal `n`
/// (either orientation): `d − 2 (d·n) n` (paper, "Ray Traversal").
#[inline]
pub fn reflect<T: Real>(d: Vec3<T>, n: Vec3<T>) -> Vec3<T> {
    d - n * (d.dot(n) * T::from_f64(2.0))
}

/// Refraction of the unit propagation direction `d` through a surface with unit
/// normal `n_inc` pointing back into the incident medium (`d·n_inc < 0`), with
/// `ratio = c2/c1` (Snell for sound speeds: `sin θt = ratio·sin θi`) and
/// `cos_t` from [`fresnel`]. Vector form (pbrt-v4 §9.5):
/// `t = ratio·d + (ratio·cos θi − cos θt)·n_inc`.
#[inline]
pub fn refract<T: Real>(d: Vec3<T>, n_inc: Vec3<T>, ratio: T, cos_t: T) -> Vec3<T> {
    let cos_i = -d.dot(n_inc);
    (d * ratio + n_inc * (ratio * cos_i - cos_t)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snell_and_tir() {
        let th: f64 = 0.3;
        let d = Vec3::new(th.sin(), 0.0, th.cos());
        let n = Vec3::new(0.0, 0.0, -1.0);
        let f = fresnel(th.cos(), 1500.0, 1800.0, 1.5, 1.7);
        let t = refract(d, n, 1800.0 / 1500.0, f.cos_t);
        assert!((t.x - th.sin() * 1.2).abs() < 1e-12);
        assert!((t.length() - 1.0).abs() < 1e-12);
        let g = fresnel(0.2_f64, 1500.0, 3000.0, 1.5, 3.0);
        assert!(g.tir && g.r == 1.0 && g.t == 0.0);
    }
}
