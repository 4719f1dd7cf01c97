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
//! The losses compared are scores unbiased in the simulation's variance
//! ([`held_out_scores`]), so that a candidate is not credited for a quieter
//! simulation. With a paired loss the blocks take the first seed's image
//! alone, so the blocks' sum differs from the paired excess by the paired
//! loss's correction; the spread across blocks is what is used.

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
/// seed's score and its shares by block of the image.
pub(crate) struct HeldOutScores {
    /// One score per held-out seed.
    pub per_seed: Vec<f64>,
    /// Each seed's score by block (row-major over the blocks); they sum to
    /// [`HeldOutScores::per_seed`] (for a paired loss, to its first image's
    /// pixel loss).
    pub blocks: Vec<Vec<f64>>,
}

/// The held-out evaluations `evals` of one model against `measured`, scored
/// for the verdict by blocks of `side` pixels, through `setup`'s comparison.
///
/// The one-render loss rewards a quieter simulation: for a pixel `s` of the
/// model, `E ℓ₂(s − R) = (E s − R)² + Var s`, so a candidate that only
/// darkens the model's Monte Carlo clutter (an attenuation at depth) gains on
/// every seed and in every block. Each seed `j` is therefore scored in the
/// form of the energy score with the next seed's image (Gneiting & Raftery,
/// *JASA* 102, 359, 2007, eq. 22; [`L1L2::paired_value_and_gradient`]):
/// `S_j = L(I_j, R) − ½ L(I_j, I_{j+1})` (cyclically), whose ℓ2 term's
/// expectation is `(E s − R)²` exactly. No render is added: the seeds' images
/// are already there. A paired loss already is this score (each evaluation's
/// loss is taken as it is; its blocks are the first image's pixel loss);
/// with one seed no pair exists and the loss is taken as it is.
pub(crate) fn held_out_scores(
    setup: &LossSetup,
    measured: &[f64],
    evals: &[Evaluation],
    side: usize,
) -> HeldOutScores {
    let loss = L1L2::default();
    let Some(first) = evals.first() else {
        return HeldOutScores {
            per_seed: vec![],
            blocks: vec![],
        };
    };
    let (nz, nx) = (first.image.nz, first.image.nx);
    let compare = |image: &[f64]| {
        if setup.comparison.is_identity() {
            image.to_vec()
        } else {
            setup.comparison.apply(image, nz, nx)
        }
    };
    let reference = compare(measured);
    let compared: Vec<Vec<f64>> = evals.iter().map(|e| compare(&e.image.data)).collect();
    let k = compared.len();
    let blocks: Vec<Vec<f64>> = (0..k)
        .map(|j| {
            let mut b = per_block(&compared[j], &reference, nz, nx, side, &loss);
            if !setup.paired && k > 1 {
                let own = per_block(&compared[j], &compared[(j + 1) % k], nz, nx, side, &loss);
                for (x, o) in b.iter_mut().zip(own) {
                    *x -= 0.5 * o;
                }
            }
            b
        })
        .collect();
    let per_seed = if setup.paired || k == 1 {
        evals.iter().map(|e| e.loss).collect()
    } else {
        blocks.iter().map(|b| b.iter().sum()).collect()
    };
    HeldOutScores { per_seed, blocks }
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
    use usray_signal::Image;

    /// `k` images of `n` pixels, each `0.5 + σ·g` with `g` standard normal
    /// (Box–Muller on a 64-bit LCG, keyed by `key`), as held-out evaluations
    /// whose `loss` is the one-render pixel loss against `reference`.
    fn noisy(k: usize, n: usize, sigma: f64, key: u64, reference: &[f64]) -> Vec<Evaluation> {
        let mut state = key.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..k)
            .map(|_| {
                let data: Vec<f64> = (0..n)
                    .map(|_| {
                        let (u, v) = (uniform(), uniform());
                        0.5 + sigma * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
                    })
                    .collect();
                Evaluation {
                    loss: L1L2::default().value(&data, reference),
                    gradient: vec![],
                    image: Image {
                        nz: 1,
                        nx: n,
                        x_m: vec![0.0; n],
                        z_m: vec![0.0],
                        data,
                    },
                    demod_fc_part: vec![],
                    render_seconds: 0.0,
                }
            })
            .collect()
    }

    #[test]
    fn a_quieter_simulation_gains_less_in_the_energy_score() {
        // Two models with the reference's mean and Monte Carlo noise 0.10 and
        // 0.02 per pixel. One-render loss `E ℓ(s − R) = σ√(2/π) + σ²`; the
        // score `E ℓ(s − R) − ½ E ℓ(s − s')` keeps only the ℓ1 term's
        // `σ√(2/π)(1 − 1/√2)` (module docs): the quieter model's advantage
        // falls from 0.0736 to 0.0187 of a grey level.
        let n = 40_000;
        let reference = vec![0.5; n];
        let setup = LossSetup::default();
        let (loud, quiet) = (
            noisy(6, n, 0.10, 1, &reference),
            noisy(6, n, 0.02, 2, &reference),
        );
        let score = |e: &[Evaluation]| {
            let s = held_out_scores(&setup, &reference, e, 1000);
            let one: f64 = e.iter().map(|x| x.loss).sum::<f64>() / e.len() as f64;
            (s.per_seed.iter().sum::<f64>() / e.len() as f64, one)
        };
        let ((s_loud, l_loud), (s_quiet, l_quiet)) = (score(&loud), score(&quiet));
        let root = (2.0 / std::f64::consts::PI).sqrt();
        let one_render = 0.08 * root + (0.01 - 0.0004);
        let energy = 0.08 * root * (1.0 - std::f64::consts::FRAC_1_SQRT_2);
        // Standard error of a mean over 6·40 000 pixels of a loss whose spread
        // is about σ: under 3e-4; allow 5 of them.
        assert!(
            ((l_loud - l_quiet) - one_render).abs() < 1.5e-3,
            "{}",
            l_loud - l_quiet
        );
        assert!(
            ((s_loud - s_quiet) - energy).abs() < 1.5e-3,
            "{}",
            s_loud - s_quiet
        );
        // The blocks sum to each seed's score.
        let s = held_out_scores(&setup, &reference, &loud, 1000);
        for (b, v) in s.blocks.iter().zip(&s.per_seed) {
            assert_eq!(b.len(), 40);
            assert!((b.iter().sum::<f64>() - v).abs() < 1e-12);
        }
    }

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
