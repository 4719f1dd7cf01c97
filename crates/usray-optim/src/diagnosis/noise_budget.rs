//! How much of a diagnosis's gap is the simulation's own Monte Carlo noise, and
//! how many rays would make it a small share.
//!
//! The held-out loss `H` of the calibrated model against the measured image has
//! two parts: the gap the model cannot close, and the noise of the one
//! simulated image it compares. The noise level `N` of a diagnosis is the loss
//! between two independent renders of the same model, so it holds the noise of
//! *two* images: one image's share is about `N/2` (exactly so for the loss's ℓ2
//! term, whose expectation adds the two images' variances), and
//!
//! `share = (N/2) / H`.
//!
//! While that share is large a refit may win or lose by fitting noise, and a
//! verdict of `none` would only say that the simulation was too noisy to see.
//! The noise level falls with the rays `r` as `N ∝ r^(−p)`: `p = 1` for the ℓ2
//! term (variance `∝ 1/r`), `p = ½` for the ℓ1 term (deviation `∝ 1/√r`).

/// Default largest share of the calibrated held-out loss that the simulation's
/// noise may hold for a diagnosis to decide ([`crate::DiagnoseOptions::noise_share`]).
pub(crate) const DEFAULT_NOISE_SHARE: f64 = 0.25;

/// Exponent `p` of `N ∝ r^(−p)` assumed before two ray counts have been
/// measured: between the ℓ1 term's ½ and the ℓ2 term's 1, on the side that asks
/// for more rays rather than fewer.
pub(crate) const DEFAULT_NOISE_EXPONENT: f64 = 0.75;

/// `(N/2) / H`: the share of the held-out loss `held_loss` that one simulated
/// image's Monte Carlo noise holds, from the noise level `noise_loss` (the loss
/// between two independent renders). 1 where `held_loss` is not positive.
///
/// ```
/// use usray_optim::simulation_noise_share;
/// assert_eq!(simulation_noise_share(0.02, 0.04), 0.25);
/// assert_eq!(simulation_noise_share(0.02, 0.0), 1.0);
/// ```
pub fn simulation_noise_share(noise_loss: f64, held_loss: f64) -> f64 {
    if held_loss > 0.0 {
        (0.5 * noise_loss / held_loss).min(1.0)
    } else {
        1.0
    }
}

/// The exponent `p` of `N ∝ r^(−p)` from noise levels measured at two ray
/// counts, kept within `[0.25, 1.5]` (a noisy pair of measurements must not
/// promise that a few more rays silence the simulation); `None` when the two
/// counts are equal or a level is not positive.
///
/// ```
/// use usray_optim::noise_exponent;
/// // Four times the rays, half the noise: p = ½.
/// assert!((noise_exponent(20, 0.04, 80, 0.02).unwrap() - 0.5).abs() < 1e-12);
/// assert_eq!(noise_exponent(20, 0.04, 20, 0.03), None);
/// ```
pub fn noise_exponent(rays_a: usize, noise_a: f64, rays_b: usize, noise_b: f64) -> Option<f64> {
    if rays_a == rays_b || noise_a <= 0.0 || noise_b <= 0.0 {
        return None;
    }
    let p = (noise_a / noise_b).ln() / (rays_b as f64 / rays_a as f64).ln();
    Some(p.clamp(0.25, 1.5))
}

/// Rays at which one image's noise share of the held-out loss falls to
/// `target`, from its level at `rays`: the gap `G = H − N/2` stays while the
/// noise falls as `r^(−p)`, so the share is `target` where
/// `N(r)/2 = target·G/(1 − target)`. `None` when the gap is not positive (the
/// held-out loss is all noise: no ray count makes the noise a small share of
/// it).
///
/// ```
/// use usray_optim::rays_needed;
/// // N = 0.04, H = 0.04: gap 0.02; a share of 1/4 needs N/2 = 0.02/3, a
/// // noise 3× lower: 3² = 9× the rays at p = ½.
/// let r = rays_needed(20, 0.04, 0.04, 0.25, 0.5).unwrap();
/// assert_eq!(r, 180);
/// assert_eq!(rays_needed(20, 0.04, 0.02, 0.25, 0.5), None);
/// ```
pub fn rays_needed(
    rays: usize,
    noise_loss: f64,
    held_loss: f64,
    target: f64,
    exponent: f64,
) -> Option<usize> {
    let gap = held_loss - 0.5 * noise_loss;
    if gap <= 0.0 || noise_loss <= 0.0 {
        return None;
    }
    let wanted = 2.0 * target * gap / (1.0 - target);
    let factor = (noise_loss / wanted).powf(1.0 / exponent);
    Some(((rays as f64) * factor).ceil().max(rays as f64) as usize)
}

/// Whether the simulation's noise let a diagnosis decide, and what it would
/// have taken ([`crate::Diagnosis::noise_check`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct NoiseCheck {
    /// Rays per element of the final calibration and everything after it.
    pub rays: usize,
    /// [`simulation_noise_share`] at those rays.
    pub share: f64,
    /// The largest share allowed ([`crate::DiagnoseOptions::noise_share`]).
    pub target: f64,
    /// `share ≤ target`.
    pub passed: bool,
    /// Rays at which the share would reach the target ([`rays_needed`]);
    /// `None` when no ray count would (the held-out loss is all noise).
    pub rays_needed: Option<usize>,
    /// The diagnosis's estimated wall time at [`NoiseCheck::rays_needed`],
    /// seconds: its calibration's time per ray × the rays ×
    /// the ratio of a whole diagnosis's time to its calibration stage's
    /// (6, the middle of those measured; docs/performance.md).
    pub seconds_needed: Option<f64>,
    /// Each calibration's rays and share, in order (more than one where the
    /// rays were raised within the budget).
    pub history: Vec<(usize, f64)>,
}
