//! The switchable effects of CONTRACT §3 (each off when its key is absent or 0).
//!
//! - **attenuation**: amplitude factor `10^(−α·f_MHz·d_cm/20)` along every segment
//!   of length `d` in a medium with `α` dB/(cm·MHz), at the centre frequency `f_c`
//!   (the usual linear-in-frequency power law, Szabo, *Diagnostic Ultrasound
//!   Imaging*, §4.2), and the echo's spectral down-shift: the path's exponent
//!   `β = Σ α_i d_i` ([`attenuation_exponent`]) moves its carrier down by
//!   `βσ_f²` ([`crate::downshift`]).
//! - **depth_gain**: the scanner's time-gain, amplitude factor
//!   `10^(g·(c·t/2 in cm)/20)` on a deposit at time `t`, `c` the imaging speed.
//! - **volume_scattering**: sub-resolution scatterers inside a material — see
//!   [`ScattererField`].
//! - **sound_speed**: transport uses the media's speeds; the imaging speed is used
//!   only by the scanner model (transmit delays, depth gain) and the beamformer.

use crate::rng::mix64;
use usray_ad::Real;
use usray_geometry::Vec3;

const DB_TO_NEPER_AMPLITUDE: f64 = core::f64::consts::LN_10 / 20.0;

/// Amplitude factor of attenuation `alpha_db_cm_mhz` over `d` metres at `fc` Hz:
/// `10^(−α·(f_c/1e6)·(100 d)/20)`.
#[inline]
pub fn attenuation<T: Real>(alpha_db_cm_mhz: T, fc: T, d: T) -> T {
    attenuation_and_exponent(alpha_db_cm_mhz, fc, d).0
}

/// [`attenuation`] and [`attenuation_exponent`] of one segment together: the
/// factor `e^{−β f_c}` and `β`, the exponent computed once (the tracer
/// carries both along a path).
#[inline]
pub fn attenuation_and_exponent<T: Real>(alpha_db_cm_mhz: T, fc: T, d: T) -> (T, T) {
    let beta = attenuation_exponent(alpha_db_cm_mhz, d);
    let x = -(beta * fc);
    if alpha_db_cm_mhz.value() == 0.0 {
        // exp(x) at x = 0 to first order: value exactly 1, derivative x' (so a
        // zero attenuation still has its gradient).
        return (T::one() + x, beta);
    }
    (x.exp(), beta)
}

/// The attenuation exponent per hertz of a segment, `β = α·d` in Np/Hz for
/// `alpha_db_cm_mhz` dB/(cm·MHz) over `d` metres: `α·(100 d)·10⁻⁶·ln 10/20`.
/// [`attenuation`] is `e^{−β f_c}`; the path's sum of `β` sets the spectral
/// down-shift of its echo ([`crate::downshift`]).
///
/// ```
/// use usray_transport::effects::{attenuation, attenuation_exponent};
/// let (a, d, fc) = (0.5_f64, 0.02, 5e6);
/// assert!((attenuation(a, fc, d) - (-attenuation_exponent(a, d) * fc).exp()).abs() < 1e-15);
/// ```
#[inline]
pub fn attenuation_exponent<T: Real>(alpha_db_cm_mhz: T, d: T) -> T {
    (alpha_db_cm_mhz * d).scale(1e-6 * 100.0 * DB_TO_NEPER_AMPLITUDE)
}

/// Amplitude factor of depth gain `g` dB/cm at time `t` s for imaging speed `c`:
/// `10^(g·(100·c·t/2)/20)`.
#[inline]
pub fn depth_gain<T: Real>(g_db_cm: T, c: T, t: T) -> T {
    let x = (g_db_cm * c * t).scale(50.0 * DB_TO_NEPER_AMPLITUDE);
    if g_db_cm.value() == 0.0 {
        // Value exactly 1, derivative x' (a zero gain keeps its gradient).
        return T::one() + x;
    }
    x.exp()
}

