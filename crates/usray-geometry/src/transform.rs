//! Rigid-plus-scale transforms ([`Transform`]) and 3×3 matrices ([`Mat3`]).
//!
//! Frames are named by what they map: a `world_from_object` transform takes a point
//! given in the object's own frame (as stored in a mesh file) to the world frame
//! (the probe frame of `CONTRACT.md` §1 unless the transport says otherwise):
//! `p_world = world_from_object.transform_point(p_object)`.

use crate::Vec3;
use usray_ad::Real;

/// A 3×3 matrix stored by rows, generic over [`Real`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mat3<T> {
    /// The three rows.
    pub rows: [Vec3<T>; 3],
}

impl<T: Real> Mat3<T> {
    /// The identity matrix.
    pub fn identity() -> Self {
        let (o, z) = (T::one(), T::zero());
        Self {
            rows: [Vec3::new(o, z, z), Vec3::new(z, o, z), Vec3::new(z, z, o)],
        }
    }

    /// Matrix–vector product `M·v`.
    #[inline]
    pub fn mul_vec(&self, v: Vec3<T>) -> Vec3<T> {
        Vec3::new(
            self.rows[0].dot(v),
            self.rows[1].dot(v),
            self.rows[2].dot(v),
        )
    }

    /// Transposed product `Mᵀ·v` (the inverse for a rotation).
    #[inline]
    pub fn mul_vec_transposed(&self, v: Vec3<T>) -> Vec3<T> {
        self.rows[0] * v.x + self.rows[1] * v.y + self.rows[2] * v.z
    }

    /// Matrix product `A·B`.
    pub fn mul_mat(&self, b: &Self) -> Self {
        let col = |j: usize| Vec3::new(b.rows[0].get(j), b.rows[1].get(j), b.rows[2].get(j));
        let (c0, c1, c2) = (col(0), col(1), col(2));
        let row = |r: Vec3<T>| Vec3::new(r.dot(c0), r.dot(c1), r.dot(c2));
        Self {
            rows: [row(self.rows[0]), row(self.rows[1]), row(self.rows[2])],
        }
    }

    /// Rotation about x by `a` radians (right-handed).
    pub fn rotation_x(a: T) -> Self {
        let (s, c, o, z) = (a.sin(), a.cos(), T::one(), T::zero());
        Self {
            rows: [Vec3::new(o, z, z), Vec3::new(z, c, -s), Vec3::new(z, s, c)],
        }
    }

    /// Rotation about y by `a` radians (right-handed).
    pub fn rotation_y(a: T) -> Self {
        let (s, c, o, z) = (a.sin(), a.cos(), T::one(), T::zero());
        Self {
            rows: [Vec3::new(c, z, s), Vec3::new(z, o, z), Vec3::new(-s, z, c)],
        }
    }

    /// Rotation about z by `a` radians (right-handed).
    pub fn rotation_z(a: T) -> Self {
        let (s, c, o, z) = (a.sin(), a.cos(), T::one(), T::zero());
        Self {
            rows: [Vec3::new(c, -s, z), Vec3::new(s, c, z), Vec3::new(z, z, o)],
        }
    }

    /// Rotation by the angle `|axis_angle|` (radians) about the unit axis
    /// `axis_angle/|axis_angle|`, by Rodrigues' formula
    /// `R = I + sin θ K + (1 − cos θ) K²` (`K` the cross-product matrix of the axis).
    /// A zero vector gives the identity (with zero derivative there).
    pub fn rotation_axis_angle(axis_angle: Vec3<T>) -> Self {
        let theta = axis_angle.length();
        if theta.value().is_nan() || theta.value() <= 0.0 {
            return Self::identity();
        }
        let k = axis_angle * theta.recip();
        let (s, c1) = (theta.sin(), T::one() - theta.cos());
        let z = T::zero();
        let km = Self {
            rows: [
                Vec3::new(z, -k.z, k.y),
                Vec3::new(k.z, z, -k.x),
                Vec3::new(-k.y, k.x, z),
            ],
        };
        let k2 = km.mul_mat(&km);
        let id = Self::identity();
        let mut rows = id.rows;
        for i in 0..3 {
            rows[i] = id.rows[i] + km.rows[i] * s + k2.rows[i] * c1;
        }
        Self { rows }
    }

    /// Determinant.
    pub fn determinant(&self) -> T {
        self.rows[0].dot(self.rows[1].cross(self.rows[2]))
    }

    /// Values only.
    pub fn to_f64(&self) -> Mat3<f64> {
        Mat3 {
            rows: [
                self.rows[0].to_f64(),
                self.rows[1].to_f64(),
                self.rows[2].to_f64(),
            ],
        }
    }
}

