//! Array geometry: element centres and outward normals in the probe frame
//! (CONTRACT §1: `x` lateral, `z` depth), for the probe kinds of CONTRACT §2.
//!
//! * `linear` and `phased`: element `e` at `x_e = (e − (N−1)/2)·pitch`, `z_e = 0`,
//!   normal `(0, 1)`. The two share their geometry; a phased array differs by its
//!   small pitch and its sector field of view (the default image grid,
//!   [`crate::grid::PolarGrid`]).
//! * `convex`: elements on an arc of radius `R = radius_m`, PyMUST's convention
//!   (`Param.getElementPositions`, `getparam('C5-2v')`): neighbouring centres
//!   are one `pitch` apart along the chord, i.e. the angular step is
//!   `δ = 2·asin(pitch/(2R))`; element `e` sits at angle
//!   `θ_e = (e − (N−1)/2)·δ` from the `z` axis, at
//!   `(x_e, z_e) = (R sin θ_e, R cos θ_e − h)` with normal `(sin θ_e, cos θ_e)`,
//!   where `h = R cos(θ_{N−1})` is the apothem: the arc's centre is at
//!   `(0, −h)`, the two end elements lie on `z = 0` and the middle of the arc
//!   bulges to `z = R − h > 0`.
//!
//! Every quantity is generic in [`Real`], so a tracer or a gradient can carry
//! derivatives with respect to `pitch_m`, `element_width_m` and `radius_m`.

use usray_ad::Real;

use crate::channels::{limits, ProbeMeta};

/// The probe kinds of CONTRACT §2.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArrayKind {
    /// Flat array, rectangular field of view.
    Linear,
    /// Flat array with a small pitch, sector field of view.
    Phased,
    /// Elements on an arc of radius `radius_m`.
    Convex,
}

impl ArrayKind {
    /// The kind named by CONTRACT §2's `probe.kind`.
    pub fn parse(kind: &str) -> Result<ArrayKind, String> {
        match kind {
            "linear" => Ok(ArrayKind::Linear),
            "phased" => Ok(ArrayKind::Phased),
            "convex" => Ok(ArrayKind::Convex),
            other => Err(format!(
                "`probe.kind` is {other:?}; expected \"linear\", \"phased\" or \"convex\""
            )),
        }
    }
    /// Whether the elements lie on `z = 0` with normal `(0, 1)`.
    pub fn is_flat(self) -> bool {
        self != ArrayKind::Convex
    }
}

/// One element: centre and outward unit normal, probe frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element<T> {
    /// Centre `(x, z)`, m.
    pub centre_m: [T; 2],
    /// Outward unit normal `(n_x, n_z)` (into the medium).
    pub normal: [T; 2],
}

/// An array's geometry (CONTRACT §2 `probe`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArrayGeometry<T> {
    /// Kind.
    pub kind: ArrayKind,
    /// Number of elements `N`.
    pub n_elements: usize,
    /// Centre-to-centre spacing (along the chord for a convex array), m.
    pub pitch_m: T,
    /// Element width, m.
    pub element_width_m: T,
    /// Radius of curvature `R`, m (convex arrays; unused otherwise).
    pub radius_m: T,
}