/// A fixed field of sub-resolution point scatterers filling a material.
///
/// Space is cut into cubic cells of side `h = (1/ρ_g)^{1/3}`, each holding exactly
/// one scatterer at a position and with an amplitude `g` that are pure hashes of
/// (object, cell): the same for every ray, transmit and seed, so echoes from
/// different rays add coherently and form **speckle** (a fixed pattern, not Monte
/// Carlo noise).
///
/// **Estimator.** Along a ray segment inside the material, scattering events are
/// found by **free-flight sampling** at rate `μ = 1/h` per metre (on average one
/// event per cell crossed); an event in a cell selects that cell's scatterer,
/// which re-radiates isotropically through a receiver connection; the ray itself
/// continues unchanged (first-order Born scattering: the scatterers are weak and
/// do not deplete the beam). Rays sample the beam's cross-section (a path's
/// weight carries the area per ray, as for a surface hit, whose contributions
/// estimate `∫ dA`), so the expected sum of an event factor `F` over all events
/// is `∫ dA ∫ μ F ds = μ ∫ F dV`. For the scatterer of a cell to contribute its
/// own amplitude `A` once, `F = A/(μ h³) = A/h²` on its cell: each event carries
/// the factor `A·(1 mm/h)²` with `A` in mm² (per steradian of the incident
/// amplitude), [`ScattererField::event_weight`] × `strength·g/(4π)`.
///
/// **Amplitudes and density.** `A = strength·√(ρ/ρ_g)·g/(4π)`, `g` uniform on
/// `[−√3, √3]` (unit variance). The grid's density `ρ_g` is the material's
/// density `ρ` rounded *up* to a power of two
/// ([`ScattererField::grid_density_per_mm3`]), and the weight `√(ρ/ρ_g)` ∈
/// (1/√2, 1] makes the expected echo power per volume `ρ_g·E[A²] ∝ ρ·strength²`,
/// the power of `ρ` scatterers per mm³ (incoherent sum of random phasors, Szabo,
/// *Diagnostic Ultrasound Imaging*, §8.3; the "equivalent scatterer" scaling of
/// Field II phantoms). So the image is a smooth function of `ρ` between powers of
/// two and the density has a gradient. The grid — positions and cell count —
/// changes only where `ρ` crosses a power of two, a discontinuity of measure zero
/// that is not differentiated (like a visibility change). The grid holds 1–2× the
/// scatterers `ρ` asks for, which leaves speckle statistics (fully developed
/// above ~10 scatterers per resolution cell) much as they are.
///
/// **In 2-D** ([`ScattererField::planar`]) the field is its cut at `y = 0`:
/// square cells of the same side `h` in the `xz` plane (so `ρ_g^{2/3}`
/// scatterers per mm², a cubic grid's density in a slab one cell thick), each
/// scatterer a line along `y` that re-radiates isotropically in the plane
/// (`1/(2π)` per radian). A path's weight then carries the width per ray, the
/// events estimate `μ ∫ F dA`, and `F = A/(μ h²) = A/h`: the event factor is
/// `√(ρ/ρ_g)·(1 mm/h)`, with `A` in mm per radian.
#[derive(Clone, Copy, Debug)]
pub struct ScattererField {
    /// Cell side `h`, metres.
    pub cell_m: f64,
    /// Density of the grid `ρ_g` (a power of two), scatterers per mm³.
    pub grid_per_mm3: f64,
    /// Key of the owning object.
    pub key: u64,
    /// The 2-D field of a planar scene (`acquisition.dimensions = 2`).
    pub planar: bool,
}

impl ScattererField {
    /// The field of object `object` with density `per_mm3` (scatterers per mm³);
    /// `None` for a density that is not positive and finite.
    ///
    /// ```
    /// use usray_transport::effects::ScattererField;
    /// let f = ScattererField::new(0, 5.0).unwrap();
    /// assert_eq!(f.grid_per_mm3, 8.0); // 5 rounded up to a power of two
    /// assert!((f.cell_m - 0.5e-3).abs() < 1e-15); // (1/8 mm³)^{1/3}
    /// assert!(ScattererField::new(0, 0.0).is_none());
    /// ```
    pub fn new(object: usize, per_mm3: f64) -> Option<Self> {
        Self::keyed(Self::material_key(object), per_mm3)
    }

    /// The field keyed `key` (its scatterers are hashes of the key and the
    /// cell) with density `per_mm3`; `None` for a density that is not positive
    /// and finite.
    pub fn keyed(key: u64, per_mm3: f64) -> Option<Self> {
        let grid = Self::grid_density_per_mm3(per_mm3)?;
        Some(Self {
            cell_m: 1e-3 * grid.powf(-1.0 / 3.0),
            grid_per_mm3: grid,
            key,
            planar: false,
        })
    }

    /// The same field cut at `y = 0` for a 2-D scene (see the type's docs).
    ///
    /// ```
    /// use usray_transport::effects::ScattererField;
    /// let f = ScattererField::new(0, 8.0).unwrap().planar(); // h = 0.5 mm
    /// assert!((f.event_weight(8.0f64) - 2.0).abs() < 1e-12); // 1 mm / h
    /// let (q, _) = f.scatterer_near::<f64>([1e-3, 0.2e-3, 2e-3]);
    /// assert_eq!(q.y, 0.0);
    /// ```
    pub fn planar(self) -> Self {
        Self {
            planar: true,
            ..self
        }
    }

