//! Step 4's statistics: the held-out renders (seeds the fits have not seen),
//! the losses on them, and means with standard errors over the seeds.

use super::calibration::LossSetup;
use crate::objective::Evaluation;
use crate::OptimError;
use usray_transport::{RenderOptions, Scene};

/// Distance between the seeds of successive held-out renders ([`held_out_seed`]):
/// far from the calibration's seed `s`, from the spreads' `s … s + 2·spread_pairs`
/// and from the paired loss's second seeds (`+ 2³²`).
const HELD_OUT_SEED_STRIDE: u64 = 1 << 33;

/// Seed of the `j`-th held-out render of a diagnosis whose fits use seed `s`:
/// `s + 1` first (the seed the spreads' first noise realisation also uses),
/// then 2³³ apart: far from the spreads' seeds `s … s + 2·spread_pairs` and
/// from the paired loss's second seeds (`+ 2³²`).
///
/// ```
/// use usray_optim::held_out_seed;
/// assert_eq!(held_out_seed(7, 0), 8);
/// assert_eq!(held_out_seed(7, 2), 8 + 2 * (1 << 33));
/// ```
pub fn held_out_seed(s: u64, j: usize) -> u64 {
    s.wrapping_add(1)
        .wrapping_add((j as u64).wrapping_mul(HELD_OUT_SEED_STRIDE))
}

/// `scene`'s loss against `measured` on each held-out render (no free
/// parameters; the loss taken as `setup` says).
pub(crate) fn held_out(
    scene: &Scene,
    measured: &[f64],
    renders: &[RenderOptions],
    setup: &LossSetup,
) -> Result<Vec<Evaluation>, OptimError> {
    renders
        .iter()
        .map(|r| {
            setup
                .objective(scene.clone(), measured, vec![], r)?
                .value(&[])
        })
        .collect()
}

/// Arithmetic mean (0 for none).
pub(crate) fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// Mean of per-seed values and its standard error `sd/√K` (`None` for one).
///
/// ```
/// let (m, se) = usray_optim::mean_and_se(&[1.0, 2.0, 3.0]);
/// assert_eq!(m, 2.0);
/// assert!((se.unwrap() - (1.0f64 / 3.0).sqrt()).abs() < 1e-15);
/// ```
pub fn mean_and_se(v: &[f64]) -> (f64, Option<f64>) {
    let m = mean(v);
    let se = (v.len() > 1).then(|| {
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
        (var / v.len() as f64).sqrt()
    });
    (m, se)
}

/// Mean loss of several held-out evaluations.
pub(crate) fn mean_loss(evals: &[Evaluation]) -> f64 {
    mean(&evals.iter().map(|e| e.loss).collect::<Vec<_>>())
}

/// Per-seed differences `(a_j − b_j) / scale`: the shrink of losses `b`
/// relative to `a` seed by seed (common random numbers: each held-out seed
/// renders every model), in units of `scale` (the calibrated held-out loss).
pub(crate) fn relative_differences(a: &[f64], b: &[f64], scale: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| (x - y) / scale).collect()
}
