//! The switchable effects of CONTRACT §3 (each off when its key is absent or 0).
//!
//! - **attenuation**: amplitude factor `10^(−α·f_MHz·d_cm/20)` along every segment
//!   of length `d` in a medium with `α` dB/(cm·MHz), at the centre frequency `f_c`
//!   (the usual linear-in-frequency power law, Szabo, *Diagnostic Ultrasound
//!   Imaging*, §4.2, evaluated at `f_c` only: no pulse down-shift).
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
    let x = -(alpha_db_cm_mhz * fc * d).scale(1e-6 * 100.0 * DB_TO_NEPER_AMPLITUDE);
    if alpha_db_cm_mhz.value() == 0.0 {
        // exp(x) at x = 0 to first order: value exactly 1, derivative x' (so a
        // zero attenuation still has its gradient).
        return T::one() + x;
    }
    x.exp()
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
/// Space is cut into cubic cells of side `h = (1/ρ)^{1/3}` (ρ the density in
/// scatterers per m³), each holding exactly one scatterer at a position and
/// with an amplitude `g` that are pure hashes of (object, cell): the same for
/// every ray, transmit and seed, so echoes from different rays add coherently
/// and form **speckle** (a fixed pattern, not Monte Carlo noise).
///
/// Along a ray segment inside the material, scattering events are found by
/// **free-flight sampling** at rate `μ = 1/h` per metre (on average one event per
/// cell crossed; an event in a cell selects that cell's scatterer), so that the
/// expected contribution of a cell is proportional to the ray length inside it.
/// Each event re-radiates isotropically `f = strength·g/(4π)` per steradian of
/// the incident amplitude (`g` uniform on `[−√3, √3]`, unit variance) through a
/// receiver connection; the ray itself continues unchanged (first-order Born
/// scattering: the scatterers are weak and do not deplete the beam).
/// Cell size and positions use the density's value (no gradient through them);
/// the strength carries gradients.
#[derive(Clone, Copy, Debug)]
pub struct ScattererField {
    /// Cell side `h`, metres.
    pub cell_m: f64,
    /// Key of the owning object.
    pub key: u64,
}

impl ScattererField {
    /// The field of object `object` with density `per_mm3` (scatterers per mm³).
    pub fn new(object: usize, per_mm3: f64) -> Option<Self> {
        (per_mm3 > 0.0).then(|| Self {
            cell_m: 1e-3 * per_mm3.powf(-1.0 / 3.0),
            key: mix64(0x5ca7_7e2e_0000_0000 ^ object as u64),
        })
    }

    /// The scatterer of the cell containing point `p` (metres): its position
    /// (constants) and its amplitude `g`.
    pub fn scatterer_near<T: Real>(&self, p: [f64; 3]) -> (Vec3<T>, f64) {
        let h = self.cell_m;
        let c = [
            (p[0] / h).floor() as i64,
            (p[1] / h).floor() as i64,
            (p[2] / h).floor() as i64,
        ];
        let mut k = self.key;
        for ci in c {
            k = mix64(k ^ (ci as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        }
        let u = |j: u64| (mix64(k ^ j) >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        let pos = Vec3::from_f64s([
            (c[0] as f64 + u(1)) * h,
            (c[1] as f64 + u(2)) * h,
            (c[2] as f64 + u(3)) * h,
        ]);
        let g = (2.0 * u(4) - 1.0) * 3f64.sqrt();
        (pos, g)
    }
}
