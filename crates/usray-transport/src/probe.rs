//! The array as the tracer sees it (CONTRACT §1 frame: `x` lateral, `y`
//! elevation, `z` depth): element faces, emission directions, the two
//! directivities about each element's normal, and where a ray returning to
//! the probe lands.
//!
//! Element centres and normals come from one place,
//! [`usray_signal::array::ArrayGeometry::element`] (linear and phased arrays:
//! centres on `z = 0`, normal `+z`; convex arrays: centres on the arc of
//! radius `R` about `(0, −h)`, normals radial), evaluated once per lifted
//! scene ([`crate::scene::SceneT::elements`]). An element's face is the
//! rectangle `element_width_m` (along the tangent `t = (n_z, 0, −n_x)`) ×
//! `elevation_m` (along `y`) about its centre, facing its normal `n`.
//!
//! **Elevation.** Emission points are sampled uniformly over each element's
//! face, and emission directions over the full 3-D cosine-weighted hemisphere
//! about its normal (no restriction in elevation): scenes are 3-D; a cylinder
//! along `y` is infinite, so out-of-plane rays see the same cross-section
//! tilted, and rays leaving the elevation slab simply miss the receivers.
//!
//! Flat arrays keep the historic expressions (`x` offsets along `+x`, `n·ω =
//! ω_z`) bit for bit; the general ones reduce to them for `n = (0, 1)` only up
//! to the sign of zeros, so each function branches once on
//! [`ArrayKind::is_flat`].

use usray_ad::Real;
use usray_geometry::Vec3;
use usray_signal::array::{ArrayGeometry, ArrayKind, Element};

/// Element centre in 3-D (`y = 0`), m.
#[inline]
pub fn centre3<T: Real>(el: &Element<T>) -> Vec3<T> {
    Vec3::new(el.centre_m[0], T::zero(), el.centre_m[1])
}

/// `n·ω`: the cosine between an element's normal `n = (n_x, n_z)` and direction `ω` (for a flat
/// array `ω_z`).
#[inline]
pub fn cos_to_normal<T: Real>(kind: ArrayKind, normal: &[T; 2], dir: Vec3<T>) -> T {
    if kind.is_flat() {
        dir.z
    } else {
        normal[0] * dir.x + normal[1] * dir.z
    }
}

/// `t·ω`: the component of direction `ω` along an element's width, the
/// tangent `t = (n_z, 0, −n_x)` of its normal `n = (n_x, n_z)` (for a flat
/// array `ω_x`). For a unit `ω` in the `xz` plane it is `±sin α`, `α` the angle
/// to the normal.
#[inline]
pub fn along_width<T: Real>(kind: ArrayKind, normal: &[T; 2], dir: Vec3<T>) -> T {
    if kind.is_flat() {
        dir.x
    } else {
        normal[1] * dir.x - normal[0] * dir.z
    }
}

/// The point of element `el`'s face at the offsets `(u_t, u_y) ∈ [−½, ½]²`
/// of its width (along the tangent) and elevation, m.
#[inline]
pub fn face_point<T: Real>(
    kind: ArrayKind,
    el: &Element<T>,
    width: T,
    elevation: T,
    u_t: f64,
    u_y: f64,
) -> Vec3<T> {
    let y = elevation.scale(u_y);
    if kind.is_flat() {
        return Vec3::new(el.centre_m[0] + width.scale(u_t), y, T::zero());
    }
    let s = width.scale(u_t);
    Vec3::new(
        el.centre_m[0] + el.normal[1] * s,
        y,
        el.centre_m[1] - el.normal[0] * s,
    )
}

/// The direction with components `local = (a, b, c)` along element `el`'s
/// tangent, `y` and normal (a flat array's frame is the world frame).
#[inline]
pub fn from_element_frame<T: Real>(kind: ArrayKind, el: &Element<T>, local: [f64; 3]) -> Vec3<T> {
    let [a, b, c] = local.map(T::from_f64);
    Vec3 {
        y: b,
        ..from_element_frame_xz(kind, el, a, c)
    }
}

