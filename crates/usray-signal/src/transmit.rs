//! Transmitted waves and their time models on the clock of CONTRACT §1:
//! `t = 0` is the instant the transmitted wavefront passes the probe-frame
//! origin `(0, 0)` (the array centre of a flat array; the middle of the chord
//! through the end elements of a convex one).
//!
//! | kind | JSON keys (CONTRACT §2 `transmits[i]`) | arrival time `t(p)` at `p = (x, z)`, s |
//! |---|---|---|
//! | `plane_wave` | `angle_rad` θ | `(x sin θ + z cos θ)/c` (Montaldo et al. 2009) |
//! | `diverging` | `virtual_source_m` `v = [x, z]`, `z < 0` | `(‖p − v‖ − ‖v‖)/c` |
//! | `focused` | `focus_m` `f = [x, z]`, `z > 0` | `(‖f‖ ∓ ‖p − f‖)/c`, `−` before the focus, `+` beyond |
//!
//! "Before the focus" means on the array's side of the line through `f`
//! perpendicular to the beam axis `f − 0`: `(p − f)·f < 0` (for an on-axis
//! focus the same as `z < z_f`). Inside the beam (the lines from the aperture
//! through the focus) this is PyMUST `dasmtx`'s virtual-source model
//! (`param.useVirtualSource`); outside it PyMUST takes the nearest normal of
//! its virtual transducer, an edge-wave construction, and neither model
//! describes the field there. Diverging and
//! focused waves are spherical (circular in 2-D) about `v` or `f`: PyMUST's
//! `txdelay(param, tilt, width)` returns the delays of the virtual source
//! `angles2origo(L, tilt, width)` behind a flat array, and `txdelay(x0, z0,
//! param)` those of a focus (`z0 > 0`) or a virtual source (`z0 < 0`).
//!
//! An element at `e` fires at `t(e)` (the wave's arrival time at the element):
//! that is the transmit delay law, relative to the same `t = 0`; a file's
//! `t0_s` says when sample 0 was taken on this clock (PyMUST and scanners
//! start at the first firing: `t0_s = min_e t(e)`).

use usray_ad::Real;

use crate::channels::TransmitMeta;

/// The key of a diverging wave's virtual source `[x, z]`, m.
pub const VIRTUAL_SOURCE_KEY: &str = "virtual_source_m";
/// The key of a focused wave's focal point `[x, z]`, m.
pub const FOCUS_KEY: &str = "focus_m";

/// One transmitted wave (CONTRACT §2 `transmits[i]`), generic in [`Real`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TransmitWave<T> {
    /// Plane wave steered by `angle_rad` (positive: toward `+x`).
    PlaneWave {
        /// Steering angle θ, rad.
        angle_rad: T,
    },
    /// Circular wave from a virtual source behind the array.
    Diverging {
        /// Virtual source `(x, z)`, m, `z < 0`.
        source_m: [T; 2],
    },
    /// Circular wave converging on a focus in front of the array.
    Focused {
        /// Focal point `(x, z)`, m, `z > 0`.
        focus_m: [T; 2],
    },
}

fn norm<T: Real>(v: [T; 2]) -> T {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}

impl<T: Real> TransmitWave<T> {
    /// Arrival time of the wavefront at `p = (x, z)` m, s, for sound speed `c`
    /// m/s (the table in the module documentation).
    #[inline]
    pub fn arrival_time_s(&self, p: [T; 2], c: T) -> T {
        match *self {
            TransmitWave::PlaneWave { angle_rad } => {
                (p[0] * angle_rad.sin() + p[1] * angle_rad.cos()) / c
            }
            TransmitWave::Diverging { source_m: v } => {
                (norm([p[0] - v[0], p[1] - v[1]]) - norm(v)) / c
            }
            TransmitWave::Focused { focus_m: f } => {
                let d = [p[0] - f[0], p[1] - f[1]];
                let before = (d[0] * f[0] + d[1] * f[1]).value() < 0.0;
                let r = norm(d);
                let r = if before { -r } else { r };
                (norm(f) + r) / c
            }
        }
    }