impl ArrayGeometry<f64> {
    /// The geometry of a channel file's probe, checked: a known kind, a radius
    /// (`probe.radius_m`, finite) of at least half the aperture
    /// `(N − 1)·pitch/2` for a convex array (a smaller one cannot hold the
    /// elements on less than a half circle), and elements that do not overlap
    /// (`element_width_m ≤ pitch_m`). The error names the key.
    pub fn from_meta(probe: &ProbeMeta) -> Result<Self, String> {
        let kind = ArrayKind::parse(&probe.kind)?;
        let (lo, hi) = limits::PITCH_M;
        if !(probe.pitch_m.is_finite() && probe.pitch_m > lo && probe.pitch_m <= hi) {
            return Err(format!(
                "`probe.pitch_m` must lie in ({lo:e}, {hi:e}], got {}",
                probe.pitch_m
            ));
        }
        let w = probe.element_width_m;
        if !(w.is_finite() && w > 0.0) {
            return Err(format!(
                "`probe.element_width_m` must be positive and finite, got {w}"
            ));
        }
        if w > probe.pitch_m {
            return Err(format!(
                "`probe.element_width_m` = {w} m exceeds `probe.pitch_m` = {} m: the elements would overlap (width must lie in (0, pitch])",
                probe.pitch_m
            ));
        }
        let radius = probe.extra.get(RADIUS_KEY);
        let radius_m = match (kind, radius) {
            (ArrayKind::Convex, None) => {
                return Err(format!(
                    "`probe.{RADIUS_KEY}` is required for a convex probe"
                ))
            }
            (ArrayKind::Convex, Some(v)) => {
                let r = v.as_f64().filter(|r| r.is_finite()).ok_or_else(|| {
                    format!("`probe.{RADIUS_KEY}` must be a finite number, got {v}")
                })?;
                let half = probe.n_elements.saturating_sub(1) as f64 * probe.pitch_m / 2.0;
                if !(r >= half && r > 0.0) {
                    return Err(format!(
                        "`probe.{RADIUS_KEY}` = {r} m is below half the aperture ((n_elements − 1)·pitch/2 = {half} m): the arc cannot hold the elements"
                    ));
                }
                r
            }
            (_, Some(_)) => {
                return Err(format!(
                "`probe.{RADIUS_KEY}` is given for a {:?} probe; only a convex probe has a radius",
                probe.kind
            ))
            }
            (_, None) => f64::INFINITY,
        };
        Ok(ArrayGeometry {
            kind,
            n_elements: probe.n_elements,
            pitch_m: probe.pitch_m,
            element_width_m: w,
            radius_m,
        })
    }
}

/// The key of the convex radius in CONTRACT §2's `probe`, m.
pub const RADIUS_KEY: &str = "radius_m";

impl<T: Real> ArrayGeometry<T> {
    /// `(e − (N−1)/2)`, the element's signed index from the array centre.
    fn offset(&self, e: usize) -> f64 {
        e as f64 - (self.n_elements as f64 - 1.0) / 2.0
    }

    /// Angular step `δ = 2·asin(pitch/(2R))` of a convex array, rad (PyMUST
    /// `getElementPositions`: chord `2R sin((N−1)·asin(pitch/(2R)))`).
    pub fn angular_pitch_rad(&self) -> T {
        (self.pitch_m / (self.radius_m.scale(2.0)))
            .asin()
            .scale(2.0)
    }

    /// Apothem `h = R cos((N−1)δ/2)`: the distance from the arc's centre to the
    /// chord through the end elements, m (0 for a flat array).
    pub fn apothem_m(&self) -> T {
        if self.kind.is_flat() {
            return T::zero();
        }
        let half = self
            .angular_pitch_rad()
            .scale((self.n_elements as f64 - 1.0) / 2.0);
        self.radius_m * half.cos()
    }

    /// Centre of curvature `(0, −h)` of a convex array; the array centre
    /// `(0, 0)` for a flat one (the origin of the sector grid).
    pub fn sector_origin_m(&self) -> [T; 2] {
        [T::zero(), -self.apothem_m()]
    }

    /// Element `e`'s centre and normal.
    pub fn element(&self, e: usize) -> Element<T> {
        let k = self.offset(e);
        if self.kind.is_flat() {
            // The historic `element_x` (`pitch·k`, in values the beamformer's
            // `k·pitch` bit for bit), so flat arrays keep their bits in the
            // tracer's derivatives too.
            return Element {
                centre_m: [self.pitch_m.scale(k), T::zero()],
                normal: [T::zero(), T::one()],
            };
        }
        let th = self.angular_pitch_rad().scale(k);
        let (s, c) = (th.sin(), th.cos());
        Element {
            centre_m: [self.radius_m * s, self.radius_m * c - self.apothem_m()],
            normal: [s, c],
        }
    }

