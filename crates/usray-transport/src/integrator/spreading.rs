//! Geometrical spreading in the 2-D transport: each path carries its ray
//! tube (dynamic ray tracing in the plane), so that its echo has the pressure
//! of ray theory rather than the energy of the Monte Carlo ray density.
//!
//! # Why
//! The estimator spreads *energy*: the density of rays, and a receiver
//! connection's element angle `w cos θ_e / r`, make a path's deposit
//! proportional to the ray tube's width ratio `Q₀/Q` — the law of an
//! intensity — while its coefficients (Fresnel `R`, `T`) are pressures. Ray
//! theory's pressure falls as the square root of that ratio (Červený,
//! *Seismic Ray Theory*, 2001, §4.10: `p ∝ 1/√J`, `J` the ray Jacobian): in
//! 2-D a line scatterer's echo falls as `1/√r`, a convex wall's as
//! `√(f/(D + f))` (focal length `f`, distance `D`), not as their squares.
//! Against 2-D full-wave data (k-Wave) the energy law made every deeper face
//! of a ring too faint (the far wall of the thin ring by 15%, so its two
//! faces, a half period apart, summed 8 ns early), a depth trend that
//! attenuation and depth gain then explained.
//!
//! # What a path carries
//! The tube's width `Q` (per unit width of the emitted wave; per radian of a
//! point source, in units of [`POINT_SOURCE_REFERENCE_M`]), its rate of
//! change `P = dQ/ds` (1/m; the wavefront's curvature is `P/Q`), and `J`, the
//! product of the width jumps `cos θ_t / cos θ_i` of its refractions. Along a
//! straight segment `Q += P·s`. At an interface of in-plane curvature `κ`
//! (positive where it is convex towards the incident side), with incidence
//! and transmission cosines taken about the (micro)facet normal:
//! - reflection (the mirror equation in the plane of incidence, whose focal
//!   length is `ρ cos θ / 2`): `P ← P + 2κQ / cos θ`;
//! - refraction (Coddington's tangential equation, `n = 1/c`:
//!   `n₂ cos²θ_t K_t = n₁ cos²θ_i K_i + (n₁ cos θ_i − n₂ cos θ_t) κ` with
//!   `K = P/Q`): `Q ← Q cos θ_t / cos θ_i`, `J ← J cos θ_t / cos θ_i`,
//!   `P ← [c₂ cos θ_i P + (c₂ cos θ_i − c₁ cos θ_t) κ Q / cos θ_i] / (c₁ cos θ_t)`.
//!
//! The estimator's deposit carries `Q₀/Q` (ray density, jumps included); ray
//! theory's pressure carries `√(Q₀ J / Q)` (the Fresnel `T` already holds the
//! jump's share). So each deposit is multiplied by
//! `C = √(|Q| J / Q₀)` ([`Spread::pressure_factor`]), which is 1 wherever
//! the tube keeps its width (a plane wave on planes). `|Q|`: past a caustic
//! (`Q` through 0, the focus of a concave wall) ray theory keeps the
//! amplitude law and shifts the phase, which this model does not carry.
//!
//! The factor is a smooth function of the path, so a connection and the
//! continuation it is MIS-weighted against carry the same factor and the
//! estimate stays unbiased for its new integrand; near a specular path (a
//! narrow rough lobe) it is the specular tube's, so the lobe's integral gives
//! ray theory's echo. A diffusely rough surface (a wide lobe) scatters as
//! independent facets, whose echo is an incoherent sum that this correction
//! does not make pressure-like.
//!
//! 3-D paths carry no tube (the factor is 1): their spreading keeps the
//! energy law (`docs/architecture.md`, "Spreading").

use usray_ad::Real;
use usray_geometry::Vec3;

/// The width unit of a point source's tube (cosine emission, a volume
/// scatterer): 1 mm. A point source's pressure then falls as `√(1 mm / r)`
/// where the energy law gives `1 mm / r`: equal at 1 mm.
pub const POINT_SOURCE_REFERENCE_M: f64 = 1e-3;

/// Smallest cosine the interface rules divide by (grazing incidence, where
/// the lobes' weights vanish anyway).
const MIN_COS: f64 = 1e-6;

/// A path's 2-D ray tube (module docs).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Spread<T> {
    /// Width `Q`, in units of the emitted tube's.
    q: T,
    /// `dQ/ds`, 1/m.
    p: T,
    /// Product of the refractions' width jumps (and, after a volume
    /// scatterer, its incident factor `|Q| J`).
    jumps: T,
}

impl<T: Real> Spread<T> {
    /// A wave whose front has curvature `curvature` (1/m, positive diverging)
    /// at the start: `Q = 1`, `P = curvature` (0 for a plane wave).
    pub(crate) fn wavefront(curvature: T) -> Self {
        Self {
            q: T::one(),
            p: curvature,
            jumps: T::one(),
        }
    }

    /// A point source (cosine emission): `Q = 0`, `P = 1/(1 mm)`.
    pub(crate) fn point_source() -> Self {
        Self {
            q: T::zero(),
            p: T::from_f64(1.0 / POINT_SOURCE_REFERENCE_M),
            jumps: T::one(),
        }
    }

