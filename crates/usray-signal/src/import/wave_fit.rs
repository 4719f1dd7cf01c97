//! The transmitted wave behind one transmit's per-element delays: a plane wave,
//! a diverging wave from a virtual source behind the array, or a wave focused
//! in front of it ([`crate::transmit`]), fitted by least squares.
//!
//! A file's delays `d_e` (seconds, on the file's clock: PyMUST's `txdelay` and
//! Verasonics' `TX.Delay` start at 0 on the first-firing element) are modelled
//! as `d_e = a + τ_e`, where `τ_e` is the wave's delay law on usray's clock
//! ([`TransmitWave::element_delay_s`], CONTRACT §1: `t = 0` when the wavefront
//! passes the probe-frame origin) and `a` is the file-clock time of that
//! instant. A sample taken at time `T` on the file's clock is at `T − a` on
//! usray's, so a record whose sample 0 is at the file's `t0` has
//! `t0_s = t0 − a`.
//!
//! Fits: a plane wave, `(a, θ)`; a circular wave, `d_e = b ± ‖e − p‖/c`
//! (`+` diverging, `−` focused), started from the closed form that squaring
//! gives (`(c·d_e − c·b)² = ‖e − p‖²` is linear in `c·b`, `p` and
//! `‖p‖² − (c·b)²`) and refined by Gauss–Newton. The plane wave is taken when it
//! fits within the tolerance (a virtual source kilometres away is a plane
//! wave); else the circular wave if it does; else the transmit is refused.
//! Each model is tried only with more elements than it has unknowns (3 for the
//! plane wave, 4 for the circular one), so that its residual tests it.

use crate::array::Element;
use crate::transmit::TransmitWave;

/// A recovered wave and how well it explains the delays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Fitted {
    /// The wave, CONTRACT §2.
    pub wave: TransmitWave<f64>,
    /// `a`: the file-clock time at which the wave passes the origin, s.
    pub offset_s: f64,
    /// Largest `|d_e − a − τ_e|` over the elements, s.
    pub max_residual_s: f64,
}

/// Why no model fits: the best residual of each, s (`None` when the model
/// could not be fitted at all, e.g. a plane wave steered past 90°).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct NoFit {
    pub plane_s: Option<f64>,
    pub circular_s: Option<f64>,
}

/// The model of the delays `delays_s` fired by `elements` in sound speed `c`:
/// the plane wave if its largest residual is at most `tolerance_s`, else the
/// circular wave if it is.
pub(super) fn fit_wave(
    elements: &[Element<f64>],
    delays_s: &[f64],
    c: f64,
    tolerance_s: f64,
) -> Result<Fitted, NoFit> {
    let plane = fit_plane(elements, delays_s, c);
    if let Some(p) = plane.filter(|p| p.max_residual_s <= tolerance_s) {
        return Ok(p);
    }
    let circular = fit_circular(elements, delays_s, c);
    if let Some(s) = circular.filter(|s| s.max_residual_s <= tolerance_s) {
        return Ok(s);
    }
    Err(NoFit {
        plane_s: plane.map(|p| p.max_residual_s),
        circular_s: circular.map(|s| s.max_residual_s),
    })
}

/// `a` (the mean of `d_e − τ_e`) and the largest residual, for `wave`.
fn offset_and_residual(
    wave: TransmitWave<f64>,
    elements: &[Element<f64>],
    delays_s: &[f64],
    c: f64,
) -> Option<Fitted> {
    let gaps: Vec<f64> = elements
        .iter()
        .zip(delays_s)
        .map(|(e, d)| d - wave.element_delay_s(e.centre_m, c))
        .collect();
    let offset_s = gaps.iter().sum::<f64>() / gaps.len() as f64;
    let max_residual_s = gaps.iter().fold(0.0f64, |m, g| m.max((g - offset_s).abs()));
    max_residual_s.is_finite().then_some(Fitted {
        wave,
        offset_s,
        max_residual_s,
    })
}

