//! Step 4's spatial statistic: is an excess over the null refit spread over
//! the image, or carried by a few places?
//!
//! The standard error of an excess ([`super::EffectResult::excess_std`]) comes
//! from the held-out *seeds*: it measures the simulation's Monte Carlo noise,
//! not the measured image's. Against one measured image, a candidate that bends
//! the model towards a structure it does not hold (an unmodelled wire, the edge
//! waves of full-wave data) gains the same on every seed, so that standard error
//! says such a gain is certain. Which pixels gain says otherwise: a real
//! effect makes the model better wherever the effect shows, a candidate that
//! absorbs a foreign structure gains at that structure and loses elsewhere.
//!
//! The image is cut into square blocks [`BLOCK_WAVELENGTHS`] wavelengths wide
//! (wider than an echo, so blocks' residuals are nearly independent), the
//! loss is the sum of its blocks' shares (`L = Σ_b L_b`, `L_b = (1/N_pix)
//! Σ_{u∈b} ℓ(I_u − R_u)` for the pixel loss `ℓ` of [`crate::L1L2`]), and the
//! excess is `Σ_b D_b` with `D_b` the block's loss difference null − refit,
//! averaged over the held-out seeds, over the calibrated held-out loss. Taking
//! the blocks as a sample, the standard error of that sum is `√B · sd(D_b)`
//! (the block jackknife of a total; Künsch, *Ann. Stat.* 17, 1217, 1989).
//! Blocks the model and data leave empty add `D_b ≈ 0` to both the sum and the
//! spread and change the ratio little.
//!
//! With a paired loss the blocks take the first seed's image alone, so the
//! blocks' sum differs from the paired excess by the paired loss's
//! correction; the spread across blocks is what is used.

use super::calibration::LossSetup;
use crate::objective::Evaluation;
use crate::L1L2;
use usray_transport::Scene;

/// Side of a block, wavelengths `λ = c/f_c` (the medium's speed, the probe's
/// centre frequency): three, wider than an echo's envelope (about one
/// wavelength at 2–3 cycles) and a lateral resolution cell (`F#·λ`, 1.5λ at
/// F# 1.5).
pub(crate) const BLOCK_WAVELENGTHS: f64 = 3.0;

/// A block's side in pixels on `scene`'s grid (at least 2).
pub(crate) fn block_px(scene: &Scene) -> usize {
    let wavelength_m = scene.medium.sound_speed_m_s / scene.probe.center_frequency_hz;
    ((BLOCK_WAVELENGTHS * wavelength_m / scene.imaging.pixel_m).round() as usize).max(2)
}

/// The held-out evaluations of one model as the verdict compares them: each
/// seed's loss and its shares by block of the image.
pub(crate) struct HeldOutLosses {
    /// One loss per held-out seed.
    pub per_seed: Vec<f64>,
    /// Each seed's loss by block (row-major over the blocks); they sum to its
    /// one-image pixel loss (for a paired loss, its first image's).
    pub blocks: Vec<Vec<f64>>,
}

/// The held-out evaluations `evals` of one model against `measured`, with
/// their losses by blocks of `side` pixels through `setup`'s comparison.
pub(crate) fn held_out_losses(
    setup: &LossSetup,
    measured: &[f64],
    evals: &[Evaluation],
    side: usize,
) -> HeldOutLosses {
    let loss = L1L2::default();
    let blocks = evals
        .iter()
        .map(|e| {
            let (nz, nx) = (e.image.nz, e.image.nx);
            let (sim, reference) = if setup.comparison.is_identity() {
                (e.image.data.clone(), measured.to_vec())
            } else {
                (
                    setup.comparison.apply(&e.image.data, nz, nx),
                    setup.comparison.apply(measured, nz, nx),
                )
            };
            per_block(&sim, &reference, nz, nx, side, &loss)
        })
        .collect();
    HeldOutLosses {
        per_seed: evals.iter().map(|e| e.loss).collect(),
        blocks,
    }
}

/// `L_b = (1/N_pix) Σ_{u∈b} (λ₁|a_u − r_u| + λ₂ (a_u − r_u)²)` for each block
/// of `side` × `side` pixels of `[nz, nx]` images (the last row and column
/// of blocks may be narrower).
fn per_block(a: &[f64], r: &[f64], nz: usize, nx: usize, side: usize, loss: &L1L2) -> Vec<f64> {
    let (bz, bx) = (nz.div_ceil(side), nx.div_ceil(side));
    let mut out = vec![0.0; bz * bx];
    let n = (nz * nx).max(1) as f64;
    for iz in 0..nz {
        for ix in 0..nx {
            let d = a[iz * nx + ix] - r[iz * nx + ix];
            out[(iz / side) * bx + ix / side] +=
                (loss.lambda1 * d.abs() + loss.lambda2 * d * d) / n;
        }
    }
    out
}

/// The spatial standard error of an excess: `√B · sd(D_b)`, with `D_b` the
/// per-seed block differences `(base_jb − after_jb) / scale` averaged over the
/// seeds (module docs). `None` with fewer than two blocks.
pub(crate) fn excess_spatial_std(base: &[Vec<f64>], after: &[Vec<f64>], scale: f64) -> Option<f64> {
    let blocks = base.first()?.len();
    if blocks < 2 || base.len() != after.len() || base.is_empty() {
        return None;
    }
    let seeds = base.len() as f64;
    let d: Vec<f64> = (0..blocks)
        .map(|b| {
            base.iter()
                .zip(after)
                .map(|(x, y)| (x[b] - y[b]) / scale)
                .sum::<f64>()
                / seeds
        })
        .collect();
    let m = d.iter().sum::<f64>() / blocks as f64;
    let var = d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (blocks - 1) as f64;
    Some((blocks as f64 * var).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_sum_to_the_pixel_loss() {
        let (nz, nx) = (7, 5);
        let a: Vec<f64> = (0..nz * nx)
            .map(|i| (i as f64 * 0.37).sin().abs())
            .collect();
        let r: Vec<f64> = (0..nz * nx)
            .map(|i| (i as f64 * 0.11).cos().abs())
            .collect();
        let loss = L1L2::default();
        let blocks = per_block(&a, &r, nz, nx, 3, &loss);
        assert_eq!(blocks.len(), 3 * 2);
        let whole = loss.value(&a, &r);
        assert!((blocks.iter().sum::<f64>() - whole).abs() < 1e-15 * whole.max(1.0));
    }

    #[test]
    fn spread_gains_are_certain_and_a_gain_paid_elsewhere_is_not() {
        // Ten blocks each gaining 0.01 on two seeds: the spread is 0.
        let base = vec![vec![1.0; 10]; 2];
        let after = vec![vec![0.99; 10]; 2];
        assert!(excess_spatial_std(&base, &after, 1.0).unwrap() < 1e-12);
        // One block gains 0.1, another loses 0.05: total 0.05, and the
        // standard error √B·sd(D) is larger than it.
        let mut after = vec![vec![1.0; 10]; 2];
        for a in &mut after {
            a[0] = 0.9;
            a[1] = 1.05;
        }
        let se = excess_spatial_std(&base, &after, 1.0).unwrap();
        let d = [0.1, -0.05, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let m = 0.005;
        let sd = (d.iter().map(|x: &f64| (x - m).powi(2)).sum::<f64>() / 9.0).sqrt();
        assert!((se - 10f64.sqrt() * sd).abs() < 1e-12);
        assert!(se > 0.05);
    }
}
