//! Frustrated total reflection: sound tunnelling through a thin layer beyond
//! its critical angle.
//!
//! A ray meeting a faster layer (a vessel's wall, a membrane) beyond the
//! critical angle `sin θ1 > c1/c2` is totally reflected by a single interface
//! ([`crate::fresnel`]). A layer of thickness `d` with the same fluid on both
//! sides is not: the evanescent field in it reaches the far side and
//! re-radiates there, and a wall thinner than a wavelength lets most of a
//! grazing wave through. A ray model that reflects it totally traps grazing
//! rays inside a thin-walled lumen that, in a full-wave field, leak out of it.
//!
//! Source: the transmission coefficient of a fluid layer between two
//! half-spaces of the same fluid (Brekhovskikh & Godin, *Acoustics of Layered
//! Media I*, 2nd ed., §3.2; Kinsler et al., *Fundamentals of Acoustics*, 4th ed.,
//! §6.5 at oblique incidence):
//!
//! `T = 1 / (cos(k₂z d) − (i/2)(Z_{n2}/Z_{n1} + Z_{n1}/Z_{n2}) sin(k₂z d))`,
//!
//! with the normal impedances `Z_{nj} = Z_j / cos θ_j` and `k₂z = (ω/c2) cos θ2`.
//! Beyond the critical angle `cos θ2 = i γ`, `γ = √(sin²θ2 − 1)`,
//! `sin θ2 = (c2/c1) sin θ1`, so `k₂z = i κ` with `κ = (ω/c2) γ` (1/m) and
//!
//! `|T|² = 1 / (cosh²(κd) + ¼ (1/m − m)² sinh²(κd))`,  `m = Z2 cos θ1 / (Z1 γ)`,
//!
//! the fraction of the incident energy that crosses the layer (the rest is
//! reflected: the layer is lossless and the same fluid lies on both sides, so
//! `|R|² = 1 − |T|²`). The wave is narrow-band about the probe's centre
//! frequency, at which `ω` is taken; the evanescent crossing adds no
//! propagation delay and the tunnelled ray leaves the far side in its incident
//! direction (Snell between equal fluids).
//!
//! The tracer applies it where a scene sets
//! `acquisition.thin_layer_tunnelling = true` (off by default: `docs/contract.md`).

use usray_ad::Real;

/// A thin layer behind an interface, the same medium on its far side as on
/// the incident one ([`crate::ggx::Interface::scatter_through`]).
#[derive(Clone, Copy, Debug)]
pub struct Layer<T> {
    /// Thickness along the normal, metres.
    pub thickness_m: T,
    /// Frequency at which the tunnelling is evaluated (the probe's centre), Hz.
    pub frequency_hz: T,
}

/// Largest `κd` evaluated: beyond it `|T|² < 4e-43`, taken as 0.
const MAX_KAPPA_D: f64 = 50.0;