/// The in-plane direction with components `a` along element `el`'s tangent
/// and `c` along its normal ([`from_element_frame`] for components in `T`).
#[inline]
pub fn from_element_frame_xz<T: Real>(kind: ArrayKind, el: &Element<T>, a: T, c: T) -> Vec3<T> {
    if kind.is_flat() {
        return Vec3::new(a, T::zero(), c);
    }
    let [n_x, n_z] = el.normal;
    Vec3::new(n_z * a + n_x * c, T::zero(), n_z * c - n_x * a)
}

/// Cosine-weighted direction on the `+z` hemisphere from two uniforms (Malley's
/// method, pbrt-v4 §A.5.3): density `cos θ / π` per steradian.
#[inline]
pub fn cosine_hemisphere(u1: f64, u2: f64) -> [f64; 3] {
    let r = u1.sqrt();
    let phi = 2.0 * core::f64::consts::PI * u2;
    [r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt()]
}

/// Transmit directivity, paper eq. `directivity`: `f_d = max(0, n·ω)` about
/// element `el`'s normal `n` (dimensionless).
#[inline]
pub fn transmit_directivity<T: Real>(kind: ArrayKind, el: &Element<T>, dir: Vec3<T>) -> T {
    cos_to_normal(kind, &el.normal, dir).max(T::zero())
}

/// Receive directivity, paper eq. `cutoff`: with `α = arccos(n·ω)` the angle
/// between the element normal and the direction back towards the source
/// (`cos_alpha = −n·d` for an arriving propagation direction `d`), `1` inside the
/// main lobe `α_m`, falling linearly to `0` at the cutoff `α_c`, `0` beyond.
#[inline]
pub fn receive_directivity<T: Real>(cos_alpha: T, main_lobe: T, cutoff: T) -> T {
    ReceiveLobe::new(main_lobe, cutoff).eval(cos_alpha)
}

/// [`receive_directivity`] of fixed lobe angles, with their cosines computed
/// once.
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

/// An element's own receive directivity (`probe.receive_directivity =
/// "element"`, [`crate::scene::ReceiveDirectivity`]): a uniformly sensitive
/// strip of width `w` averages a plane wave arriving with component `s = t·ω`
/// along its width to `sinc(π w s / λ)` (Szabo, *Diagnostic Ultrasound
/// Imaging*, 2nd ed., eq. 6.16), `λ = c/f_c`. Signed: past the first zero
/// (`w > λ`) a side lobe receives with the opposite sign.
///
/// ```
/// use usray_transport::probe::ElementDirectivity;
/// // A 0.27 mm element at 2.5 MHz in water (λ = 0.592 mm), 30° off its normal.
/// let d = ElementDirectivity::new(0.27e-3 * 2.5e6 / 1480.0);
/// let s = 30f64.to_radians().sin();
/// let x = std::f64::consts::PI * 0.27e-3 / (1480.0 / 2.5e6) * s;
/// assert!((d.eval(30f64.to_radians().cos(), s) - x.sin() / x).abs() < 1e-12);
/// assert_eq!(d.eval(1.0, 0.0), 1.0);
/// assert_eq!(d.eval(-0.5, 0.3), 0.0); // from behind the element
/// ```
///
/// In a rigid baffle ([`ElementDirectivity::rigid_baffle`],
/// `probe.receive_baffle = "rigid"`) the element receives the sinc alone: the
/// directivity is then `sinc / cos α`, which cancels the obliquity `cos α`
/// that every receiver measure carries ([`crate::scene::ReceiveBaffle`]).
///
/// ```
/// # use usray_transport::probe::ElementDirectivity;
/// let soft = ElementDirectivity::new(0.456);
/// let rigid = ElementDirectivity::new(0.456).rigid_baffle();
/// let (c, s) = (40f64.to_radians().cos(), 40f64.to_radians().sin());
/// assert!((rigid.eval(c, s) * c - soft.eval(c, s)).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct ElementDirectivity<T> {
    /// `π w / λ = π w f_c / c`, dimensionless.
    pi_width_over_wavelength: T,
    /// The face in a rigid baffle: no obliquity.
    rigid: bool,
}

