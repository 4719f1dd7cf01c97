//! How a simulated B-mode is compared with a measured one before the pixel loss:
//! both are smoothed by a Gaussian and floored at the measurement's noise level.
//!
//! The paper's loss (eq. `weighted_l1_l2_loss`) compares log-compressed B-modes
//! pixel by pixel. Two things in a measured image no simulation reproduces pixel
//! for pixel: speckle and electronic noise, each a random field whose *level* a
//! model can match but whose *realisation* it cannot. Pixel-wise, both add a
//! loss that no parameter removes, and that share of the loss dilutes every
//! effect a diagnosis measures against it (on tier (a)'s layered scene with
//! −50 dB channel noise, 66% of the calibrated loss lay outside every object).
//! The comparison here takes both out of the loss:
//!
//! `C(I) = max(G_σ * I, f)`,
//!
//! with `G_σ` a separable Gaussian of standard deviation `σ = (σ_z, σ_x)` pixels
//! (zero-padded, truncated at 3σ: a symmetric operator, so its adjoint is itself)
//! that averages a speckle or noise field over about a resolution cell, and `f`
//! the floor: the grey level below which the measurement shows its own noise
//! and not the scene ([`noise_floor`]). The loss is then
//! `L(C(I_sim), C(I_meas))` and its gradient `∂L/∂I = G_σ [1{G_σ*I > f} ∂L/∂C]`.
//! [`Comparison::identity`] (σ = 0, f = 0 on images in `[0, 1]`) is the paper's loss.

/// Smoothing and floor of the comparison (module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// Standard deviation of the Gaussian along depth, pixels (0: none).
    pub sigma_z_px: f64,
    /// Standard deviation of the Gaussian along the array, pixels (0: none).
    pub sigma_x_px: f64,
    /// The floor `f`, grey level of the log-compressed image (0 = the bottom of
    /// its dynamic range, 1 = its top; 0: no floor).
    pub floor: f64,
}

impl Default for Comparison {
    /// [`Comparison::identity`].
    fn default() -> Self {
        Self::identity()
    }
}

impl Comparison {
    /// No smoothing, no floor: the pixel-wise comparison of the paper.
    #[must_use]
    pub fn identity() -> Self {
        Self {
            sigma_z_px: 0.0,
            sigma_x_px: 0.0,
            floor: 0.0,
        }
    }

    /// A smoothing of `sigma_m` metres on a grid of `pixel_m`, no floor.
    #[must_use]
    pub fn smoothing(sigma_m: f64, pixel_m: f64) -> Self {
        let px = if pixel_m > 0.0 && sigma_m > 0.0 {
            sigma_m / pixel_m
        } else {
            0.0
        };
        Self {
            sigma_z_px: px,
            sigma_x_px: px,
            floor: 0.0,
        }
    }

    /// Whether this comparison changes nothing.
    #[must_use]
    pub fn is_identity(&self) -> bool {
        self.sigma_z_px <= 0.0 && self.sigma_x_px <= 0.0 && self.floor <= 0.0
    }

    /// `G_σ * I` of a `[nz, nx]` row-major image (no floor).
    #[must_use]
    pub fn smooth(&self, image: &[f64], nz: usize, nx: usize) -> Vec<f64> {
        let along_x = blur_rows(image, nz, nx, self.sigma_x_px);
        blur_columns(&along_x, nz, nx, self.sigma_z_px)
    }

    /// `C(I) = max(G_σ * I, f)`.
    #[must_use]
    pub fn apply(&self, image: &[f64], nz: usize, nx: usize) -> Vec<f64> {
        let mut out = self.smooth(image, nz, nx);
        if self.floor > 0.0 {
            for v in &mut out {
                *v = v.max(self.floor);
            }
        }
        out
    }

