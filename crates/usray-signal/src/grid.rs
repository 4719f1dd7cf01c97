//! Sector imaging: the polar `(r, θ)` pixel grid of phased and convex arrays and
//! its bilinear scan conversion to a Cartesian image, with the conversion's VJP.
//!
//! A polar pixel `(r_i, θ_j)` sits at `origin + r_i·(sin θ_j, cos θ_j)` in the
//! probe frame (CONTRACT §1), `θ` measured from the `z` axis toward `+x`. The
//! origin is the array centre `(0, 0)` for a phased array and the arc's centre
//! `(0, −h)` for a convex one ([`crate::array::ArrayGeometry::sector_origin_m`]),
//! as PyMUST's `impolgrid`. Rows are radii, columns angles (`[n_r, n_θ]`,
//! row-major), so a polar image has the layout of a Cartesian one.
//!
//! Scan conversion reads a polar image at each Cartesian pixel `(x, z)` by
//! bilinear interpolation in `(r, θ)` (`r = ‖p − o‖`, `θ = atan2(x − o_x, z −
//! o_z)`); pixels outside the sector are 0. It is linear, `y = S u`; its VJP is
//! `ū = Sᵀ ȳ`, accumulated in pixel order (same bits for any thread count).

use crate::array::ArrayGeometry;

/// A uniform polar grid.
#[derive(Clone, Debug, PartialEq)]
pub struct PolarGrid {
    /// Centre of the polar coordinates, probe frame `(x, z)`, m.
    pub origin_m: [f64; 2],
    /// Radii of the rows, m, increasing, uniformly spaced.
    pub r_m: Vec<f64>,
    /// Angles of the columns from the `z` axis, rad, increasing, uniformly spaced.
    pub theta_rad: Vec<f64>,
    sin_cos: Vec<(f64, f64)>,
}

fn uniform(name: &str, v: &[f64]) -> Result<(), String> {
    if v.is_empty() || v.iter().any(|x| !x.is_finite()) {
        return Err(format!("{name}: needs at least one finite value"));
    }
    if v.len() > 1 {
        let h = (v[v.len() - 1] - v[0]) / (v.len() - 1) as f64;
        let scale = v[0].abs().max(v[v.len() - 1].abs()).max(h.abs());
        if h.is_nan()
            || h <= 0.0
            || v.iter()
                .enumerate()
                .any(|(i, x)| (x - (v[0] + i as f64 * h)).abs() > 1e-9 * scale)
        {
            return Err(format!("{name}: values must increase in uniform steps"));
        }
    }
    Ok(())
}

impl PolarGrid {
    /// A grid of radii `r_m` (≥ 0) and angles `theta_rad` (inside ±π/2) about
    /// `origin_m`, both uniform and increasing. The error names what is wrong.
    pub fn new(origin_m: [f64; 2], r_m: Vec<f64>, theta_rad: Vec<f64>) -> Result<Self, String> {
        uniform("polar grid radii", &r_m)?;
        uniform("polar grid angles", &theta_rad)?;
        if r_m[0] < 0.0 {
            return Err(format!("polar grid radii start at {} m (< 0)", r_m[0]));
        }
        if theta_rad
            .iter()
            .any(|t| t.abs() >= std::f64::consts::FRAC_PI_2)
        {
            return Err("polar grid angles must lie inside ±π/2".into());
        }
        if !origin_m.iter().all(|v| v.is_finite()) {
            return Err(format!("polar grid origin {origin_m:?} is not finite"));
        }
        let sin_cos = theta_rad.iter().map(|t| t.sin_cos()).collect();
        Ok(PolarGrid {
            origin_m,
            r_m,
            theta_rad,
            sin_cos,
        })
    }

    /// The sector of `array` that covers the Cartesian box `x_range_m` ×
    /// `z_range_m` at about `pixel_m` resolution: origin
    /// [`ArrayGeometry::sector_origin_m`]; angles over the array's field of
    /// view (a convex array's arc, `±(N−1)δ/2`; ±45° for a flat array), limited
    /// to the box; radii from the box's nearest depth to its farthest corner in
    /// steps of `pixel_m`, angles in steps of `pixel_m` at the largest radius.
    pub fn sector(
        array: &ArrayGeometry<f64>,
        x_range_m: [f64; 2],
        z_range_m: [f64; 2],
        pixel_m: f64,
    ) -> Result<Self, String> {
        let o = array.sector_origin_m();
        let fov = if array.kind.is_flat() {
            std::f64::consts::FRAC_PI_4
        } else {
            array.angular_pitch_rad() * (array.n_elements as f64 - 1.0) / 2.0
        };
        let corners = [
            [x_range_m[0], z_range_m[1]],
            [x_range_m[1], z_range_m[1]],
            [x_range_m[0], z_range_m[0]],
            [x_range_m[1], z_range_m[0]],
        ];
        let r_max = corners
            .iter()
            .map(|p| (p[0] - o[0]).hypot(p[1] - o[1]))
            .fold(0.0, f64::max);
        let r_min = (z_range_m[0] - o[1]).max(0.0);
        let angle = |x: f64| {
            // The widest angle a point of the box at lateral x can have.
            let z = (z_range_m[0] - o[1]).max(1e-12);
            (x - o[0]).atan2(z)
        };
        let (t0, t1) = (angle(x_range_m[0]).max(-fov), angle(x_range_m[1]).min(fov));
        if !(r_max > r_min && t1 > t0 && pixel_m > 0.0) {
            return Err(format!(
                "imaging box x {x_range_m:?} × z {z_range_m:?} m does not meet the probe's sector"
            ));
        }
        let n_r = ((r_max - r_min) / pixel_m).ceil() as usize + 1;
        let n_t = ((t1 - t0) * r_max / pixel_m).ceil() as usize + 1;
        PolarGrid::new(
            o,
            crate::das::linspace(r_min, r_max, n_r),
            crate::das::linspace(t0, t1, n_t),
        )
    }

