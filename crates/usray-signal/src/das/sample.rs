//! Channel samples as delay-and-sum reads them: the real/complex [`Sample`]
//! trait, the linear-interpolation position [`locate`], and [`linspace`] grids.

use rustfft::num_complex::Complex64;

/// A real or complex channel sample (RF: `f64`, IQ/analytic: `Complex64`).
pub trait Sample:
    Copy
    + Send
    + Sync
    + core::ops::Add<Output = Self>
    + core::ops::AddAssign
    + core::ops::Sub<Output = Self>
    + 'static
{
    /// Zero.
    fn zero() -> Self;
    /// `self · k`.
    fn scale(self, k: f64) -> Self;
    /// `self · r` (for `f64`, `r` is always 1: RF is never rotated).
    fn rot(self, r: Complex64) -> Self;
    /// `self · conj(r)`.
    fn rot_conj(self, r: Complex64) -> Self;
    /// `Re(conj(g)·self)`: the real inner product of two samples.
    fn dot(self, g: Self) -> f64;
    /// `self · i` (only used with rotation, i.e. complex).
    fn times_i(self) -> Self;
}

impl Sample for f64 {
    fn zero() -> Self {
        0.0
    }
    fn scale(self, k: f64) -> Self {
        self * k
    }
    fn rot(self, _r: Complex64) -> Self {
        self
    }
    fn rot_conj(self, _r: Complex64) -> Self {
        self
    }
    fn dot(self, g: Self) -> f64 {
        self * g
    }
    fn times_i(self) -> Self {
        0.0
    }
}

impl Sample for Complex64 {
    fn zero() -> Self {
        Complex64::new(0.0, 0.0)
    }
    fn scale(self, k: f64) -> Self {
        self * k
    }
    fn rot(self, r: Complex64) -> Self {
        self * r
    }
    fn rot_conj(self, r: Complex64) -> Self {
        self * r.conj()
    }
    fn dot(self, g: Self) -> f64 {
        self.re * g.re + self.im * g.im
    }
    fn times_i(self) -> Self {
        Complex64::new(-self.im, self.re)
    }
}

/// Integer sample `i` and fraction `w` of position `s`, if both `i` and `i + 1` lie
/// in a record of `ns` samples, i.e. `0 ≤ s < ns − 1` (NaN, negative and too large
/// positions give `None`; the bound is tested in floating point, since `as usize`
/// saturates a huge position — a sidecar's `sampling_frequency_hz = 1e300`).
#[inline]
pub(crate) fn locate(s: f64, ns: usize) -> Option<(usize, f64)> {
    if !(s >= 0.0 && s < ns as f64 - 1.0) {
        return None;
    }
    let i = s as usize;
    Some((i, s - i as f64))
}

/// `n` points from `a` to `b` inclusive (`n = 1` gives `a`).
pub fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    if n == 1 {
        return vec![a];
    }
    (0..n)
        .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::locate;

    #[test]
    fn locate_refuses_positions_outside_the_record() {
        assert_eq!(locate(2.5, 4), Some((2, 0.5)));
        assert_eq!(locate(0.0, 2), Some((0, 0.0)));
        for s in [f64::NAN, -0.5, 3.0, 3.5, 1e300, f64::INFINITY, -1e300] {
            assert_eq!(locate(s, 4), None, "{s}");
        }
    }
}