/// Plane wave: `d_e = a + (x_e sin θ + z_e cos θ)/c`; on a flat array the
/// least-squares line in `x_e` (`sin θ = c·slope`), on a curved one
/// Gauss–Newton in `(a, θ)` from the flat estimate.
fn fit_plane(elements: &[Element<f64>], delays_s: &[f64], c: f64) -> Option<Fitted> {
    // Two unknowns: two elements fit any delays, a third tests the model.
    if elements.len() < 3 {
        return None;
    }
    let x: Vec<f64> = elements.iter().map(|e| e.centre_m[0]).collect();
    let (_, slope, _) = fit_line(&x, delays_s);
    let s = slope * c;
    if s.is_nan() || s.abs() >= 1.0 {
        return None;
    }
    let mut theta = s.asin();
    if elements.iter().any(|e| e.centre_m[1] != 0.0) {
        // Gauss–Newton in (a, θ): r_e = a + (x sin θ + z cos θ)/c − d_e.
        let mut a = offset_and_residual(
            TransmitWave::PlaneWave { angle_rad: theta },
            elements,
            delays_s,
            c,
        )?
        .offset_s;
        for _ in 0..50 {
            let (sn, cs) = theta.sin_cos();
            let rows: Vec<(Vec<f64>, f64)> = elements
                .iter()
                .zip(delays_s)
                .map(|(e, d)| {
                    let [x, z] = e.centre_m;
                    (
                        vec![1.0, (x * cs - z * sn) / c],
                        a + (x * sn + z * cs) / c - d,
                    )
                })
                .collect();
            let step = gauss_newton_step(&rows)?;
            a += step[0];
            theta += step[1];
            if step[1].abs() < 1e-15 {
                break;
            }
        }
        if theta.is_nan() || theta.abs() >= std::f64::consts::FRAC_PI_2 {
            return None;
        }
    }
    offset_and_residual(
        TransmitWave::PlaneWave { angle_rad: theta },
        elements,
        delays_s,
        c,
    )
}

/// Circular wave about `p`: `d_e = b + σ‖e − p‖/c`, `σ = +1` (diverging, `p`
/// behind the array) or `−1` (focused, `p` in front).
fn fit_circular(elements: &[Element<f64>], delays_s: &[f64], c: f64) -> Option<Fitted> {
    // Three unknowns: a fourth element tests the model.
    if elements.len() < 4 {
        return None;
    }
    let (mut b, mut p, sigma) = circular_start(elements, delays_s, c)
        .or_else(|| curvature_centre_start(elements, delays_s, c))?;
    // Gauss–Newton on r_e = b + σ‖e − p‖/c − d_e, unknowns (b, p_x, p_z).
    for _ in 0..100 {
        let rows: Vec<(Vec<f64>, f64)> = elements
            .iter()
            .zip(delays_s)
            .map(|(e, d)| {
                let (dx, dz) = (e.centre_m[0] - p[0], e.centre_m[1] - p[1]);
                let r = dx.hypot(dz);
                (
                    vec![1.0, -sigma * dx / (r * c), -sigma * dz / (r * c)],
                    b + sigma * r / c - d,
                )
            })
            .collect();
        let step = gauss_newton_step(&rows)?;
        b += step[0];
        p[0] += step[1];
        p[1] += step[2];
        if step[1].hypot(step[2]) < 1e-15 * p[0].hypot(p[1]).max(1e-3) {
            break;
        }
    }
    let wave = if sigma > 0.0 && p[1] < 0.0 {
        TransmitWave::Diverging { source_m: p }
    } else if sigma < 0.0 && p[1] > 0.0 {
        TransmitWave::Focused { focus_m: p }
    } else {
        // A source in front of the array that fires the nearest element first
        // (or a focus behind it) is neither kind of CONTRACT §2.
        return None;
    };
    offset_and_residual(wave, elements, delays_s, c)
}

/// The closed-form start of [`fit_circular`]: with `D_e = c·d_e`, `B = c·b`,
/// `(D_e − B)² = ‖e − p‖²` gives `D_e² − ‖e‖² = 2B·D_e − 2e·p + K`,
/// `K = ‖p‖² − B²`, linear in `(B, p, K)` (`p_z` drops out on a flat array and
/// comes from `K`). Returns `(b, p, σ)`, `σ` the sign of `D_e − B`.
fn circular_start(
    elements: &[Element<f64>],
    delays_s: &[f64],
    c: f64,
) -> Option<(f64, [f64; 2], f64)> {
    let flat = elements.iter().all(|e| e.centre_m[1] == 0.0);
    // Millimetres keep the squares near 1.
    let k = 1e3;
    let rows: Vec<(Vec<f64>, f64)> = elements
        .iter()
        .zip(delays_s)
        .map(|(e, d)| {
            let (x, z, dd) = (e.centre_m[0] * k, e.centre_m[1] * k, c * d * k);
            let y = dd * dd - x * x - z * z;
            let j = if flat {
                vec![2.0 * dd, -2.0 * x, 1.0]
            } else {
                vec![2.0 * dd, -2.0 * x, -2.0 * z, 1.0]
            };
            (j, -y)
        })
        .collect();
    let sol = gauss_newton_step(&rows)?;
    let (big_b, px) = (sol[0], sol[1]);
    let mean_gap = delays_s.iter().map(|d| c * d * k - big_b).sum::<f64>();
    let sigma = if mean_gap >= 0.0 { 1.0 } else { -1.0 };
    let pz = if flat {
        let kk = sol[2];
        let pz2 = kk + big_b * big_b - px * px;
        if pz2.is_nan() || pz2 <= 0.0 {
            return None;
        }
        // Diverging waves come from behind the array, focused ones converge in
        // front of it.
        -sigma * pz2.sqrt()
    } else {
        sol[2]
    };
    let out = (big_b / (c * k), [px / k, pz / k], sigma);
    (out.0.is_finite() && out.1.iter().all(|v| v.is_finite())).then_some(out)
}