    /// The vector–Jacobian product of [`Comparison::apply`] at `image`:
    /// `∂L/∂I = G_σ [1{G_σ*I > f} ∂L/∂C]` (`G_σ` is symmetric). At the floor
    /// itself the subgradient 0 is taken.
    #[must_use]
    pub fn pullback(&self, image: &[f64], nz: usize, nx: usize, d_compared: &[f64]) -> Vec<f64> {
        let mut d = d_compared.to_vec();
        if self.floor > 0.0 {
            let smoothed = self.smooth(image, nz, nx);
            for (g, s) in d.iter_mut().zip(smoothed) {
                if s <= self.floor {
                    *g = 0.0;
                }
            }
        }
        let along_z = blur_columns(&d, nz, nx, self.sigma_z_px);
        blur_rows(&along_z, nz, nx, self.sigma_x_px)
    }
}

/// The normalised Gaussian taps `g_k ∝ exp(−k²/2σ²)`, `|k| ≤ ⌈3σ⌉`; `[1]` for
/// σ ≤ 0.
fn gaussian_taps(sigma: f64) -> Vec<f64> {
    if sigma <= 0.0 || !sigma.is_finite() {
        return vec![1.0];
    }
    let half = (3.0 * sigma).ceil() as isize;
    let taps: Vec<f64> = (-half..=half)
        .map(|k| (-((k * k) as f64) / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f64 = taps.iter().sum();
    taps.into_iter().map(|t| t / sum).collect()
}

/// One-dimensional zero-padded convolution of `n` values read at `at(i)`.
fn convolve(n: usize, taps: &[f64], at: impl Fn(usize) -> f64, mut put: impl FnMut(usize, f64)) {
    let half = (taps.len() / 2) as isize;
    for i in 0..n as isize {
        let mut acc = 0.0;
        for (t, &w) in taps.iter().enumerate() {
            let j = i + t as isize - half;
            if j >= 0 && j < n as isize {
                acc += w * at(j as usize);
            }
        }
        put(i as usize, acc);
    }
}

/// The Gaussian along each row (the array direction).
fn blur_rows(image: &[f64], nz: usize, nx: usize, sigma: f64) -> Vec<f64> {
    let taps = gaussian_taps(sigma);
    if taps.len() == 1 {
        return image.to_vec();
    }
    let mut out = vec![0.0; image.len()];
    for z in 0..nz {
        let row = &image[z * nx..(z + 1) * nx];
        let out_row = &mut out[z * nx..(z + 1) * nx];
        convolve(nx, &taps, |j| row[j], |i, v| out_row[i] = v);
    }
    out
}

/// The Gaussian down each column (depth).
fn blur_columns(image: &[f64], nz: usize, nx: usize, sigma: f64) -> Vec<f64> {
    let taps = gaussian_taps(sigma);
    if taps.len() == 1 {
        return image.to_vec();
    }
    let mut out = vec![0.0; image.len()];
    for x in 0..nx {
        convolve(nz, &taps, |j| image[j * nx + x], |i, v| out[i * nx + x] = v);
    }
    out
}

/// Pixels of the model's image it calls empty: smoothed grey level at most
/// this (3 dB above the bottom of a 60 dB range).
pub const MODEL_DARK_GREY: f64 = 0.05;

/// Fewest empty pixels, as a share of the image, from which a floor is
/// estimated; with fewer the floor is 0 (tissue everywhere: no region shows
/// the measurement's noise alone).
pub const MIN_DARK_SHARE: f64 = 0.1;

/// Largest noise floor, grey level (9 dB above the bottom of a 60 dB range).
/// An estimate above it is not the measurement's noise: over half the pixels
/// the model leaves empty then hold signal the model lacks (lumen speckle in
/// k-Wave data gave 0.53), which is evidence for an effect, and flooring at
/// that level would hide it; [`noise_floor`] is then 0.
pub const MAX_NOISE_FLOOR: f64 = 0.15;

/// The measurement's noise floor, grey level: over the pixels where the
/// calibrated model's smoothed image `model` is empty (≤ [`MODEL_DARK_GREY`]),
/// the median of the smoothed measured image `measured` plus two of its robust
/// standard deviations (1.4826 × the median absolute deviation: for Gaussian
/// values the 98th percentile). What the measurement shows there is its own
/// noise (or an effect the model lacks, which the median ignores while it
/// covers under half of those pixels); a simulated pixel below this level
/// cannot be told from that noise. 0 when under [`MIN_DARK_SHARE`] of the image
/// is empty, or when the estimate passes [`MAX_NOISE_FLOOR`].
///
/// ```
/// use usray_optim::noise_floor;
/// // Half the model is empty; the measurement shows noise of level 0.1 ± 0.02 there.
/// let model = [0.0, 0.0, 0.0, 0.0, 0.8, 0.8, 0.8, 0.8];
/// let measured = [0.08, 0.1, 0.12, 0.1, 0.8, 0.7, 0.9, 0.8];
/// let f = noise_floor(&model, &measured);
/// assert!((f - (0.1 + 2.0 * 1.4826 * 0.01)).abs() < 1e-12);
/// ```
#[must_use]
pub fn noise_floor(model: &[f64], measured: &[f64]) -> f64 {
    let mut dark: Vec<f64> = model
        .iter()
        .zip(measured)
        .filter(|(&s, _)| s <= MODEL_DARK_GREY)
        .map(|(_, &m)| m)
        .filter(|m| m.is_finite())
        .collect();
    if (dark.len() as f64) < MIN_DARK_SHARE * model.len() as f64 || dark.is_empty() {
        return 0.0;
    }
    let median = median_of(&mut dark);
    let mut dev: Vec<f64> = dark.iter().map(|m| (m - median).abs()).collect();
    let mad = median_of(&mut dev);
    let floor = (median + 2.0 * 1.4826 * mad).max(0.0);
    if floor > MAX_NOISE_FLOOR {
        0.0
    } else {
        floor
    }
}

/// The median of `v` (reordered; the mean of the two middle values for an even
/// count).
fn median_of(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pseudo_random(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (s >> 11) as f64 / (1u64 << 53) as f64
            })
            .collect()
    }

    /// The smoothing is its own adjoint: `⟨G a, b⟩ = ⟨a, G b⟩`.
    #[test]
    fn smoothing_passes_the_dot_product_test() {
        let (nz, nx) = (23, 17);
        let c = Comparison {
            sigma_z_px: 1.7,
            sigma_x_px: 0.9,
            floor: 0.0,
        };
        let a = pseudo_random(nz * nx, 1);
        let b = pseudo_random(nz * nx, 2);
        let ga = c.smooth(&a, nz, nx);
        let gtb = c.pullback(&a, nz, nx, &b);
        let lhs: f64 = ga.iter().zip(&b).map(|(x, y)| x * y).sum();
        let rhs: f64 = a.iter().zip(&gtb).map(|(x, y)| x * y).sum();
        assert!((lhs - rhs).abs() < 1e-12 * lhs.abs(), "{lhs} vs {rhs}");
    }

    /// The pullback through smoothing and floor matches central differences
    /// of a loss `Σ w·C(I)` (pixels away from the floor's kink).
    #[test]
    fn pullback_matches_central_differences() {
        let (nz, nx) = (9, 7);
        let c = Comparison {
            sigma_z_px: 1.2,
            sigma_x_px: 0.8,
            floor: 0.45,
        };
        let image = pseudo_random(nz * nx, 3);
        let w = pseudo_random(nz * nx, 4);
        let loss =
            |im: &[f64]| -> f64 { c.apply(im, nz, nx).iter().zip(&w).map(|(x, y)| x * y).sum() };
        let grad = c.pullback(&image, nz, nx, &w);
        let smoothed = c.smooth(&image, nz, nx);
        // No smoothed pixel may sit on the floor's kink, where the FD straddles it.
        assert!(smoothed.iter().all(|s| (s - c.floor).abs() > 1e-4));
        let h = 1e-7;
        for u in 0..image.len() {
            let mut up = image.clone();
            up[u] += h;
            let mut down = image.clone();
            down[u] -= h;
            let fd = (loss(&up) - loss(&down)) / (2.0 * h);
            assert!(
                (fd - grad[u]).abs() < 1e-7,
                "pixel {u}: {} vs FD {fd}",
                grad[u]
            );
        }
        // Some pixels lie below the floor (zero gradient there) and some above.
        assert!(smoothed.iter().any(|&s| s < c.floor) && smoothed.iter().any(|&s| s > c.floor));
    }

    /// Smoothing preserves a constant image away from the edges, and the
    /// identity changes nothing.
    #[test]
    fn smoothing_keeps_a_constant_and_identity_is_identity() {
        let (nz, nx) = (20, 20);
        let c = Comparison::smoothing(0.2e-3, 0.1e-3);
        let out = c.apply(&vec![0.5; nz * nx], nz, nx);
        assert!((out[10 * nx + 10] - 0.5).abs() < 1e-12);
        let img = pseudo_random(nz * nx, 5);
        assert_eq!(Comparison::identity().apply(&img, nz, nx), img);
        assert!(Comparison::identity().is_identity());
    }

    /// On a field of independent pixels of variance `v`, the smoothing leaves a
    /// variance `v Σ g_k²` (per axis) — the reduction the comparison relies on.
    #[test]
    fn smoothing_divides_white_noise_variance_by_the_kernels_energy() {
        let (nz, nx) = (200, 200);
        let sigma = 1.5;
        let c = Comparison {
            sigma_z_px: sigma,
            sigma_x_px: sigma,
            floor: 0.0,
        };
        let noise = pseudo_random(nz * nx, 6);
        let out = c.smooth(&noise, nz, nx);
        let m = 12; // away from the zero-padded edges
        let inner: Vec<f64> = (m..nz - m)
            .flat_map(|z| (m..nx - m).map(move |x| (z, x)))
            .map(|(z, x)| out[z * nx + x])
            .collect();
        let mean = inner.iter().sum::<f64>() / inner.len() as f64;
        let var = inner.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / inner.len() as f64;
        let energy: f64 = gaussian_taps(sigma).iter().map(|g| g * g).sum();
        let expected = (1.0 / 12.0) * energy * energy;
        // The sample variance of ~30 000 correlated pixels: a few percent.
        assert!(
            (var / expected - 1.0).abs() < 0.1,
            "variance {var} vs {expected}"
        );
    }

    /// The floor ignores a minority of bright "unmodelled" pixels among the
    /// empty ones, and is 0 when too few pixels are empty.
    #[test]
    fn noise_floor_is_robust_and_needs_empty_pixels() {
        let n = 100;
        let model: Vec<f64> = (0..n).map(|i| if i < 60 { 0.0 } else { 0.9 }).collect();
        let mut measured: Vec<f64> = (0..n).map(|i| if i < 60 { 0.1 } else { 0.9 }).collect();
        for m in measured.iter_mut().take(20) {
            *m = 0.6; // a third of the empty pixels carry an unmodelled echo
        }
        let f = noise_floor(&model, &measured);
        assert!((f - 0.1).abs() < 1e-12, "{f}");
        let full: Vec<f64> = vec![0.9; n];
        assert_eq!(noise_floor(&full, &measured), 0.0);
        // Over half the empty pixels bright (unmodelled signal, not noise):
        // no floor rather than one that would hide it.
        for m in measured.iter_mut().take(40) {
            *m = 0.6;
        }
        const { assert!(0.6 > MAX_NOISE_FLOOR) };
        assert_eq!(noise_floor(&model, &measured), 0.0);
    }
}
