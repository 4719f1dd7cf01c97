//! The linear array (CONTRACT §1): element positions, emission sampling, transmit
//! delays and the two directivities.
//!
//! Frame: `x` lateral along the array, `y` elevation, `z` depth; element centres at
//! `x_e = (e − (N−1)/2)·pitch`, `y = z = 0`; every element's normal is `+z`.
//!
//! **Elevation.** Emission points are sampled uniformly over each element's
//! face (`element_width_m` × `elevation_m`), and emission directions over the
//! full 3-D cosine-weighted hemisphere (no restriction in elevation): scenes are
//! 3-D; a cylinder along `y` is infinite, so out-of-plane rays see the same
//! cross-section tilted, and rays leaving the elevation slab simply miss the
//! receivers.

use usray_ad::Real;
use usray_geometry::Vec3;

/// `x` of element `e`'s centre, metres: `(e − (N−1)/2)·pitch`.
#[inline]
pub fn element_x<T: Real>(pitch: T, n_elements: usize, e: usize) -> T {
    pitch.scale(e as f64 - (n_elements as f64 - 1.0) * 0.5)
}

/// Cosine-weighted direction on the `+z` hemisphere from two uniforms (Malley's
/// method, pbrt-v4 §A.5.3): density `cos θ / π` per steradian.
#[inline]
pub fn cosine_hemisphere(u1: f64, u2: f64) -> [f64; 3] {
    let r = u1.sqrt();
    let phi = 2.0 * core::f64::consts::PI * u2;
    [r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt()]
}

/// Transmit directivity, paper eq. `directivity`: `f_d = max(0, n·ω)` with
/// `n = +z`, so `f_d = max(0, ω_z)` (dimensionless).
#[inline]
pub fn transmit_directivity<T: Real>(dir: Vec3<T>) -> T {
    dir.z.max(T::zero())
}

/// Receive directivity, paper eq. `cutoff`: with `α = arccos(n·ω)` the angle
/// between the element normal and the direction back towards the source
/// (`cos_alpha = −d_z` for an arriving propagation direction `d`), `1` inside the
/// main lobe `α_m`, falling linearly to `0` at the cutoff `α_c`, `0` beyond.
#[inline]
pub fn receive_directivity<T: Real>(cos_alpha: T, main_lobe: T, cutoff: T) -> T {
    ReceiveLobe::new(main_lobe, cutoff).eval(cos_alpha)
}

/// [`receive_directivity`] of fixed lobe angles, with their cosines computed
/// once (the tracer evaluates it for every receiver connection).
#[derive(Clone, Copy, Debug)]
pub struct ReceiveLobe<T> {
    main_lobe: T,
    cutoff: T,
    cos_main_lobe: f64,
    cos_cutoff: f64,
}

impl<T: Real> ReceiveLobe<T> {
    /// The lobe of main-lobe angle `main_lobe` and cutoff `cutoff`, radians.
    #[inline]
    pub fn new(main_lobe: T, cutoff: T) -> Self {
        Self {
            main_lobe,
            cutoff,
            cos_main_lobe: main_lobe.value().cos(),
            cos_cutoff: cutoff.value().cos(),
        }
    }

    /// False when the directivity at `cos_alpha` is certainly 0 (beyond the
    /// cutoff); a cheap test before [`ReceiveLobe::eval`].
    #[inline]
    pub fn may_receive(&self, cos_alpha: f64) -> bool {
        cos_alpha > 0.0 && cos_alpha >= self.cos_cutoff
    }

    /// The directivity at `cos_alpha` (see [`receive_directivity`]).
    #[inline]
    pub fn eval(&self, cos_alpha: T) -> T {
        // Compare cosines first: the arccos is needed only on the linear flank.
        let c = cos_alpha.value();
        if !self.may_receive(c) {
            return T::zero();
        }
        if c >= self.cos_main_lobe {
            return T::one();
        }
        let (main_lobe, cutoff) = (self.main_lobe, self.cutoff);
        let a = cos_alpha.safe_acos();
        if a.value() > cutoff.value() {
            T::zero()
        } else if a.value() <= main_lobe.value() {
            T::one()
        } else {
            (cutoff - a) / (cutoff - main_lobe)
        }
    }
}

/// Plane-wave transmit delay of an element at lateral position `x` (CONTRACT §1):
/// it fires at `x·sin θ / c` seconds so that the wavefront passes `(0, 0)` at
/// `t = 0`. `c` is the speed the scanner assumes (`imaging.sound_speed_m_s`).
#[inline]
pub fn transmit_delay<T: Real>(x: T, angle: T, c: T) -> T {
    x * angle.sin() / c
}

/// The element whose face contains the point `(x, y)` on the array plane.
pub fn element_at<T: Real>(
    x: f64,
    y: f64,
    pitch: T,
    width: T,
    elevation: T,
    n_elements: usize,
) -> Option<usize> {
    let (p, w, el) = (pitch.value(), width.value(), elevation.value());
    if y.abs() > 0.5 * el {
        return None;
    }
    let k = (x / p + (n_elements as f64 - 1.0) * 0.5).round();
    if !(k >= 0.0 && k < n_elements as f64) {
        return None;
    }
    let e = k as usize;
    let xe = element_x(pitch, n_elements, e).value();
    ((x - xe).abs() <= 0.5 * w).then_some(e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometry_and_directivity() {
        assert_eq!(element_x(0.3e-3_f64, 128, 0), -63.5 * 0.3e-3);
        assert_eq!(
            element_at(0.15e-3 - 1e-6, 0.0, 0.3e-3_f64, 0.27e-3, 4e-3, 128),
            Some(64)
        );
        assert_eq!(element_at(0.0, 0.0, 0.3e-3_f64, 0.27e-3, 4e-3, 128), None); // kerf
        let (m, c) = (5f64.to_radians(), 60f64.to_radians());
        assert_eq!(receive_directivity(1.0_f64, m, c), 1.0);
        assert!((receive_directivity(32.5f64.to_radians().cos(), m, c) - 0.5).abs() < 1e-9);
        assert_eq!(receive_directivity(70f64.to_radians().cos(), m, c), 0.0);
        let d = cosine_hemisphere(0.3, 0.7);
        assert!(((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) - 1.0).abs() < 1e-12);
    }
}