/// The start for delays the closed form cannot place (equal delays make its
/// `B` and `K` columns collinear): a convex array firing every element at once
/// sends a circular wave from its centre of curvature, where the end element's
/// normal crosses `x = 0`. `None` on a flat array.
fn curvature_centre_start(
    elements: &[Element<f64>],
    delays_s: &[f64],
    c: f64,
) -> Option<(f64, [f64; 2], f64)> {
    let end = elements.last()?;
    let ([x, z], [nx, nz]) = (end.centre_m, end.normal);
    if nx == 0.0 {
        return None;
    }
    let p = [0.0, z - x * nz / nx];
    let b = elements
        .iter()
        .zip(delays_s)
        .map(|(e, d)| d - (e.centre_m[0] - p[0]).hypot(e.centre_m[1] - p[1]) / c)
        .sum::<f64>()
        / elements.len() as f64;
    Some((b, p, 1.0))
}

/// The least-squares step `δ` minimising `Σ (J_e·δ + r_e)²` over the rows
/// `(J_e, r_e)` (normal equations, columns scaled to unit norm), or `None` if
/// they are singular.
fn gauss_newton_step(rows: &[(Vec<f64>, f64)]) -> Option<Vec<f64>> {
    let n = rows.first()?.0.len();
    let scale: Vec<f64> = (0..n)
        .map(|j| rows.iter().map(|(r, _)| r[j] * r[j]).sum::<f64>().sqrt())
        .collect();
    if scale.iter().any(|s| !(*s > 0.0 && s.is_finite())) {
        return None;
    }
    let mut m = vec![vec![0.0; n + 1]; n];
    for (jrow, r) in rows {
        for i in 0..n {
            let ji = jrow[i] / scale[i];
            for j in 0..n {
                m[i][j] += ji * jrow[j] / scale[j];
            }
            m[i][n] -= ji * r;
        }
    }
    let x = solve(m)?;
    Some(x.iter().zip(&scale).map(|(v, s)| v / s).collect())
}