    /// The tube `s` metres further along a straight segment.
    pub(crate) fn advanced(self, s: T) -> Self {
        Self {
            q: self.q + self.p * s,
            ..self
        }
    }

    /// The tube after reflecting `wi → wo` (both pointing away from the
    /// surface) off an interface of curvature `kappa` (1/m, positive convex
    /// towards `wi`): the facet normal is their half vector.
    pub(crate) fn reflected(self, wi: Vec3<T>, wo: Vec3<T>, kappa: T) -> Self {
        let h = (wi + wo).normalize();
        let cos_i = wi.dot(h).abs().max(T::from_f64(MIN_COS));
        Self {
            p: self.p + (kappa * self.q).scale(2.0) / cos_i,
            ..self
        }
    }

    /// The tube after refracting `wi → wo` (`wi` pointing back into the
    /// incident medium, speed `c1`; `wo` into the other, `c2`) at an interface
    /// of curvature `kappa` (positive convex towards `wi`): the facet normal
    /// is the generalised half vector `∝ wi/c₁ + wo/c₂` (Walter et al. 2007).
    pub(crate) fn refracted(self, wi: Vec3<T>, wo: Vec3<T>, c1: T, c2: T, kappa: T) -> Self {
        let h = (wi * c1.recip() + wo * c2.recip()).normalize();
        let min = T::from_f64(MIN_COS);
        let cos_i = wi.dot(h).abs().max(min);
        let cos_t = wo.dot(h).abs().max(min);
        let jump = cos_t / cos_i;
        let p = (c2 * cos_i * self.p + (c2 * cos_i - c1 * cos_t) * kappa * self.q / cos_i)
            / (c1 * cos_t);
        Self {
            q: self.q * jump,
            p,
            jumps: self.jumps * jump,
        }
    }

    /// `C²` = `|Q| J`.
    fn pressure_factor_squared(self) -> T {
        self.q.abs() * self.jumps
    }

    /// The factor `C = √(|Q| J)` that turns the estimator's energy spreading
    /// into ray theory's pressure (module docs), at this point of the tube.
    pub(crate) fn pressure_factor(self) -> T {
        self.pressure_factor_squared().safe_sqrt()
    }
}

#[cfg(test)]
mod tests {
    //! The tube rules against explicit rays: two neighbouring rays traced by
    //! Snell's law through a circle (the 2-D cut of a cylinder), their
    //! separation on a common wavefront divided by their initial separation.
    use super::*;

    type V = Vec3<f64>;
    const C_WATER: f64 = 1480.0;
    const C_WALL: f64 = 1600.0;
    const CENTRE: [f64; 3] = [0.0, 0.0, 0.016];
    const RADIUS: f64 = 5e-3;

    fn v(a: [f64; 3]) -> V {
        Vec3::new(a[0], a[1], a[2])
    }

    /// Distance along unit `d` from `o` to the circle: the nearer crossing
    /// from outside, the farther from inside.
    fn circle_hit(o: V, d: V, inside: bool) -> f64 {
        let oc = o - v(CENTRE);
        let b = oc.dot(d);
        let disc = (b * b - oc.dot(oc) + RADIUS * RADIUS).sqrt();
        if inside {
            -b + disc
        } else {
            -b - disc
        }
    }

    fn reflect(d: V, n: V) -> V {
        d - n * (2.0 * d.dot(n))
    }

    /// Snell's law, `n` facing the incident side, speeds `c1 → c2`.
    fn refract(d: V, n: V, c1: f64, c2: f64) -> V {
        let eta = c2 / c1;
        let cos_i = -d.dot(n);
        let cos_t = (1.0 - eta * eta * (1.0 - cos_i * cos_i)).sqrt();
        d * eta + n * (eta * cos_i - cos_t)
    }

    /// A ray from `o` along `d` in speed `c1` meets the circle (from inside
    /// when `inside`), reflects or refracts into speed `c2`, and runs on to
    /// travel time `t_end`: its end point, the hit distance and directions.
    fn trace(
        o: V,
        d: V,
        inside: bool,
        reflected: bool,
        c1: f64,
        c2: f64,
        t_end: f64,
    ) -> (V, f64, V) {
        let s = circle_hit(o, d, inside);
        let p = o + d * s;
        let outward = (p - v(CENTRE)) * RADIUS.recip();
        let n_inc = if inside { -outward } else { outward };
        let (wo, c_out) = if reflected {
            (reflect(d, n_inc), c1)
        } else {
            (refract(d, n_inc, c1, c2), c2)
        };
        (p + wo * ((t_end - s / c1) * c_out), s, wo)
    }