impl<T: Real> ElementDirectivity<T> {
    /// The directivity of an element `w/λ` = `width_over_wavelength` wide, in
    /// a soft baffle.
    #[inline]
    pub fn new(width_over_wavelength: T) -> Self {
        Self {
            pi_width_over_wavelength: width_over_wavelength.scale(core::f64::consts::PI),
            rigid: false,
        }
    }

    /// The same element in a rigid baffle: [`ElementDirectivity::eval`]
    /// divided by `cos α`.
    #[inline]
    pub fn rigid_baffle(self) -> Self {
        Self {
            rigid: true,
            ..self
        }
    }

    /// `sinc(π w s / λ)` for an arrival at `cos_alpha` to the normal with
    /// component `along_width` along the width (divided by `cos_alpha` in a
    /// rigid baffle); 0 from behind (`cos_alpha ≤ 0`).
    #[inline]
    pub fn eval(&self, cos_alpha: T, along_width: T) -> T {
        if cos_alpha.value() <= 0.0 {
            return T::zero();
        }
        let x = self.pi_width_over_wavelength * along_width;
        // sin x / x, by its Taylor series where the quotient loses digits.
        let sinc = if x.value().abs() < 1e-4 {
            T::one() - x * x * T::from_f64(1.0 / 6.0)
        } else {
            x.sin() / x
        };
        if self.rigid {
            sinc / cos_alpha
        } else {
            sinc
        }
    }
}

/// The receive directivity the tracer applies at every element
/// (`probe.receive_directivity`): the element's own or the paper's lobe.
#[derive(Clone, Copy, Debug)]
pub enum Receiver<T> {
    /// [`ElementDirectivity`].
    Element(ElementDirectivity<T>),
    /// [`ReceiveLobe`] (paper eq. `cutoff`).
    Lobe(ReceiveLobe<T>),
}

impl<T: Real> Receiver<T> {
    /// False when the directivity at `cos_alpha` is certainly 0; a cheap test
    /// before [`Receiver::eval`].
    #[inline]
    pub fn may_receive(&self, cos_alpha: f64) -> bool {
        match self {
            Self::Element(_) => cos_alpha > 0.0,
            Self::Lobe(lobe) => lobe.may_receive(cos_alpha),
        }
    }

    /// The directivity for a wave arriving at `cos_alpha` to the element's
    /// normal (`cos_alpha = −n·d` for a propagation direction `d`), with
    /// `along_width` its direction's component along the width
    /// ([`along_width`]; its sign does not matter, the sinc is even), asked
    /// for only by the element's own directivity: the lobe's evaluation costs
    /// what it did before the element's was added.
    #[inline]
    pub fn eval(&self, cos_alpha: T, along_width: impl FnOnce() -> T) -> T {
        match self {
            Self::Element(d) => d.eval(cos_alpha, along_width()),
            Self::Lobe(lobe) => lobe.eval(cos_alpha),
        }
    }
}

