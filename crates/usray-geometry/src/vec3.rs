//! Generic three-vectors ([`Vec3`]) over any [`Real`] scalar.

use core::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};
use usray_ad::Real;

/// A 3-vector whose components are any [`Real`] scalar (`f32`, `f64`, a dual, …).
///
/// Positions are in metres in the frame named by the variable holding them
/// (`p_world`, `p_object`); directions are dimensionless.
///
/// ```
/// use usray_geometry::Vec3;
/// let a = Vec3::new(1.0_f64, 0.0, 0.0);
/// let b = Vec3::new(0.0_f64, 1.0, 0.0);
/// assert_eq!(a.cross(b).value(), [0.0, 0.0, 1.0]);
/// assert_eq!((a + b).dot(a), 1.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vec3<T> {
    /// x component (probe frame: lateral).
    pub x: T,
    /// y component (probe frame: elevation).
    pub y: T,
    /// z component (probe frame: depth).
    pub z: T,
}

impl<T: Real> Vec3<T> {
    /// A vector from its components.
    #[inline]
    pub fn new(x: T, y: T, z: T) -> Self {
        Self { x, y, z }
    }

    /// The zero vector (constants, no derivative).
    #[inline]
    pub fn zero() -> Self {
        Self::new(T::zero(), T::zero(), T::zero())
    }

    /// A constant vector (zero derivative) from plain `f64` components.
    #[inline]
    pub fn from_f64s(v: [f64; 3]) -> Self {
        Self::new(T::from_f64(v[0]), T::from_f64(v[1]), T::from_f64(v[2]))
    }

    /// The primal values of the components.
    #[inline]
    pub fn value(&self) -> [f64; 3] {
        [self.x.value(), self.y.value(), self.z.value()]
    }

    /// The same vector in `f64` (values only).
    #[inline]
    pub fn to_f64(&self) -> Vec3<f64> {
        Vec3::new(self.x.value(), self.y.value(), self.z.value())
    }

    /// The same values with every derivative cut (see [`Real::detach`]).
    #[inline]
    pub fn detach(&self) -> Self {
        Self::new(self.x.detach(), self.y.detach(), self.z.detach())
    }

    /// Dot product `a·b`.
    #[inline]
    pub fn dot(self, o: Self) -> T {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Cross product `a × b` (right-handed).
    #[inline]
    pub fn cross(self, o: Self) -> Self {
        Self::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }

    /// Squared Euclidean length.
    #[inline]
    pub fn length_squared(self) -> T {
        self.dot(self)
    }

    /// Euclidean length, with a finite derivative at the zero vector
    /// (uses [`Real::safe_sqrt`]: the derivative there is taken as 0).
    #[inline]
    pub fn length(self) -> T {
        self.length_squared().safe_sqrt()
    }

    /// The unit vector `v/|v|`, safe everywhere.
    ///
    /// The vector is first divided by its largest absolute component (a constant,
    /// which leaves the direction and its derivative unchanged) so that very small
    /// or very large vectors neither underflow nor overflow. **A zero vector (all
    /// component values exactly 0) returns the zero vector** as a constant: finite
    /// value, zero (finite) derivatives. Callers that need a direction must handle
    /// that case themselves (a zero direction never occurs for unit rays).
    ///
    /// ```
    /// use usray_geometry::Vec3;
    /// let n = Vec3::new(3.0_f64, 0.0, 4.0).normalize();
    /// assert_eq!(n.value(), [0.6, 0.0, 0.8]);
    /// assert_eq!(Vec3::<f64>::zero().normalize().value(), [0.0; 3]);
    /// ```
    #[inline]
    pub fn normalize(self) -> Self {
        let m = self
            .x
            .value()
            .abs()
            .max(self.y.value().abs())
            .max(self.z.value().abs());
        if m.is_nan() || m <= 0.0 || !m.is_finite() {
            return Self::zero();
        }
        let v = self.scale(1.0 / m);
        let len = v.length_squared().sqrt();
        Self::new(v.x / len, v.y / len, v.z / len)
    }

    /// Multiply by a plain constant `k` (no derivative through `k`).
    #[inline]
    pub fn scale(self, k: f64) -> Self {
        Self::new(self.x.scale(k), self.y.scale(k), self.z.scale(k))
    }

    /// Component-wise product.
    #[inline]
    pub fn mul_elem(self, o: Self) -> Self {
        Self::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }

    /// True when every component (value and derivatives) is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }

    /// Component by index (0 = x, 1 = y, 2 = z; anything else is z).
    #[inline]
    pub fn get(&self, i: usize) -> T {
        match i {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }

    /// `f32` glam vector of the values (for BVH building and display).
    #[inline]
    pub fn to_glam_f32(&self) -> glam::Vec3 {
        glam::Vec3::new(
            self.x.value() as f32,
            self.y.value() as f32,
            self.z.value() as f32,
        )
    }
}

impl<T: Real> Add for Vec3<T> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl<T: Real> AddAssign for Vec3<T> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<T: Real> Sub for Vec3<T> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl<T: Real> SubAssign for Vec3<T> {
    #[inline]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

impl<T: Real> Neg for Vec3<T> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}

impl<T: Real> Mul<T> for Vec3<T> {
    type Output = Self;
    #[inline]
    fn mul(self, k: T) -> Self {
        Self::new(self.x * k, self.y * k, self.z * k)
    }
}

impl From<glam::Vec3> for Vec3<f32> {
    #[inline]
    fn from(v: glam::Vec3) -> Self {
        Self::new(v.x, v.y, v.z)
    }
}

impl From<Vec3<f32>> for glam::Vec3 {
    #[inline]
    fn from(v: Vec3<f32>) -> Self {
        glam::Vec3::new(v.x, v.y, v.z)
    }
}

impl From<[f64; 3]> for Vec3<f64> {
    #[inline]
    fn from(v: [f64; 3]) -> Self {
        Self::new(v[0], v[1], v[2])
    }
}