/// `|T|²`, the energy fraction a lossless fluid layer (speed `c2` m/s,
/// impedance `z2`, thickness `thickness_m`) passes beyond its critical angle
/// between two half-spaces of the same fluid (`c1`, `z1`), for incidence
/// cosine `cos_i` and frequency `frequency_hz` (module docs). `None` below the
/// critical angle, where the ray model refracts into the layer instead.
///
/// ```
/// use usray_transport::thin_layer::frustrated_transmission;
/// // Water (1480 m/s, 1.48 MRayl) against a 0.15 mm wall (1600 m/s,
/// // 1.76 MRayl) at 80° and 2.5 MHz: 70% crosses the wall.
/// let cos_i = 80f64.to_radians().cos();
/// let t2 = frustrated_transmission(cos_i, 1480.0, 1600.0, 1.48, 1.76, 0.15e-3, 2.5e6).unwrap();
/// assert!((t2 - 0.697).abs() < 2e-3, "{t2}");
/// // A thicker wall passes less, a vanishing one everything.
/// let thick = frustrated_transmission(cos_i, 1480.0, 1600.0, 1.48, 1.76, 1e-3, 2.5e6).unwrap();
/// assert!(thick < 0.1 * t2);
/// let none = frustrated_transmission(cos_i, 1480.0, 1600.0, 1.48, 1.76, 1e-9, 2.5e6).unwrap();
/// assert!((none - 1.0).abs() < 1e-6);
/// // Below the critical angle (67.7° here) there is no tunnelling.
/// assert!(frustrated_transmission(0.5, 1480.0, 1600.0, 1.48, 1.76, 0.15e-3, 2.5e6).is_none());
/// ```
pub fn frustrated_transmission<T: Real>(
    cos_i: T,
    c1: T,
    c2: T,
    z1: T,
    z2: T,
    thickness_m: T,
    frequency_hz: T,
) -> Option<T> {
    let one = T::one();
    let cos_i = cos_i.clamp(T::zero(), one);
    let ratio = c2 / c1;
    // sin²θ2 − 1 = γ² > 0 beyond the critical angle.
    let gamma2 = ratio * ratio * (one - cos_i * cos_i) - one;
    if gamma2.value() <= 0.0 {
        return None;
    }
    let gamma = gamma2.sqrt();
    let kappa_d = (frequency_hz / c2 * gamma * thickness_m).scale(2.0 * core::f64::consts::PI);
    if kappa_d.value() > MAX_KAPPA_D {
        return Some(T::zero());
    }
    let e = kappa_d.exp();
    let e_inv = e.recip();
    let cosh = (e + e_inv).scale(0.5);
    let sinh = (e - e_inv).scale(0.5);
    let m = z2 * cos_i / (z1 * gamma);
    let mismatch = (m.recip() - m).scale(0.5);
    Some((cosh * cosh + mismatch * mismatch * sinh * sinh).recip())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed form against the complex layer formula it was continued
    /// from, evaluated with complex `cos θ2` directly.
    #[test]
    fn matches_the_complex_layer_formula() {
        let (c1, c2, z1, z2, d, f) = (1480.0, 1600.0, 1.48, 1.76, 0.15e-3, 2.5e6);
        for deg in [68.0f64, 70.0, 75.0, 80.0, 85.0, 89.0] {
            let th = deg.to_radians();
            let sin2 = (c2 / c1) * th.sin();
            let gamma = (sin2 * sin2 - 1.0).sqrt();
            // cos θ2 = iγ; k2z d = i κ d; Zn2/Zn1 = (z2 cos θ1)/(z1 iγ) = −i m.
            let kd = 2.0 * std::f64::consts::PI * f / c2 * gamma * d;
            let m = z2 * th.cos() / (z1 * gamma);
            // cos(i x) = cosh x; sin(i x) = i sinh x; Zn2/Zn1 + Zn1/Zn2 = i(1/m − m).
            // Denominator: cosh − (i/2)·i(1/m − m)·i sinh = cosh + (i/2)(1/m − m) sinh.
            let (re, im) = (kd.cosh(), 0.5 * (1.0 / m - m) * kd.sinh());
            let want = 1.0 / (re * re + im * im);
            let got = frustrated_transmission(th.cos(), c1, c2, z1, z2, d, f).unwrap();
            assert!((got - want).abs() < 1e-12, "{deg}°: {got} vs {want}");
            assert!(got > 0.0 && got <= 1.0);
        }
    }

    /// At a smooth interface beyond the critical angle, the layer splits the
    /// branch into a reflection `√(1 − |T|²)` and a tunnelled continuation
    /// `|T|` in the incident direction: energy is conserved (same medium on
    /// both sides). Without a layer, or below the critical angle, the
    /// interface scatters as before.
    #[test]
    fn a_smooth_layer_splits_energy_beyond_the_critical_angle() {
        use crate::ggx::Interface;
        use usray_geometry::Vec3;
        let iface = Interface {
            c1: 1480.0,
            c2: 1600.0,
            z1: 1.48,
            z2: 1.76,
            alpha: 0.0,
            planar: true,
        };
        let layer = Some(Layer {
            thickness_m: 0.15e-3,
            frequency_hz: 2.5e6,
        });
        let n = Vec3::new(0.0, 0.0, -1.0);
        let th = 80f64.to_radians();
        let d = Vec3::new(th.sin(), 0.0, th.cos());
        let s = iface.scatter_through(-d, n, 0.3, 0.6, layer).unwrap();
        assert!(s.tunnelled);
        let (r, t) = (s.reflected.unwrap(), s.transmitted.unwrap());
        assert!((r.weight * r.weight + t.weight * t.weight - 1.0).abs() < 1e-12);
        let want = frustrated_transmission(th.cos(), 1480.0, 1600.0, 1.48, 1.76, 0.15e-3, 2.5e6);
        assert!((t.weight * t.weight - want.unwrap()).abs() < 1e-12);
        assert!((t.wo - d).length() < 1e-12);
        // No layer: total reflection, as the single interface gives.
        let single = iface.scatter(-d, n, 0.3, 0.6).unwrap();
        assert!(!single.tunnelled && single.transmitted.is_none());
        assert_eq!(single.reflected.unwrap().weight, 1.0);
        // Below the critical angle the layer changes nothing.
        let th = 30f64.to_radians();
        let d = Vec3::new(th.sin(), 0.0, th.cos());
        let a = iface.scatter_through(-d, n, 0.3, 0.6, layer).unwrap();
        let b = iface.scatter(-d, n, 0.3, 0.6).unwrap();
        assert!(!a.tunnelled);
        assert_eq!(a.transmitted.unwrap().weight, b.transmitted.unwrap().weight);
    }

    /// Grazing incidence (`cos θ1 → 0`) reflects everything; tunnelling grows
    /// toward the critical angle.
    #[test]
    fn grazing_reflects_and_critical_transmits_more() {
        let at = |deg: f64| {
            frustrated_transmission(
                deg.to_radians().cos(),
                1480.0,
                1600.0,
                1.48,
                1.76,
                0.15e-3,
                2.5e6,
            )
            .unwrap()
        };
        assert!(at(89.99) < 1e-3);
        assert!(at(70.0) > at(80.0) && at(80.0) > at(88.0));
    }
}