/// Where a ray `origin + t·dir` (unit `dir`) travelling from the medium
/// first reaches the array's surface, `t` in m (`+∞` if never): for a flat
/// array the plane `z = 0` when travelling up (`−o_z/d_z`); for a convex one
/// the cylinder of radius `R` about the axis through `(0, −h)` along `y`
/// (entered from outside: the smaller root of `|o' + t·d'|² = R²` in the
/// `xz` plane, `o' = (o_x, o_z + h)`), when the point lies within the arc's
/// span (beyond its end elements there is no probe).
pub fn array_surface_t<T: Real>(a: &ArrayGeometry<T>, origin: Vec3<T>, dir: Vec3<T>) -> T {
    let never = T::from_f64(f64::INFINITY);
    if a.kind.is_flat() {
        return if dir.z.value() < 0.0 {
            -origin.z / dir.z
        } else {
            never
        };
    }
    let (ox, oz) = (origin.x, origin.z + a.apothem_m());
    let qa = dir.x * dir.x + dir.z * dir.z;
    let qb = ox * dir.x + oz * dir.z;
    let qc = ox * ox + oz * oz - a.radius_m * a.radius_m;
    let disc = qb * qb - qa * qc;
    if qc.value() <= 0.0 || qb.value() >= 0.0 || disc.value() < 0.0 || qa.value() == 0.0 {
        return never; // inside the arc, moving away, or missing it
    }
    let t = (-qb - disc.sqrt()) / qa;
    let half_span = a.angular_pitch_rad().value() * (a.n_elements as f64 * 0.5);
    let theta = (ox + dir.x * t).value().atan2((oz + dir.z * t).value());
    if theta.abs() > half_span {
        return never;
    }
    t
}

/// The element whose face contains the point `p` on the array's surface
/// ([`array_surface_t`]). Flat arrays: nearest centre along `x`, `|x − x_e| ≤
/// w/2`; convex arrays: nearest centre in angle about `(0, −h)`, arc length
/// `R·|θ − θ_e| ≤ w/2`. Both: `|y| ≤ elevation/2`.
pub fn element_at<T: Real>(a: &ArrayGeometry<T>, elevation: T, p: [f64; 3]) -> Option<usize> {
    let (pitch, w, n) = (a.pitch_m.value(), a.element_width_m.value(), a.n_elements);
    if p[1].abs() > 0.5 * elevation.value() {
        return None;
    }
    let centre = (n as f64 - 1.0) * 0.5;
    if a.kind.is_flat() {
        let k = (p[0] / pitch + centre).round();
        if !(k >= 0.0 && k < n as f64) {
            return None;
        }
        let e = k as usize;
        let xe = pitch * (e as f64 - centre);
        return ((p[0] - xe).abs() <= 0.5 * w).then_some(e);
    }
    let delta = a.angular_pitch_rad().value();
    let theta = p[0].atan2(p[2] + a.apothem_m().value());
    let k = (theta / delta + centre).round();
    if !(k >= 0.0 && k < n as f64) {
        return None;
    }
    let e = k as usize;
    let arc = a.radius_m.value() * (theta - delta * (e as f64 - centre)).abs();
    (arc <= 0.5 * w).then_some(e)
}