/// Gaussian elimination with partial pivoting on the augmented matrix `m`
/// (`n × (n + 1)`); `None` if singular.
fn solve(mut m: Vec<Vec<f64>>) -> Option<Vec<f64>> {
    let n = m.len();
    for col in 0..n {
        let pivot = (col..n).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))?;
        let p = m[pivot][col].abs();
        if p.is_nan() || p <= 1e-14 {
            return None;
        }
        m.swap(col, pivot);
        for row in col + 1..n {
            let f = m[row][col] / m[col][col];
            for k in col..=n {
                m[row][k] -= f * m[col][k];
            }
        }
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|k| m[i][k] * x[k]).sum();
        x[i] = (m[i][n] - s) / m[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Least-squares line `y ≈ a + b·x` and its residual RMS.
pub(super) fn fit_line(x: &[f64], y: &[f64]) -> (f64, f64, f64) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let a = my - b * mx;
    let rms = (x
        .iter()
        .zip(y)
        .map(|(xi, yi)| (yi - a - b * xi).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    (a, b, rms)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::array::{ArrayGeometry, ArrayKind};

    const C: f64 = 1540.0;

    fn p4() -> Vec<Element<f64>> {
        ArrayGeometry {
            kind: ArrayKind::Phased,
            n_elements: 64,
            pitch_m: 0.3e-3,
            element_width_m: 0.25e-3,
            radius_m: f64::INFINITY,
        }
        .elements()
    }

    fn c5() -> Vec<Element<f64>> {
        ArrayGeometry {
            kind: ArrayKind::Convex,
            n_elements: 128,
            pitch_m: 0.508e-3,
            element_width_m: 0.46e-3,
            radius_m: 49.57e-3,
        }
        .elements()
    }

    /// Delays as a scanner stores them: the first-firing element at 0.
    fn delays(wave: TransmitWave<f64>, els: &[Element<f64>]) -> (Vec<f64>, f64) {
        let tau: Vec<f64> = els
            .iter()
            .map(|e| wave.element_delay_s(e.centre_m, C))
            .collect();
        let min = tau.iter().cloned().fold(f64::INFINITY, f64::min);
        (tau.iter().map(|t| t - min).collect(), -min)
    }

    /// Every kind on both geometries comes back, with the clock offset
    /// `a = −min τ` (the first firing is the file's 0).
    #[test]
    fn waves_are_recovered_with_their_clock() {
        let waves = [
            TransmitWave::PlaneWave { angle_rad: 0.0 },
            TransmitWave::PlaneWave { angle_rad: -0.3 },
            TransmitWave::Diverging {
                source_m: [5.456e-3, -14.906e-3],
            },
            TransmitWave::Diverging {
                source_m: [0.0, -25e-3],
            },
            TransmitWave::Focused {
                focus_m: [5e-3, 30e-3],
            },
            TransmitWave::Focused {
                focus_m: [-2e-3, 70e-3],
            },
        ];
        for els in [p4(), c5()] {
            for w in waves {
                let (d, a) = delays(w, &els);
                let f = fit_wave(&els, &d, C, 1e-9).unwrap_or_else(|e| panic!("{w:?}: {e:?}"));
                assert_eq!(
                    std::mem::discriminant(&f.wave),
                    std::mem::discriminant(&w),
                    "{w:?} → {:?}",
                    f.wave
                );
                let (got, want) = match (f.wave, w) {
                    (
                        TransmitWave::PlaneWave { angle_rad: g },
                        TransmitWave::PlaneWave { angle_rad: t },
                    ) => ([g, 0.0], [t, 0.0]),
                    (
                        TransmitWave::Diverging { source_m: g },
                        TransmitWave::Diverging { source_m: t },
                    )
                    | (
                        TransmitWave::Focused { focus_m: g },
                        TransmitWave::Focused { focus_m: t },
                    ) => (g, t),
                    _ => unreachable!(),
                };
                assert!(
                    (got[0] - want[0]).abs() < 1e-9 && (got[1] - want[1]).abs() < 1e-9,
                    "{w:?} → {:?}",
                    f.wave
                );
                assert!(
                    (f.offset_s - a).abs() < 1e-13,
                    "{w:?}: a {} vs {a}",
                    f.offset_s
                );
                assert!(f.max_residual_s < 1e-13, "{w:?}: {}", f.max_residual_s);
            }
        }
    }

    /// A convex array firing every element at once: a diverging wave from
    /// its centre of curvature `(0, −h)`.
    #[test]
    fn equal_delays_on_a_convex_array_diverge_from_its_centre() {
        let els = c5();
        let h = 49.57e-3 * (63.5 * 2.0 * (0.508e-3f64 / (2.0 * 49.57e-3)).asin()).cos();
        let f = fit_wave(&els, &[0.0; 128], C, 1e-9).unwrap();
        let TransmitWave::Diverging { source_m } = f.wave else {
            panic!("{:?}", f.wave);
        };
        assert!(
            source_m[0].abs() < 1e-12 && (source_m[1] + h).abs() < 1e-12,
            "{source_m:?}"
        );
        assert!(f.max_residual_s < 1e-15);
    }

    /// Delays that are no wave at all (random, one element late by a
    /// sample) fit none of the models.
    #[test]
    fn other_profiles_fit_no_model() {
        let els = p4();
        let (mut d, _) = delays(
            TransmitWave::Diverging {
                source_m: [0.0, -16e-3],
            },
            &els,
        );
        d[20] += 1.0 / 10.88e6;
        let e = fit_wave(&els, &d, C, 0.1 / 10.88e6).unwrap_err();
        assert!(e.circular_s.unwrap() > 0.1 / 10.88e6, "{e:?}");
        let zigzag: Vec<f64> = (0..64).map(|i| (i % 2) as f64 * 1e-7).collect();
        assert!(fit_wave(&els, &zigzag, C, 1e-8).is_err());
    }

    #[test]
    fn a_line_is_fitted_exactly() {
        let x = [-1.0, 0.0, 1.0, 2.0];
        let y: Vec<f64> = x.iter().map(|v| 3.0 - 2.0 * v).collect();
        let (a, b, rms) = fit_line(&x, &y);
        assert!((a - 3.0).abs() < 1e-12 && (b + 2.0).abs() < 1e-12 && rms < 1e-12);
    }
}
