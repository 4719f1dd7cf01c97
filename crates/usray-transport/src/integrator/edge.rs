//! The edge waves of a transmit aperture (2-D): the part of a finite array's
//! transmitted field that the collimated emission does not carry.
//!
//! # Physics
//! A plane wave steered to `θ` by an aperture `[a, b]` of line sources is, by
//! the Rayleigh integral (Kirchhoff's, for a velocity source: the array's
//! elements, k-Wave's monopole rows), `p(r) ∝ ∫ₐᵇ G(|r − x'|) e^{ik x' sin θ} dx'`
//! with the 2-D Green's function `G = (i/4) H₀⁽¹⁾(kR) ≈ (i/4) √(2/(πkR))
//! e^{i(kR − π/4)}`. Its stationary point is the plane wave `P₀` (the
//! collimated rays of [`super::emission`]); its two end points add, by the
//! end-point rule of the method of stationary phase (Bleistein & Handelsman,
//! *Asymptotic Expansions of Integrals*, 1986, §3.4), one cylindrical wave
//! from each edge of the aperture:
//!
//! `p_edge(R, ψ) = P₀ · E(ψ) · e^{i(kR + π/4)} / √(2π k R)`, with
//! `E(ψ) = −cos θ / (τ·(t − d))`,
//!
//! `t` the transmitted wave's direction at the edge, `d` the direction from
//! the edge to the field point (`ψ` its angle to the element normal), `τ` the
//! aperture's outward tangent at that edge and `cos θ = n·t`. Inside the
//! insonified strip `τ·(t − d) > 0`: the edge wave is inverted there (the
//! "edge wave" of a baffled piston's impulse response; Stepanishen, JASA 49,
//! 1971). The same rule holds for diverging and focused waves with `t` their
//! direction at the edge (the delay law's derivative along the face is
//! `t·τ / c`).
//!
//! k-Wave's 2-D data of the thin ring (tier (b) of `docs/diagnosis.md`) show
//! these waves' echo on every element, 1.6–2.1 µs after the near wall's and up
//! to 18 dB below it, with the timing of this rule; a Hann-apodized transmit,
//! which has no edge waves, removes it (to −50 dB).
//!
//! # What the tracer does
//! Each end element's path also emits rays from the outer edge of its face
//! ([`EdgeWaves::rays_per_edge`]), at the wave's arrival time there, as a point source (2-D ray tube
//! [`Spread::point_source`]) whose weight makes the deposit the pressure above:
//! a point source's deposit on an element of width `w` at range `R` is
//! `A w cos θₑ / √(R · 1 mm)` for a ray amplitude density `A` (per radian), so
//! `A = (n·t) E(ψ) √(1 mm / (2πk)) / w`. The factor `e^{iπ/4}` (a half
//! integral of the pulse) is placed as a delay of `1/8` of a period at the
//! centre frequency, which puts the carrier right and the envelope 1/8 of a
//! period late.
//!
//! `E` is singular on the insonified strip's boundary (`ψ = θ`), where the
//! uniform theory replaces the two terms by a Fresnel integral whose total is
//! `P₀/2`. The tracer regularises `1/u` as `u/(u² + ε²)`, `ε = 1/√(2πk R₀)`
//! at half the recorded depth `R₀`: there the edge term peaks at `P₀/2`, as
//! the uniform field does. It is odd in `u`, so the boundary's blur adds no
//! net echo.
//!
//! Directions are drawn from a mixture (one-sample MIS, balance heuristic):
//! half uniform in `ψ ∈ (−π/2, π/2)`, half Cauchy in `u` about the boundary
//! with scale `ε`, so the weight stays bounded on both sides of it. One
//! uniform picks the component and the value, so that the element's
//! stratified rays stratify both.
//!
//! 3-D transport has no edge waves: its spreading keeps the energy law
//! (`docs/architecture.md`, "Spreading"), in which this pressure rule has no
//! counterpart.

use super::spreading::POINT_SOURCE_REFERENCE_M;
use core::f64::consts::PI;
use usray_ad::Real;

/// The edge waves' constants for one lifted scene.
#[derive(Clone, Copy, Debug)]
pub struct EdgeWaves<T> {
    /// `√(1 mm / (2πk)) / w`, 1/m·m = dimensionless per radian.
    scale: T,
    /// The boundary's regularisation `ε = 1/√(2πk R₀)`.
    epsilon: T,
    /// The half integral's delay, `1/(8 f_c)`, s.
    delay_s: T,
    /// Rays each edge traces per path of its end element.
    rays_per_edge: u32,
}