    /// The transmit delay law: when the element centred at `e` fires, s, on the
    /// same clock ([`Self::arrival_time_s`] at the element).
    pub fn element_delay_s(&self, e: [T; 2], c: T) -> T {
        self.arrival_time_s(e, c)
    }
}

impl TransmitWave<f64> {
    /// The wave of a channel file's transmit `i`, checked: a known kind and its
    /// key, finite values, `|angle_rad| < π/2`, a virtual source behind the
    /// array (`z < 0`), a focus in front of it (`z > 0`). The error names the key.
    pub fn from_meta(i: usize, t: &TransmitMeta) -> Result<Self, String> {
        let point = |key: &str| -> Result<[f64; 2], String> {
            let v = t.extra.get(key).ok_or_else(|| {
                format!(
                    "transmits[{i}].{key} is required for a {:?} transmit",
                    t.kind
                )
            })?;
            let p = v
                .as_array()
                .filter(|a| a.len() == 2)
                .and_then(|a| Some([a[0].as_f64()?, a[1].as_f64()?]))
                .filter(|p| p.iter().all(|c| c.is_finite()))
                .ok_or_else(|| {
                    format!(
                        "transmits[{i}].{key} must be two finite numbers [x, z] in metres, got {v}"
                    )
                })?;
            Ok(p)
        };
        match t.kind.as_str() {
            "plane_wave" => {
                if !(t.angle_rad.is_finite() && t.angle_rad.abs() < std::f64::consts::FRAC_PI_2) {
                    return Err(format!(
                        "transmits[{i}].angle_rad must be finite and inside ±π/2, got {}",
                        t.angle_rad
                    ));
                }
                Ok(TransmitWave::PlaneWave {
                    angle_rad: t.angle_rad,
                })
            }
            "diverging" => {
                let v = point(VIRTUAL_SOURCE_KEY)?;
                if v[1] >= 0.0 {
                    return Err(format!(
                        "transmits[{i}].{VIRTUAL_SOURCE_KEY} = {v:?}: a virtual source must lie behind the array (z < 0); a point in front of it is a focus (kind \"focused\", `{FOCUS_KEY}`)"
                    ));
                }
                Ok(TransmitWave::Diverging { source_m: v })
            }
            "focused" => {
                let f = point(FOCUS_KEY)?;
                if f[1] <= 0.0 {
                    return Err(format!(
                        "transmits[{i}].{FOCUS_KEY} = {f:?}: a focus must lie in front of the array (z > 0); a point behind it is a virtual source (kind \"diverging\", `{VIRTUAL_SOURCE_KEY}`)"
                    ));
                }
                Ok(TransmitWave::Focused { focus_m: f })
            }
            other => Err(format!(
                "transmits[{i}].kind is {other:?}; expected \"plane_wave\", \"diverging\" or \"focused\""
            )),
        }
    }

    /// The inverse of [`TransmitWave::from_meta`]: the transmit's `kind` and
    /// `angle_rad` (0 for a circular wave), its point written into `extra`
    /// under [`VIRTUAL_SOURCE_KEY`] or [`FOCUS_KEY`].
    pub fn to_meta_fields(
        &self,
        extra: &mut serde_json::Map<String, serde_json::Value>,
    ) -> (&'static str, f64) {
        match *self {
            TransmitWave::PlaneWave { angle_rad } => ("plane_wave", angle_rad),
            TransmitWave::Diverging { source_m } => {
                extra.insert(VIRTUAL_SOURCE_KEY.into(), source_m.to_vec().into());
                ("diverging", 0.0)
            }
            TransmitWave::Focused { focus_m } => {
                extra.insert(FOCUS_KEY.into(), focus_m.to_vec().into());
                ("focused", 0.0)
            }
        }
    }