    /// `(n_r, n_θ)`.
    pub fn shape(&self) -> (usize, usize) {
        (self.r_m.len(), self.theta_rad.len())
    }

    /// Probe-frame position `(x, z)` of pixel (row `ir`, column `it`), m.
    #[inline(always)]
    pub fn pixel(&self, ir: usize, it: usize) -> [f64; 2] {
        let (s, c) = self.sin_cos[it];
        let r = self.r_m[ir];
        [self.origin_m[0] + r * s, self.origin_m[1] + r * c]
    }
}

/// Bilinear weights of one Cartesian pixel: the polar pixel `base` (row `i`,
/// column `j`) and its neighbours `base + 1`, `base + n_θ`, `base + n_θ + 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Tap {
    base: usize,
    w_r: f64,
    w_t: f64,
    /// Column step (0 on a one-column grid) and row step (0 on a one-row grid).
    step: [usize; 2],
}

/// Bilinear scan conversion from a [`PolarGrid`] to a Cartesian grid.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanConversion {
    n_polar: usize,
    taps: Vec<Option<Tap>>,
}

/// Fractional index of `v` on a uniform axis, if inside it (`None` outside).
fn fractional(v: f64, axis: &[f64]) -> Option<(usize, f64)> {
    let n = axis.len();
    if n == 1 {
        return (v == axis[0]).then_some((0, 0.0));
    }
    let h = (axis[n - 1] - axis[0]) / (n - 1) as f64;
    let s = (v - axis[0]) / h;
    if !(s >= 0.0 && s <= (n - 1) as f64) {
        return None;
    }
    let i = (s as usize).min(n - 2);
    Some((i, s - i as f64))
}

impl ScanConversion {
    /// The conversion of images on `polar` to the grid `x_m` × `z_m` (`[nz, nx]`).
    pub fn new(polar: &PolarGrid, x_m: &[f64], z_m: &[f64]) -> Self {
        let (nr, nt) = polar.shape();
        let o = polar.origin_m;
        let mut taps = Vec::with_capacity(x_m.len() * z_m.len());
        for &z in z_m {
            for &x in x_m {
                let (dx, dz) = (x - o[0], z - o[1]);
                let r = dx.hypot(dz);
                let th = dx.atan2(dz);
                taps.push(
                    fractional(r, &polar.r_m)
                        .zip(fractional(th, &polar.theta_rad))
                        .map(|((i, w_r), (j, w_t))| Tap {
                            base: i * nt + j,
                            w_r,
                            w_t,
                            step: [usize::from(nt > 1), if nr > 1 { nt } else { 0 }],
                        }),
                );
            }
        }
        ScanConversion {
            n_polar: nr * nt,
            taps,
        }
    }

    /// Number of polar pixels the input must hold.
    pub fn polar_len(&self) -> usize {
        self.n_polar
    }

    /// Number of Cartesian pixels of the output.
    pub fn cartesian_len(&self) -> usize {
        self.taps.len()
    }

    /// `out = S·polar`.
    ///
    /// # Panics
    /// If the buffer lengths differ from [`Self::polar_len`] / [`Self::cartesian_len`].
    pub fn forward(&self, polar: &[f64], out: &mut [f64]) {
        assert_eq!(polar.len(), self.n_polar, "polar image length");
        assert_eq!(out.len(), self.taps.len(), "Cartesian image length");
        for (o, tap) in out.iter_mut().zip(&self.taps) {
            *o = match tap {
                None => 0.0,
                Some(t) => {
                    let [sc, sr] = t.step;
                    let a = polar[t.base] * (1.0 - t.w_t) + polar[t.base + sc] * t.w_t;
                    let b = polar[t.base + sr] * (1.0 - t.w_t) + polar[t.base + sr + sc] * t.w_t;
                    a * (1.0 - t.w_r) + b * t.w_r
                }
            };
        }
    }

    /// `polar_bar = Sᵀ·out_bar` (overwritten).
    ///
    /// # Panics
    /// If the buffer lengths differ from [`Self::polar_len`] / [`Self::cartesian_len`].
    pub fn vjp(&self, out_bar: &[f64], polar_bar: &mut [f64]) {
        assert_eq!(polar_bar.len(), self.n_polar, "polar image length");
        assert_eq!(out_bar.len(), self.taps.len(), "Cartesian image length");
        polar_bar.fill(0.0);
        for (&g, tap) in out_bar.iter().zip(&self.taps) {
            let Some(t) = tap else { continue };
            let [sc, sr] = t.step;
            let (a, b) = (g * (1.0 - t.w_r), g * t.w_r);
            polar_bar[t.base] += a * (1.0 - t.w_t);
            polar_bar[t.base + sc] += a * t.w_t;
            polar_bar[t.base + sr] += b * (1.0 - t.w_t);
            polar_bar[t.base + sr + sc] += b * t.w_t;
        }
    }
}