impl<T: Real> EdgeWaves<T> {
    /// The constants at centre frequency `f_c` (Hz) in a medium of speed `c`
    /// (m/s), for `n_elements` elements `w` wide (m), with the boundary
    /// regularised at range `reference_range_m`.
    pub fn new(
        center_frequency: T,
        sound_speed: T,
        element_width: T,
        n_elements: usize,
        reference_range_m: f64,
    ) -> Self {
        let two_pi_k = (center_frequency / sound_speed).scale(4.0 * PI * PI);
        Self {
            scale: (two_pi_k.recip().scale(POINT_SOURCE_REFERENCE_M)).sqrt() / element_width,
            epsilon: (two_pi_k.scale(reference_range_m)).sqrt().recip(),
            delay_s: center_frequency.scale(8.0).recip(),
            rays_per_edge: (n_elements as u32).div_ceil(2),
        }
    }

    /// Rays each edge traces per path of its end element: half the number
    /// of elements, so that the two edges trace as many rays as the
    /// aperture's collimated beamlets. One ray per edge left their echoes
    /// noisier than the rest of the image (a seed-to-seed loss of 0.036
    /// against 0.005 without edge waves, 64 elements at 20 rays); the noise
    /// falls as `1/√rays` (0.016 at 8, 0.0065 at 64), and an edge ray costs
    /// less than a beamlet, most of them leaving the image unreflected.
    pub fn rays_per_edge(&self) -> u32 {
        self.rays_per_edge
    }

    /// The delay of the edge wave's pulse after the wave's arrival at the edge, s.
    pub fn delay_s(&self) -> T {
        self.delay_s
    }

    /// `E(ψ)` regularised: `−cos θ · u / (u² + ε²)` with `u = τ·(t − d)`.
    pub fn coefficient(&self, cos_theta: T, u: T) -> T {
        -(cos_theta * u) / (u * u + self.epsilon * self.epsilon)
    }

    /// The ray amplitude density (per radian) of direction `ψ`, `u = τ·(t − d)`:
    /// `(n·t) E(ψ) √(1 mm/(2πk)) / w` (module docs).
    pub fn amplitude(&self, cos_theta: T, u: T) -> T {
        cos_theta * self.coefficient(cos_theta, u) * self.scale
    }

    /// Draw `sin ψ` of an edge ray from one uniform `u` (its lower half
    /// picks the uniform component, its upper half the Cauchy one, each
    /// rescaled to `[0, 1)`, so that a stratified `u` stratifies both) for a
    /// wave with `sin θ = t·t̂` (`t̂` the element's tangent) at the edge whose
    /// outward tangent is `side · t̂` (`side = ±1`), and its mixture density
    /// per radian. Both are functions of the parameters (through `ε` and
    /// `sin θ`), differentiated like every other sample of the tracer, so
    /// that a fixed seed's estimate is differentiable. `None` when the Cauchy
    /// component falls outside the half plane.
    pub fn sample(&self, sin_theta: T, side: f64, u: f64) -> Option<(T, T)> {
        let sin_psi = if u < 0.5 {
            T::from_f64((PI * (2.0 * u - 0.5)).sin())
        } else {
            let v = self.epsilon.scale((PI * (2.0 * u - 1.5)).tan());
            let s = sin_theta - v.scale(side);
            // (A NaN from a non-finite tangent is refused with the rest.)
            if s.value().is_nan() || s.value().abs() >= 1.0 {
                return None;
            }
            s
        };
        let pdf = self.pdf(sin_theta, side, sin_psi);
        (pdf.value() > 0.0).then_some((sin_psi, pdf))
    }