    /// The angle of all directions a scatterer re-radiates into, isotropically:
    /// `4π` sr, in 2-D `2π` rad.
    pub fn full_angle(&self) -> f64 {
        if self.planar {
            2.0 * core::f64::consts::PI
        } else {
            4.0 * core::f64::consts::PI
        }
    }

    /// Key of the field filling object `object`'s material.
    pub fn material_key(object: usize) -> u64 {
        mix64(0x5ca7_7e2e_0000_0000 ^ object as u64)
    }

    /// Key of the field in object `object`'s lumen (another pattern than its
    /// wall's material).
    ///
    /// ```
    /// use usray_transport::effects::ScattererField;
    /// assert_ne!(ScattererField::lumen_key(0), ScattererField::material_key(0));
    /// ```
    pub fn lumen_key(object: usize) -> u64 {
        mix64(0x1a4e_5ca7_0000_0000 ^ object as u64)
    }

    /// `ρ_g`: the smallest power of two `≥ per_mm3` (`None` unless positive and
    /// finite).
    pub fn grid_density_per_mm3(per_mm3: f64) -> Option<f64> {
        if !(per_mm3 > 0.0 && per_mm3.is_finite()) {
            return None;
        }
        // `log2` may be off by one ulp near an exact power: correct both ways.
        let mut k = per_mm3.log2().ceil() as i32;
        while 2f64.powi(k) < per_mm3 {
            k += 1;
        }
        while 2f64.powi(k - 1) >= per_mm3 {
            k -= 1;
        }
        Some(2f64.powi(k))
    }

    /// The factor `√(ρ/ρ_g)·(1 mm/h)² = √(ρ/ρ_g)·ρ_g^{2/3}` (ρ in per mm³) of
    /// every scattering event for the material's density `ρ`, in `T`: its
    /// derivative carries the density's gradient, `∂/∂ρ = weight/(2ρ)`. In 2-D
    /// `√(ρ/ρ_g)·(1 mm/h) = √(ρ/ρ_g)·ρ_g^{1/3}`.
    ///
    /// ```
    /// use usray_transport::effects::ScattererField;
    /// let f = ScattererField::new(0, 4.0).unwrap(); // a power of two: h = 0.63 mm
    /// assert!((f.event_weight(4.0f64) - 4f64.powf(2.0 / 3.0)).abs() < 1e-12);
    /// ```
    #[inline]
    pub fn event_weight<T: Real>(&self, per_mm3: T) -> T {
        // (1 mm/h)^k with h = ρ_g^{−1/3} mm: k = 2 (a ray's cross-section is
        // an area), 1 in 2-D (a width).
        let k = if self.planar { 1.0 } else { 2.0 };
        per_mm3
            .scale(1.0 / self.grid_per_mm3)
            .sqrt()
            .scale(self.grid_per_mm3.powf(k / 3.0))
    }

    /// The scatterer of the cell containing point `p` (metres): its position
    /// (constants) and its amplitude `g`. In 2-D the cell of `p`'s projection
    /// on `y = 0`, and a position there.
    pub fn scatterer_near<T: Real>(&self, p: [f64; 3]) -> (Vec3<T>, f64) {
        self.scatterer_in(self.cell_of(p))
    }

    /// The cell containing point `p` (metres), in units of the cell side; in
    /// 2-D the cell of `p`'s projection on `y = 0`.
    ///
    /// ```
    /// use usray_transport::effects::ScattererField;
    /// let f = ScattererField::new(0, 8.0).unwrap(); // h = 0.5 mm
    /// assert_eq!(f.cell_of([1.2e-3, -0.2e-3, 2.1e-3]), [2, -1, 4]);
    /// ```
    pub fn cell_of(&self, p: [f64; 3]) -> [i64; 3] {
        let h = self.cell_m;
        [
            (p[0] / h).floor() as i64,
            if self.planar {
                0
            } else {
                (p[1] / h).floor() as i64
            },
            (p[2] / h).floor() as i64,
        ]
    }

    /// The scatterer of cell `c` ([`ScattererField::cell_of`]): its position
    /// (constants) and its amplitude `g`.
    pub fn scatterer_in<T: Real>(&self, c: [i64; 3]) -> (Vec3<T>, f64) {
        let h = self.cell_m;
        let mut k = self.key;
        for ci in c {
            k = mix64(k ^ (ci as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        }
        let u = |j: u64| (mix64(k ^ j) >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        let y = if self.planar {
            0.0
        } else {
            (c[1] as f64 + u(2)) * h
        };
        let pos = Vec3::from_f64s([(c[0] as f64 + u(1)) * h, y, (c[2] as f64 + u(3)) * h]);
        let g = (2.0 * u(4) - 1.0) * 3f64.sqrt();
        (pos, g)
    }
}