    /// The tube width of a plane wave's rays at `x` (moving `+z` from depth
    /// `z0`) after the circle and the rest of travel time `t_end`, by central
    /// differences of explicit rays, against [`Spread`]'s.
    fn check(x: f64, z0: f64, inside: bool, reflected: bool, c1: f64, c2: f64, t_end: f64) {
        let d = Vec3::new(0.0, 0.0, 1.0);
        let dx = 1e-8;
        let end = |x| trace(Vec3::new(x, 0.0, z0), d, inside, reflected, c1, c2, t_end).0;
        let width = (end(x + dx) - end(x - dx)).length() / (2.0 * dx);
        let (_, s, wo) = trace(Vec3::new(x, 0.0, z0), d, inside, reflected, c1, c2, t_end);
        let kappa = if inside {
            -RADIUS.recip()
        } else {
            RADIUS.recip()
        };
        let tube = Spread::<f64>::wavefront(0.0).advanced(s);
        let (tube, rest) = if reflected {
            (tube.reflected(-d, wo, kappa), (t_end - s / c1) * c1)
        } else {
            (tube.refracted(-d, wo, c1, c2, kappa), (t_end - s / c1) * c2)
        };
        let q = tube.advanced(rest).q;
        assert!(
            (q.abs() - width).abs() < 1e-5 * width.max(1.0),
            "x {x} inside {inside} reflected {reflected}: tube {q} vs rays {width}"
        );
    }

    #[test]
    fn reflection_off_a_convex_and_a_concave_circle_follows_the_rays() {
        for x in [0.0, 1e-3, 2.5e-3, -4e-3] {
            // From outside (convex), back up 20 µs.
            check(x, 0.0, false, true, C_WATER, C_WATER, 20e-6);
            // From the centre line inside (concave), through the focus and beyond.
            check(x, CENTRE[2], true, true, C_WATER, C_WATER, 12e-6);
        }
    }

    #[test]
    fn refraction_into_and_out_of_a_circle_follows_the_rays() {
        for x in [0.0, 1e-3, 2.5e-3, -4e-3] {
            // Into a faster cylinder through its convex face.
            check(x, 0.0, false, false, C_WATER, C_WALL, 14e-6);
            // Out of it through the concave (from inside) far face.
            check(x, CENTRE[2], true, false, C_WALL, C_WATER, 6e-6);
        }
    }

    #[test]
    fn a_point_source_below_a_flat_interface_seen_through_it() {
        // A point source at depth `a` in the wall under a flat interface,
        // seen from the water above it: the width per radian by explicit
        // rays, in units of the point source's reference length.
        let a = 2e-3;
        let ray_width = |theta: f64| {
            let h = 1e-7;
            let end = |t: f64| {
                let d = Vec3::new(t.sin(), 0.0, -t.cos());
                let p = d * (a / t.cos());
                let wo = refract(d, Vec3::new(0.0, 0.0, 1.0), C_WALL, C_WATER);
                // Equal travel time: the rest of a common time in water.
                p + wo * ((20e-6 - (a / t.cos()) / C_WALL) * C_WATER)
            };
            (end(theta + h) - end(theta - h)).length() / (2.0 * h)
        };
        for theta in [0.0_f64, 0.2, 0.4] {
            let d = Vec3::new(theta.sin(), 0.0, -theta.cos());
            let wo = refract(d, Vec3::new(0.0, 0.0, 1.0), C_WALL, C_WATER);
            let rest = (20e-6 - (a / theta.cos()) / C_WALL) * C_WATER;
            let tube = Spread::<f64>::point_source()
                .advanced(a / theta.cos())
                .refracted(-d, wo, C_WALL, C_WATER, 0.0)
                .advanced(rest);
            let want = ray_width(theta) / POINT_SOURCE_REFERENCE_M;
            assert!(
                (tube.q - want).abs() < 1e-5 * want,
                "θ {theta}: tube {} vs rays {want}",
                tube.q
            );
        }
    }

    #[test]
    fn the_pressure_factor_is_one_where_the_tube_keeps_its_width() {
        // A plane wave reflected and refracted by flat interfaces at normal
        // incidence: no spreading, no jump.
        let up = Vec3::new(0.0, 0.0, 1.0);
        let down = -up;
        let t = Spread::<f64>::wavefront(0.0)
            .advanced(0.01)
            .refracted(up, down, C_WATER, C_WALL, 0.0)
            .advanced(0.002)
            .reflected(up, up, 0.0)
            .advanced(0.03);
        assert!((t.pressure_factor() - 1.0).abs() < 1e-12);
        // A point source's factor √(r / 1 mm): 1 at 1 mm.
        let p = Spread::<f64>::point_source().advanced(POINT_SOURCE_REFERENCE_M);
        assert!((p.pressure_factor() - 1.0).abs() < 1e-12);
        // A scatterer's echo carries the incident tube's factor times its own
        // point source's (integrator::volume): lit at 4 mm from a point
        // source (factor 2), seen from 9 mm (factor 3).
        let incident = Spread::<f64>::point_source().advanced(4e-3);
        let own = Spread::<f64>::point_source().advanced(9e-3);
        assert!((incident.pressure_factor() - 2.0).abs() < 1e-12);
        assert!((own.pressure_factor() - 3.0).abs() < 1e-12);
    }
}
