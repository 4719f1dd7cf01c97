//! Rays ([`Ray`]): an origin (metres) and a unit direction.

use crate::Vec3;
use usray_ad::Real;

/// A ray `x(t) = origin + t·dir`, `t` in metres when `dir` is a unit vector.
///
/// `dir` **must be a unit vector**: every intersection routine returns `t` in
/// units of `|dir|`, and the transport reads `t` as a distance in metres (time of
/// flight `t/c`). Use [`Ray::new_normalized`] when the direction is not unit yet.
///
/// ```
/// use usray_geometry::{Ray, Vec3};
/// let r = Ray::new_normalized(Vec3::new(0.0_f64, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0));
/// assert_eq!(r.at(0.5).value(), [0.0, 0.0, 0.5]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray<T> {
    /// Start point, metres.
    pub origin: Vec3<T>,
    /// Unit direction of travel.
    pub dir: Vec3<T>,
}

impl<T: Real> Ray<T> {
    /// A ray from an origin and an already unit direction (not checked).
    #[inline]
    pub fn new(origin: Vec3<T>, dir: Vec3<T>) -> Self {
        Self { origin, dir }
    }

    /// A ray whose direction is normalised here ([`Vec3::normalize`]).
    #[inline]
    pub fn new_normalized(origin: Vec3<T>, dir: Vec3<T>) -> Self {
        Self {
            origin,
            dir: dir.normalize(),
        }
    }

    /// A constant ray (no derivatives) from plain `f64` arrays; `dir` is normalised.
    #[inline]
    pub fn from_f64s(origin: [f64; 3], dir: [f64; 3]) -> Self {
        Self::new_normalized(Vec3::from_f64s(origin), Vec3::from_f64s(dir))
    }

    /// The point at parameter `t` (metres along a unit ray).
    #[inline]
    pub fn at(&self, t: T) -> Vec3<T> {
        self.origin + self.dir * t
    }

    /// The same ray in `f64` (values only).
    #[inline]
    pub fn to_f64(&self) -> Ray<f64> {
        Ray::new(self.origin.to_f64(), self.dir.to_f64())
    }

    /// The same ray with all derivatives cut.
    #[inline]
    pub fn detach(&self) -> Self {
        Self::new(self.origin.detach(), self.dir.detach())
    }
}