    /// Whether this is a plane wave (the beamformer's fast path needs only those).
    pub fn is_plane(&self) -> bool {
        matches!(self, TransmitWave::PlaneWave { .. })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use usray_ad::Dual;

    const C: f64 = 1540.0;

    /// Each model passes the origin at t = 0 and its wavefront moves at c.
    #[test]
    fn time_models_pass_the_origin_at_zero_and_move_at_c() {
        let waves = [
            TransmitWave::PlaneWave { angle_rad: 0.2 },
            TransmitWave::Diverging {
                source_m: [3e-3, -15e-3],
            },
            TransmitWave::Focused {
                focus_m: [5e-3, 40e-3],
            },
        ];
        for w in waves {
            assert!(w.arrival_time_s([0.0, 0.0], C).abs() < 1e-20, "{w:?}");
        }
        // Along a ray from the virtual source, time grows as distance / c.
        let v = [3e-3, -15e-3];
        let w = TransmitWave::Diverging { source_m: v };
        let u = [0.6, 0.8];
        let t = |s: f64| w.arrival_time_s([v[0] + s * u[0], v[1] + s * u[1]], C);
        assert!((t(0.05) - t(0.03) - 0.02 / C).abs() < 1e-18);
        // Along the beam axis, before and beyond the focus, the wavefront
        // moves at c.
        let f = [5e-3, 40e-3];
        let w = TransmitWave::Focused { focus_m: f };
        let n = (f[0] * f[0] + f[1] * f[1]).sqrt();
        let a = [f[0] / n, f[1] / n];
        let t = |s: f64| w.arrival_time_s([s * a[0], s * a[1]], C);
        for s in [0.01, 0.03, n, 0.05, 0.07] {
            assert!((t(s) - s / C).abs() < 1e-18, "{s}: {} vs {}", t(s), s / C);
        }
    }

    /// Plane waves: bit-identical to the historic expression.
    #[test]
    fn plane_wave_time_is_the_historic_expression() {
        let th: f64 = -0.17;
        let (x, z) = (3.3e-3, 21.7e-3);
        let (s, co) = th.sin_cos();
        let w = TransmitWave::PlaneWave { angle_rad: th };
        assert_eq!(w.arrival_time_s([x, z], C), (x * s + z * co) / C);
    }

    /// Dual derivatives of the time models against central differences.
    #[test]
    fn time_derivatives_match_finite_differences() {
        let p = [4e-3, 30e-3];
        for (v, focused) in [([2e-3, -12e-3], false), ([-3e-3, 45e-3], true)] {
            let mk = |v: [f64; 2], c: f64| {
                let w = if focused {
                    TransmitWave::Focused { focus_m: v }
                } else {
                    TransmitWave::Diverging { source_m: v }
                };
                w.arrival_time_s(p, c)
            };
            let vd = [Dual::<3>::variable(v[0], 0), Dual::<3>::variable(v[1], 1)];
            let wd = if focused {
                TransmitWave::Focused { focus_m: vd }
            } else {
                TransmitWave::Diverging { source_m: vd }
            };
            let t = wd.arrival_time_s([Dual::from(p[0]), Dual::from(p[1])], Dual::variable(C, 2));
            let h = 1e-7;
            let fd = [
                (mk([v[0] + h, v[1]], C) - mk([v[0] - h, v[1]], C)) / (2.0 * h),
                (mk([v[0], v[1] + h], C) - mk([v[0], v[1] - h], C)) / (2.0 * h),
                (mk(v, C + 1e-3) - mk(v, C - 1e-3)) / 2e-3,
            ];
            for k in 0..3 {
                let rel = (t.eps[k] - fd[k]).abs() / t.eps[k].abs();
                assert!(
                    rel < 1e-6,
                    "focused {focused}, partial {k}: AD {} FD {}",
                    t.eps[k],
                    fd[k]
                );
            }
        }
    }
}