/// A differentiable similarity-like transform: per-axis scale, then rotation, then
/// translation:
///
/// `p_world = translation + R · (scale ⊙ p_object)`  (metres).
///
/// All three parts are `T`, so derivatives flow to translation, angles and scale.
/// Rotations built by [`Transform::from_euler`] use `R = Rz(γ)·Ry(β)·Rx(α)` (rotate
/// about x first, then y, then z, about fixed world axes), angles in radians.
/// Scales must be non-zero; a negative product of scales mirrors the object, which
/// [`Transform::flips_orientation`] reports so that mesh normals stay outward.
///
/// ```
/// use usray_geometry::{Transform, Vec3};
/// let w = Transform::from_euler(
///     Vec3::new(0.0_f64, 0.0, 0.02),
///     Vec3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
///     Vec3::new(2.0, 2.0, 2.0),
/// );
/// let p = w.transform_point(Vec3::new(1.0e-3, 0.0, 0.0)).value();
/// assert!((p[0] - 0.0).abs() < 1e-15 && (p[1] - 2.0e-3).abs() < 1e-15 && p[2] == 0.02);
/// let back = w.inverse_transform_point(Vec3::from_f64s(p)).value();
/// assert!((back[0] - 1.0e-3).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform<T> {
    /// Translation, metres.
    pub translation: Vec3<T>,
    /// Rotation matrix (orthonormal).
    pub rotation: Mat3<T>,
    /// Per-axis scale factors (dimensionless), applied first, in the object frame.
    pub scale: Vec3<T>,
}

impl<T: Real> Default for Transform<T> {
    fn default() -> Self {
        Self::identity()
    }
}

impl<T: Real> Transform<T> {
    /// The identity.
    pub fn identity() -> Self {
        Self {
            translation: Vec3::zero(),
            rotation: Mat3::identity(),
            scale: Vec3::new(T::one(), T::one(), T::one()),
        }
    }

    /// A pure translation (metres).
    pub fn from_translation(translation: Vec3<T>) -> Self {
        Self {
            translation,
            ..Self::identity()
        }
    }

    /// Translation, Euler angles `(α, β, γ)` in radians (`R = Rz(γ)·Ry(β)·Rx(α)`),
    /// per-axis scale.
    pub fn from_euler(translation: Vec3<T>, euler_rad: Vec3<T>, scale: Vec3<T>) -> Self {
        let r = Mat3::rotation_z(euler_rad.z)
            .mul_mat(&Mat3::rotation_y(euler_rad.y))
            .mul_mat(&Mat3::rotation_x(euler_rad.x));
        Self {
            translation,
            rotation: r,
            scale,
        }
    }

    /// Translation, rotation as an axis-angle vector (direction = axis, length =
    /// angle in radians), per-axis scale.
    pub fn from_axis_angle(translation: Vec3<T>, axis_angle: Vec3<T>, scale: Vec3<T>) -> Self {
        Self {
            translation,
            rotation: Mat3::rotation_axis_angle(axis_angle),
            scale,
        }
    }

    /// Apply to a point: `t + R·(s ⊙ p)`.
    #[inline]
    pub fn transform_point(&self, p: Vec3<T>) -> Vec3<T> {
        self.translation + self.rotation.mul_vec(p.mul_elem(self.scale))
    }

    /// Apply to a direction (no translation): `R·(s ⊙ v)` (not renormalised).
    #[inline]
    pub fn transform_vector(&self, v: Vec3<T>) -> Vec3<T> {
        self.rotation.mul_vec(v.mul_elem(self.scale))
    }

    /// Apply to a surface normal (inverse transpose, `R·(n ⊘ s)`), renormalised.
    /// Flip it yourself when [`Transform::flips_orientation`] holds and you computed
    /// it from a winding order.
    #[inline]
    pub fn transform_normal(&self, n: Vec3<T>) -> Vec3<T> {
        let inv_s = Vec3::new(
            self.scale.x.recip(),
            self.scale.y.recip(),
            self.scale.z.recip(),
        );
        self.rotation.mul_vec(n.mul_elem(inv_s)).normalize()
    }

    /// The inverse map on points: `s⁻¹ ⊙ Rᵀ(p − t)` (object from world).
    #[inline]
    pub fn inverse_transform_point(&self, p: Vec3<T>) -> Vec3<T> {
        let q = self.rotation.mul_vec_transposed(p - self.translation);
        Vec3::new(q.x / self.scale.x, q.y / self.scale.y, q.z / self.scale.z)
    }

    /// True when the transform mirrors space (`det < 0`), which reverses triangle
    /// winding.
    pub fn flips_orientation(&self) -> bool {
        let ds = self.scale.x.value() * self.scale.y.value() * self.scale.z.value();
        ds * self.rotation.to_f64().determinant() < 0.0
    }

    /// Values only.
    pub fn to_f64(&self) -> Transform<f64> {
        Transform {
            translation: self.translation.to_f64(),
            rotation: self.rotation.to_f64(),
            scale: self.scale.to_f64(),
        }
    }

    /// True when every entry is finite and every scale factor is non-zero.
    pub fn is_valid(&self) -> bool {
        self.translation.is_finite()
            && self.rotation.rows.iter().all(|r| r.is_finite())
            && self.scale.is_finite()
            && self.scale.value().iter().all(|s| *s != 0.0)
    }
}