    /// Every element, in index order.
    pub fn elements(&self) -> Vec<Element<T>> {
        (0..self.n_elements).map(|e| self.element(e)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use usray_ad::Dual;

    fn convex(n: usize, pitch: f64, r: f64) -> ArrayGeometry<f64> {
        ArrayGeometry {
            kind: ArrayKind::Convex,
            n_elements: n,
            pitch_m: pitch,
            element_width_m: pitch * 0.9,
            radius_m: r,
        }
    }

    #[test]
    fn flat_elements_match_the_historic_formula() {
        let a = ArrayGeometry {
            kind: ArrayKind::Linear,
            n_elements: 128,
            pitch_m: 0.3e-3,
            element_width_m: 0.27e-3,
            radius_m: f64::INFINITY,
        };
        for e in 0..128 {
            let el = a.element(e);
            assert_eq!(el.centre_m[0], (e as f64 - 63.5) * 0.3e-3);
            assert_eq!(el.centre_m[1], 0.0);
            assert_eq!(el.normal, [0.0, 1.0]);
        }
    }

    /// Closed form: neighbours one pitch apart, every centre at distance R
    /// from (0, −h) along its normal, end elements on z = 0.
    #[test]
    fn convex_elements_lie_on_the_arc() {
        let a = convex(128, 0.508e-3, 49.57e-3);
        let h = a.apothem_m();
        let els = a.elements();
        for w in els.windows(2) {
            let d =
                (w[1].centre_m[0] - w[0].centre_m[0]).hypot(w[1].centre_m[1] - w[0].centre_m[1]);
            assert!((d - 0.508e-3).abs() < 1e-15, "{d}");
        }
        for el in &els {
            let [x, z] = el.centre_m;
            assert!((x - 49.57e-3 * el.normal[0]).abs() < 1e-15);
            assert!((z + h - 49.57e-3 * el.normal[1]).abs() < 1e-15);
            assert!((el.normal[0].hypot(el.normal[1]) - 1.0).abs() < 1e-15);
        }
        assert!(els[0].centre_m[1].abs() < 1e-15 && els[127].centre_m[1].abs() < 1e-15);
        // C5-2v: PyMUST's chord 60.0 mm (2R sin(127·asin(p/2R))).
        let chord = els[127].centre_m[0] - els[0].centre_m[0];
        let want = 2.0 * 49.57e-3 * (127.0 * (0.508e-3 / (2.0 * 49.57e-3)).asin()).sin();
        assert!((chord - want).abs() < 1e-15, "{chord} {want}");
    }

    /// The dual-number derivative of an element centre with respect to the
    /// pitch against a central finite difference.
    #[test]
    fn convex_element_derivative_matches_finite_differences() {
        let (p, r) = (0.508e-3, 49.57e-3);
        let d = ArrayGeometry {
            kind: ArrayKind::Convex,
            n_elements: 128,
            pitch_m: Dual::<2>::variable(p, 0),
            element_width_m: Dual::<2>::from(0.46e-3),
            radius_m: Dual::<2>::variable(r, 1),
        };
        for e in [0, 17, 64, 127] {
            let el = d.element(e);
            for (i, (dp, dr)) in [(1e-9, 0.0), (0.0, 1e-7)].into_iter().enumerate() {
                let hi = convex(128, p + dp, r + dr).element(e).centre_m;
                let lo = convex(128, p - dp, r - dr).element(e).centre_m;
                for k in 0..2 {
                    let fd = (hi[k] - lo[k]) / (2.0 * (dp + dr));
                    let ad = el.centre_m[k].eps[i];
                    assert!(
                        (fd - ad).abs() <= 1e-6 * ad.abs().max(1e-3),
                        "element {e}, coordinate {k}, parameter {i}: AD {ad}, FD {fd}"
                    );
                }
            }
        }
    }
}
