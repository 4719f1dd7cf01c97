//! USTB's `uff.curvilinear_array` and usray's convex array: the same elements in
//! frames `R − h` apart.
//!
//! USTB (`uff.curvilinear_array.update`, and `pyuff_ustb`'s `CurvilinearArray`
//! geometry): angular step `δ = 2·asin(pitch/(2R))`, element `e` at angle
//! `θ_e = (e − (N−1)/2)·δ` and at `(R sin θ_e, R cos θ_e − R)`: the arc's apex is
//! the origin, its centre `(0, −R)`. usray (CONTRACT §1, PyMUST's convention,
//! [`crate::array`]): the same angles, at `(R sin θ_e, R cos θ_e − h)` with
//! `h = R cos θ_{N−1}`: the chord through the end elements on `z = 0`. So
//! `z_usray = z_USTB + s`, `s = R − h` (the sagitta of the end elements), for
//! element positions and wave sources alike; flat arrays have `s = 0`.
//!
//! Clocks: both put `t = 0` when the wave passes their own origin, so a wave
//! passes USTB's origin, usray's `(0, s)`, at usray time `t_s = t((0, s))`
//! ([`TransmitWave::arrival_time_s`]) and a sample at USTB time `τ` is at usray
//! time `τ + t_s`.

use crate::array::ArrayGeometry;
use crate::transmit::TransmitWave;

/// `s = R − h`, m: how far usray's origin lies below USTB's (0 for a flat array).
pub(super) fn frame_shift_m(array: &ArrayGeometry<f64>) -> f64 {
    if array.kind.is_flat() {
        0.0
    } else {
        array.radius_m - array.apothem_m()
    }
}

/// `wave` with its source or focus moved by `dz` in depth.
pub(super) fn shifted(wave: TransmitWave<f64>, dz: f64) -> TransmitWave<f64> {
    match wave {
        TransmitWave::PlaneWave { .. } => wave,
        TransmitWave::Diverging { source_m: [x, z] } => TransmitWave::Diverging {
            source_m: [x, z + dz],
        },
        TransmitWave::Focused { focus_m: [x, z] } => TransmitWave::Focused {
            focus_m: [x, z + dz],
        },
    }
}

/// `t_s`: the usray time at which `wave` (in usray's frame) passes USTB's
/// origin `(0, s)`, s.
pub(super) fn clock_shift_s(wave: &TransmitWave<f64>, shift_m: f64, c: f64) -> f64 {
    wave.arrival_time_s([0.0, shift_m], c)
}

/// Element `e` of `array` in USTB's frame: `(x, z, azimuth)`.
pub(super) fn ustb_element(array: &ArrayGeometry<f64>, e: usize) -> (f64, f64, f64) {
    let el = array.element(e);
    let azimuth = el.normal[0].atan2(el.normal[1]);
    (
        el.centre_m[0],
        el.centre_m[1] - frame_shift_m(array),
        azimuth,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::array::ArrayKind;

    /// USTB's formula, written out, against usray's elements moved by `−s`.
    #[test]
    fn elements_match_ustbs_formula() {
        let a: ArrayGeometry<f64> = ArrayGeometry {
            kind: ArrayKind::Convex,
            n_elements: 128,
            pitch_m: 0.508e-3,
            element_width_m: 0.46e-3,
            radius_m: 49.57e-3,
        };
        let r = a.radius_m;
        let dtheta = 2.0 * (a.pitch_m / 2.0 / r).asin();
        for e in [0, 1, 63, 64, 127] {
            let th = (e as f64 - 63.5) * dtheta;
            let (x, z, az) = ustb_element(&a, e);
            assert!((x - r * th.sin()).abs() < 1e-15, "{e}");
            assert!((z - (r * th.cos() - r)).abs() < 1e-15, "{e}");
            assert!((az - th).abs() < 1e-14, "{e}");
        }
        // The sagitta of C5-2v's end elements: 49.57 − 39.44 = 10.13 mm.
        assert!((frame_shift_m(&a) - 10.13e-3).abs() < 0.01e-3);
    }

    /// A wave moved into USTB's frame passes USTB's origin at USTB time 0,
    /// i.e. at usray time `t_s`.
    #[test]
    fn clocks_agree_at_ustbs_origin() {
        let s = 10e-3;
        for w in [
            TransmitWave::PlaneWave { angle_rad: 0.2 },
            TransmitWave::Diverging {
                source_m: [3e-3, -20e-3],
            },
            TransmitWave::Focused {
                focus_m: [2e-3, 40e-3],
            },
        ] {
            let ustb = shifted(w, -s);
            let p = [4e-3, 30e-3];
            let t_usray = w.arrival_time_s(p, 1540.0);
            let t_ustb = ustb.arrival_time_s([p[0], p[1] - s], 1540.0);
            let ts = clock_shift_s(&w, s, 1540.0);
            assert!((t_usray - (t_ustb + ts)).abs() < 1e-18, "{w:?}");
        }
    }
}