/// A lower bound on the distance (m) from a point at depth `z` to any point
/// of the array's surface: `|z|` for a flat array, `z − (R − h)` (at least 0)
/// for a convex one, whose arc bulges down to `z = R − h`.
#[inline]
pub fn distance_bound_m<T: Real>(a: &ArrayGeometry<T>, z: f64) -> f64 {
    if a.kind.is_flat() {
        z.abs()
    } else {
        (z - (a.radius_m - a.apothem_m()).value()).max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn linear() -> ArrayGeometry<f64> {
        ArrayGeometry {
            kind: ArrayKind::Linear,
            n_elements: 128,
            pitch_m: 0.3e-3,
            element_width_m: 0.27e-3,
            radius_m: f64::INFINITY,
        }
    }

    #[test]
    fn geometry_and_directivity() {
        let a = linear();
        assert_eq!(element_at(&a, 4e-3, [0.15e-3 - 1e-6, 0.0, 0.0]), Some(64));
        assert_eq!(element_at(&a, 4e-3, [0.0, 0.0, 0.0]), None); // kerf
        let (m, c) = (5f64.to_radians(), 60f64.to_radians());
        assert_eq!(receive_directivity(1.0_f64, m, c), 1.0);
        assert!((receive_directivity(32.5f64.to_radians().cos(), m, c) - 0.5).abs() < 1e-9);
        assert_eq!(receive_directivity(70f64.to_radians().cos(), m, c), 0.0);
        let d = cosine_hemisphere(0.3, 0.7);
        assert!(((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) - 1.0).abs() < 1e-12);
    }

    /// The element's directivity through [`Receiver`]: its first zero at
    /// `sin α = λ/w`, even in `α`, the same along a convex element's tangent
    /// as along a flat one's `x`, and smooth through broadside (the series
    /// branch meets the quotient).
    #[test]
    fn element_directivity_zeros_symmetry_and_frames() {
        let w_over_lambda = 1.6;
        let element = Receiver::Element(ElementDirectivity::new(w_over_lambda));
        let rx = |kind, normal: &[f64; 2], towards_source: Vec3<f64>| {
            let cos_alpha = cos_to_normal(kind, normal, towards_source);
            element.eval(cos_alpha, || along_width(kind, normal, towards_source))
        };
        let flat = [0.0, 1.0];
        let at = |s: f64| Vec3::new(s, 0.0, (1.0 - s * s).sqrt());
        let first_zero = 1.0 / w_over_lambda;
        assert!(rx(ArrayKind::Linear, &flat, at(first_zero)).abs() < 1e-12);
        assert!(rx(ArrayKind::Linear, &flat, at(first_zero + 0.05)) < 0.0);
        let (p, m) = (at(0.3), at(-0.3));
        assert_eq!(
            rx(ArrayKind::Linear, &flat, p),
            rx(ArrayKind::Linear, &flat, m)
        );
        // A convex element tilted by 0.2 rad: the same angle off its normal.
        let (sn, cn) = 0.2f64.sin_cos();
        let normal = [sn, cn];
        let (sa, ca) = 0.3f64.sin_cos();
        let rotate = |x: f64, z: f64| Vec3::new(cn * x + sn * z, 0.0, cn * z - sn * x);
        let tilted = rotate(sa, ca);
        let flat_value = rx(ArrayKind::Linear, &flat, Vec3::new(sa, 0.0, ca));
        assert!((rx(ArrayKind::Convex, &normal, tilted) - flat_value).abs() < 1e-12);
        let d = ElementDirectivity::new(w_over_lambda);
        let (below, above) = (d.eval(1.0, 0.99e-4 / 5.03), d.eval(1.0, 1.01e-4 / 5.03));
        assert!((below - above).abs() < 1e-9);
    }

    /// A convex array: a ray aimed at an element centre along minus its
    /// normal lands on that element's face at distance `d`, a face point
    /// lies on the element's tangent, and the local frame is orthonormal.
    #[test]
    fn convex_surface_hits_the_element_it_aims_at() {
        let a = ArrayGeometry {
            kind: ArrayKind::Convex,
            n_elements: 64,
            pitch_m: 0.5e-3,
            element_width_m: 0.45e-3,
            radius_m: 40e-3,
        };
        for e in [0, 5, 31, 32, 63] {
            let el = a.element(e);
            let n = Vec3::new(el.normal[0], 0.0, el.normal[1]);
            let d = 0.02;
            let o = centre3(&el) + n * d;
            let t = array_surface_t(&a, o, -n);
            assert!((t - d).abs() < 1e-12, "{e}: {t}");
            let p = (o - n * t).value();
            assert_eq!(element_at(&a, 4e-3, p), Some(e));
            let f = face_point(a.kind, &el, a.element_width_m, 4e-3, 0.5, 0.0);
            assert!(((f - centre3(&el)).dot(n)).abs() < 1e-15);
            assert!(((f - centre3(&el)).length() - 0.225e-3).abs() < 1e-15);
            let w = from_element_frame(a.kind, &el, [0.6, 0.0, 0.8]);
            assert!((w.length() - 1.0).abs() < 1e-15);
            assert!((cos_to_normal(a.kind, &el.normal, w) - 0.8).abs() < 1e-15);
        }
        // Beyond the end elements there is no probe.
        let o = Vec3::<f64>::new(0.03, 0.0, 0.01);
        assert!(array_surface_t(&a, o, Vec3::new(0.0, 0.0, -1.0)).is_infinite());
    }
}
