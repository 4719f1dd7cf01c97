//! Analytic shapes and triangle-mesh instances, one file per shape.
//!
//! Every analytic shape exposes the same three things, all generic over [`Real`]:
//! - `roots(&ray) -> Roots<T>`: every crossing of the ray's *line* with the shape's
//!   surfaces (any sign of `t`), each tagged with its surface index; the *position*
//!   of a crossing in the returned list depends only on values, so a root found in
//!   `f64` can be recomputed in a dual/tape scalar by its index;
//! - `normal_at(point, surface)`: the unit **outward normal of the solid region**;
//! - `contains([f64; 3])`: point-in-solid on values.
//!
//! Lengths are metres throughout.

use usray_ad::Real;

pub mod cylinder;
pub mod half_space;
pub mod hollow_cylinder;
pub mod mesh;
pub mod slab;
pub mod sphere;

/// Up to four crossings of a ray's line with a shape's surfaces: `(t, surface)`
/// pairs in a value-determined order (see the module documentation).
#[derive(Clone, Copy, Debug)]
pub struct Roots<T> {
    /// Number of valid entries in `items`.
    pub len: usize,
    /// `(t, surface)` pairs; only the first `len` are meaningful.
    pub items: [(T, u32); 4],
}

impl<T: Real> Roots<T> {
    /// No crossing.
    #[inline]
    pub fn none() -> Self {
        Self {
            len: 0,
            items: [(T::zero(), 0); 4],
        }
    }

    /// Append a crossing (ignored beyond four).
    #[inline]
    pub fn push(&mut self, t: T, surface: u32) {
        if self.len < 4 {
            self.items[self.len] = (t, surface);
            self.len += 1;
        }
    }

    /// The valid entries.
    #[inline]
    pub fn as_slice(&self) -> &[(T, u32)] {
        &self.items[..self.len]
    }

    /// Index of the smallest root with value in `[t_min, t_max]`, if any.
    #[inline]
    pub fn nearest_in(&self, t_min: f64, t_max: f64) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for (i, (t, _)) in self.as_slice().iter().enumerate() {
            let tv = t.value();
            if tv.is_finite() && tv >= t_min && tv <= t_max && best.is_none_or(|(_, b)| tv < b) {
                best = Some((i, tv));
            }
        }
        best.map(|(i, _)| i)
    }
}

/// Both real roots of `a t² + 2 b t + c = 0` for `a > 0`, smaller first, by the
/// cancellation-free form (Press et al., *Numerical Recipes*, 3rd ed., §5.6):
/// `q = −(b + sign(b)·√(b² − ac))`, `t₁ = q/a`, `t₂ = c/q`.
///
/// Returns `None` when the discriminant is not strictly positive (no crossing, or a
/// tangent ray, which is treated as a miss so every reported crossing is a proper
/// entry or exit) or when `a` is not positive (a ray parallel to a cylinder axis).
/// Never divides by zero: `q ≠ 0` whenever the discriminant is positive.
#[inline]
pub fn solve_quadratic_half_b<T: Real>(a: T, b: T, c: T) -> Option<(T, T)> {
    if a.value().is_nan() || a.value() <= 0.0 {
        return None;
    }
    let disc = b * b - a * c;
    if disc.value().is_nan() || disc.value() <= 0.0 || !disc.value().is_finite() {
        return None;
    }
    let s = disc.sqrt();
    let q = if b.value() >= 0.0 { -(b + s) } else { s - b };
    let (t1, t2) = (q / a, c / q);
    if t1.value() <= t2.value() {
        Some((t1, t2))
    } else {
        Some((t2, t1))
    }
}