    /// The mixture's density per radian of `ψ` (see [`Self::sample`]).
    pub fn pdf(&self, sin_theta: T, side: f64, sin_psi: T) -> T {
        let eps = self.epsilon;
        let u = (sin_theta - sin_psi).scale(side);
        let cos_psi = (T::one() - sin_psi * sin_psi).max(T::zero()).sqrt();
        let cauchy = eps / (u * u + eps * eps) * cos_psi;
        (T::one() + cauchy).scale(0.5 / PI)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 2-D field of a finite aperture `[a, b]` steered to `θ`, by the
    /// Rayleigh integral with the large-argument Green's function, minus the
    /// plane wave, against the two edge terms of the module docs.
    #[test]
    fn the_edge_terms_are_the_rayleigh_integral_less_the_plane_wave() {
        let (f, c) = (2.5e6, 1480.0);
        let k = 2.0 * PI * f / c;
        let (a, b) = (-9.6e-3, 9.6e-3);
        for (theta_deg, x, z) in [(0.0, 0.0, 15e-3), (8.0, 2e-3, 12e-3), (-8.0, -3e-3, 20e-3)] {
            let th: f64 = f64::to_radians(theta_deg);
            // ∫ G e^{ik x' sin θ} dx', G = (i/4)√(2/(πkR)) e^{i(kR − π/4)},
            // times −2ik cos θ (the normal derivative of the incident plane
            // wave, sign fixed so that the infinite aperture gives e^{ik(x sin θ + z cos θ)}).
            let n = 400_000;
            let dx = (b - a) / n as f64;
            let (mut re, mut im) = (0.0, 0.0);
            for i in 0..n {
                let xp = a + (i as f64 + 0.5) * dx;
                let r = ((x - xp) * (x - xp) + z * z).sqrt();
                let amp = (2.0 / (PI * k * r)).sqrt() / 4.0;
                let ph = k * r - PI / 4.0 + k * xp * th.sin() + PI / 2.0; // the i of (i/4)
                re += amp * ph.cos() * dx;
                im += amp * ph.sin() * dx;
            }
            // × (−2ik cos θ) = × 2k cos θ e^{−iπ/2}.
            let s = 2.0 * k * th.cos();
            let (re, im) = (s * im, -s * re);
            let plane = k * (x * th.sin() + z * th.cos());
            let (re, im) = (re - plane.cos(), im - plane.sin());
            // The edge terms: E e^{i(k(R + x_e sin θ) + π/4)}/√(2πkR) at both edges.
            let (mut er, mut ei) = (0.0, 0.0);
            for (xe, side) in [(a, -1.0), (b, 1.0)] {
                let r = ((x - xe) * (x - xe) + z * z).sqrt();
                let u = side * (th.sin() - (x - xe) / r);
                let e = -th.cos() / u;
                let amp = e / (2.0 * PI * k * r).sqrt();
                let ph = k * (r + xe * th.sin()) + PI / 4.0;
                er += amp * ph.cos();
                ei += amp * ph.sin();
            }
            // The end-point expansion's next term is of relative order
            // 1/(kR u²): 2–3% at these points (kR 130–210, u ≈ 0.5–0.6),
            // measured 1.5–2.1%. Allowed 5%; a 10% amplitude error fails.
            let err = ((re - er).powi(2) + (im - ei).powi(2)).sqrt();
            let size = (er * er + ei * ei).sqrt();
            assert!(
                size > 0.02 && err < 0.05 * size,
                "θ {theta_deg}°, ({x}, {z}): integral less plane ({re:.4}, {im:.4}), edges ({er:.4}, {ei:.4})"
            );
        }
    }

    #[test]
    fn the_sampling_density_is_normalised_and_matches_its_samples() {
        let edges = EdgeWaves::new(2.5e6, 1480.0, 0.27e-3, 64, 20e-3);
        for (sin_t, side) in [(0.0, 1.0), (0.14, -1.0), (-0.3, 1.0)] {
            // ∫ pdf dψ over the half plane: 1 less the Cauchy mass beyond it.
            let n = 200_000;
            let mut total = 0.0;
            for i in 0..n {
                let psi = -PI / 2.0 + PI * (i as f64 + 0.5) / n as f64;
                total += edges.pdf(sin_t, side, psi.sin()) * PI / n as f64;
            }
            let eps = edges.epsilon;
            let lost = |lim: f64| 0.5 - lim.atan() / PI;
            let missing = 0.5 * (lost((1.0 - sin_t) / eps) + lost((1.0 + sin_t) / eps));
            assert!(
                (total - (1.0 - missing)).abs() < 1e-4,
                "∫pdf {total}, expected {}",
                1.0 - missing
            );
            // Histogram of the samples against the density, in 8 bins of ψ.
            let m = 80_000;
            let mut bins = [0.0; 8];
            for i in 0..m {
                let u = (i as f64 + 0.5) / m as f64;
                if let Some((s, _)) = edges.sample(sin_t, side, u) {
                    let psi = s.asin();
                    let k = (((psi + PI / 2.0) / PI) * 8.0) as usize;
                    bins[k.min(7)] += 1.0 / m as f64;
                }
            }
            for (k, got) in bins.iter().enumerate() {
                let (lo, hi) = (
                    -PI / 2.0 + PI * k as f64 / 8.0,
                    -PI / 2.0 + PI * (k + 1) as f64 / 8.0,
                );
                let steps = 20_000;
                let want: f64 = (0..steps)
                    .map(|j| {
                        let psi = lo + (hi - lo) * (j as f64 + 0.5) / steps as f64;
                        edges.pdf(sin_t, side, psi.sin()) * (hi - lo) / steps as f64
                    })
                    .sum();
                assert!(
                    (got - want).abs() < 2e-3,
                    "bin {k}: sampled {got}, density {want}"
                );
            }
        }
    }

    #[test]
    fn the_regularised_coefficient_peaks_at_half_the_plane_wave_at_the_reference_range() {
        let (f, c, r0) = (2.5e6, 1480.0, 20e-3);
        let edges = EdgeWaves::new(f, c, 0.27e-3, 64, r0);
        let k = 2.0 * PI * f / c;
        let eps = edges.epsilon;
        let peak = edges.coefficient(1.0, -eps) / (2.0 * PI * k * r0).sqrt();
        assert!((peak - 0.5).abs() < 1e-12, "{peak}");
        // Far from the boundary it is the unregularised 1/u to 1%.
        let u = 0.5;
        assert!((edges.coefficient(1.0, u) * u + 1.0).abs() < 0.01);
    }
}
