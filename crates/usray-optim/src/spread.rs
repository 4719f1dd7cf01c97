//! How well a fit determines its parameters: the spread of the fitted values that
//! the Monte Carlo noise of the images causes, by the fit's linearisation repeated
//! on independent noise realisations.
//!
//! Near its minimum the ℓ2 part of the image loss is a linear least-squares
//! problem in the parameters (Gauss–Newton; Bates & Watts 1988, *Nonlinear
//! Regression Analysis*, §2.1): with `J_uj = ∂I_u/∂θ_j` (pixels × parameters),
//! moving the data by a noise image `e` moves the fitted parameters by
//!
//! `δθ = (JᵀJ)⁻¹ Jᵀ e`.
//!
//! Monte Carlo noise is strongly correlated between neighbouring pixels (an echo
//! is many pixels wide), so the textbook `σ² (JᵀJ)⁻¹` of white noise understates
//! the spread. Instead `e` is *drawn*: each realisation is the difference of two
//! images of the same scene rendered with two independent seeds, whose
//! covariance `2Σ` is that of the measured data's noise plus the fit's own
//! render's noise when both have the simulation's noise `Σ` (blind data rendered
//! by usray at the same ray count). Over `m` realisations the covariance of the
//! fitted parameters is `(1/m) Σ_i δθ_i δθ_iᵀ`, each parameter's standard
//! deviation the root of its diagonal entry (relative standard error
//! ≈ `1/√(2m)`).
//!
//! For the paired loss ([`crate::Objective::pair_seeds`]) the fit's own noise is
//! the mean of its two renders', half the variance, so these realisations
//! overstate the spread by at most `√(4/3)` (15%).
//!
//! What this leaves out: the ℓ1 term of the loss (its curvature is not a
//! Gauss–Newton term), measured noise that differs from the simulation's (real
//! speckle is a fixed pattern, not noise), and any bias of the fit (an
//! unconverged refit, a model error).

use crate::objective::Objective;
use crate::OptimError;
use usray_transport::{RenderOptions, Scene};

/// Standard deviation of each of `obj`'s parameters at the fitted point
/// `params` ([`linearised_spread`]), from `image_s` and `image_held`, the images
/// at `params` rendered with the objective's seed `s` and with `s + 1`, and
/// `pairs − 1` more pairs of seeds (`s + 2, s + 3`, …). Renders one image per
/// parameter for the Jacobian (a forward difference of 1% of its range, into
/// the range, with the objective's seed) and `2 (pairs − 1)` for the noise.
///
/// # Errors
/// `pairs` of 0, images not on the objective's grid, or a failing render.
pub fn parameter_spread(
    obj: &Objective,
    params: &[f64],
    image_s: &[f64],
    image_held: &[f64],
    pairs: usize,
) -> Result<Vec<Option<f64>>, OptimError> {
    if pairs == 0 {
        return Err(OptimError::Diagnosis(
            "parameter spread: at least one pair of seeds is needed".into(),
        ));
    }
    // One render of `scene` with `seed` (a paired objective would render twice).
    let image_of = |scene: Scene, seed: u64| -> Result<Vec<f64>, OptimError> {
        let opts = RenderOptions {
            seed: Some(seed),
            ..obj.opts.clone()
        };
        Ok(Objective::new(scene, obj.reference.clone(), vec![], opts)?
            .value(&[])?
            .image
            .data)
    };
    let seed = obj.opts.seed.unwrap_or(obj.scene.acquisition.seed);
    // Jacobian columns by forward differences with common random numbers.
    let jacobian = obj
        .specs
        .iter()
        .enumerate()
        .map(|(j, spec)| {
            let width = spec.max - spec.min;
            let h = if params[j] + 0.01 * width > spec.max {
                -0.01 * width
            } else {
                0.01 * width
            };
            let mut moved = params.to_vec();
            moved[j] += h;
            let image = image_of(obj.scene_at(&moved)?, seed)?;
            Ok(image
                .iter()
                .zip(image_s)
                .map(|(a, b)| (a - b) / h)
                .collect::<Vec<f64>>())
        })
        .collect::<Result<Vec<_>, OptimError>>()?;
    // Noise realisations: differences of images of independent seeds.
    let fitted = obj.scene_at(params)?;
    let mut noise = vec![image_held
        .iter()
        .zip(image_s)
        .map(|(a, b)| a - b)
        .collect::<Vec<f64>>()];
    for p in 1..pairs as u64 {
        let a = image_of(fitted.clone(), seed.wrapping_add(2 * p))?;
        let b = image_of(fitted.clone(), seed.wrapping_add(2 * p + 1))?;
        noise.push(a.iter().zip(&b).map(|(x, y)| x - y).collect());
    }
    linearised_spread(&jacobian, &noise)
}

/// Standard deviation of each parameter from the Jacobian columns `jacobian[j]`
/// (`∂I/∂θ_j`, one value per pixel, in image units per unit of `θ_j`) and the
/// noise realisations `noise[i]` (one image each): the root mean square of the
/// linearised fits `δθ_i = (JᵀJ)⁻¹ Jᵀ e_i` (module docs). `None` for a
/// parameter the images do not determine: its column is zero, or a combination
/// of the others' (its squared distance from their span is below `1e-10` of its
/// squared norm). The other parameters' spreads stay those of the full model:
/// of a dependent set of columns, only the span counts.
///
/// ```
/// use usray_optim::linearised_spread;
/// // Two pixels, one parameter moving both by 1 per unit; two realisations.
/// let s = linearised_spread(&[vec![1.0, 1.0]], &[vec![0.2, 0.0], vec![0.0, -0.2]])?;
/// // δθ = (e₁ + e₂)/2 = ±0.1 in both realisations.
/// assert!((s[0].unwrap() - 0.1).abs() < 1e-12);
/// // A parameter the image does not see is not determined.
/// let s = linearised_spread(&[vec![1.0, 1.0], vec![0.0, 0.0]], &[vec![0.2, 0.0]])?;
/// assert!(s[0].is_some() && s[1].is_none());
/// # Ok::<(), usray_optim::OptimError>(())
/// ```
///
/// # Errors
/// No realisation, or columns and realisations of different lengths.
pub fn linearised_spread(
    jacobian: &[Vec<f64>],
    noise: &[Vec<f64>],
) -> Result<Vec<Option<f64>>, OptimError> {
    let k = jacobian.len();
    let n = jacobian.first().map_or(0, Vec::len);
    if noise.is_empty() {
        return Err(OptimError::Diagnosis(
            "parameter spread: no noise realisation".into(),
        ));
    }
    if jacobian.iter().chain(noise).any(|v| v.len() != n) {
        return Err(OptimError::Diagnosis(format!(
            "parameter spread: Jacobian columns and noise images must all have {n} pixels"
        )));
    }
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    // Normal matrix `JᵀJ` and the right-hand sides `Jᵀe_i`, once.
    let gram: Vec<Vec<f64>> = jacobian
        .iter()
        .map(|a| jacobian.iter().map(|b| dot(a, b)).collect())
        .collect();
    let rhs: Vec<Vec<f64>> = noise
        .iter()
        .map(|e| jacobian.iter().map(|a| dot(a, e)).collect())
        .collect();
    Ok((0..k)
        .map(|j| {
            // Parameter j last, after a basis of the others' span: its pivot is
            // its squared distance from that span, and the last component of
            // the solve is its δθ in the full model.
            let order: Vec<usize> = (0..k).filter(|&i| i != j).chain([j]).collect();
            let (factor, kept) = cholesky_of_independent(&gram, &order);
            if kept.last() != Some(&j) {
                return None;
            }
            let sum_sq: f64 = rhs
                .iter()
                .map(|r| {
                    let b: Vec<f64> = kept.iter().map(|&i| r[i]).collect();
                    cholesky_solve(&factor, &b).last().map_or(0.0, |d| d * d)
                })
                .sum();
            Some((sum_sq / noise.len() as f64).sqrt())
        })
        .collect())
}

/// Lower Cholesky factor of `gram` over the parameters of `order` (in that
/// order) whose columns are independent of those kept before them (pivot at
/// least `1e-10` of the diagonal), with the indices kept.
fn cholesky_of_independent(gram: &[Vec<f64>], order: &[usize]) -> (Vec<Vec<f64>>, Vec<usize>) {
    let mut kept: Vec<usize> = Vec::new();
    let mut l: Vec<Vec<f64>> = Vec::new();
    for &j in order {
        let mut row: Vec<f64> = Vec::with_capacity(kept.len() + 1);
        for (r, &i) in kept.iter().enumerate() {
            let s: f64 = (0..r).map(|c| row[c] * l[r][c]).sum();
            row.push((gram[j][i] - s) / l[r][r]);
        }
        let pivot = gram[j][j] - row.iter().map(|x| x * x).sum::<f64>();
        if gram[j][j] > 0.0 && pivot > 1e-10 * gram[j][j] {
            row.push(pivot.sqrt());
            l.push(row);
            kept.push(j);
        }
    }
    (l, kept)
}

/// Solves `L Lᵀ x = b` for a lower-triangular `l`.
fn cholesky_solve(l: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
    let n = b.len();
    let mut y = vec![0.0; n];
    for i in 0..n {
        let s: f64 = (0..i).map(|c| l[i][c] * y[c]).sum();
        y[i] = (b[i] - s) / l[i][i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|r| l[r][i] * x[r]).sum();
        x[i] = (y[i] - s) / l[i][i];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_noise::normal;

    /// Linear model with white noise of variance σ²: the covariance of the
    /// least-squares estimate is `σ² (JᵀJ)⁻¹` (Bates & Watts eq. 1.6). The
    /// estimated variances must match it within 4 standard errors of a
    /// mean of `m` squared normals (`√(2/m)` relative).
    #[test]
    fn white_noise_gives_the_textbook_covariance() {
        let n = 400;
        // Two correlated columns: a ramp and a ramp plus a bump.
        let a: Vec<f64> = (0..n).map(|u| u as f64 / n as f64).collect();
        let b: Vec<f64> = (0..n)
            .map(|u| a[u] + (-((u as f64 - 200.0) / 30.0).powi(2)).exp())
            .collect();
        let sigma = 0.3;
        let m = 400;
        let noise: Vec<Vec<f64>> = (0..m)
            .map(|i| (0..n).map(|u| sigma * normal((i * n + u) as u64)).collect())
            .collect();
        let s = linearised_spread(&[a.clone(), b.clone()], &noise).unwrap();
        // (JᵀJ)⁻¹ of the 2×2 normal matrix in closed form.
        let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
        let (aa, ab, bb) = (dot(&a, &a), dot(&a, &b), dot(&b, &b));
        let det = aa * bb - ab * ab;
        let var = [sigma * sigma * bb / det, sigma * sigma * aa / det];
        let rel = 4.0 * (2.0 / m as f64).sqrt();
        for (j, v) in var.iter().enumerate() {
            let got = s[j].unwrap().powi(2);
            assert!(
                (got / v - 1.0).abs() < rel,
                "parameter {j}: variance {got:.4e} against {v:.4e} (±{rel:.2} relative)"
            );
        }
    }

    /// Noise correlated over a few pixels spreads a parameter more than white
    /// noise of the same pixel variance; the realisations capture it where the
    /// white-noise formula does not.
    #[test]
    fn correlated_noise_spreads_more_than_white() {
        let n = 400;
        let col: Vec<f64> = (0..n).map(|u| (u as f64 / 40.0).sin()).collect();
        let m = 300;
        let white: Vec<Vec<f64>> = (0..m)
            .map(|i| (0..n).map(|u| normal((i * n + u) as u64)).collect())
            .collect();
        // Moving average over 8 pixels, scaled back to unit pixel variance.
        let smooth: Vec<Vec<f64>> = white
            .iter()
            .map(|w| {
                (0..n)
                    .map(|u| (u..u + 8).map(|v| w[v % n]).sum::<f64>() / 8f64.sqrt())
                    .collect()
            })
            .collect();
        let sw = linearised_spread(std::slice::from_ref(&col), &white).unwrap()[0].unwrap();
        let sc = linearised_spread(&[col], &smooth).unwrap()[0].unwrap();
        // For a slowly varying column the spread grows by about √8.
        let ratio = sc / sw;
        assert!(
            ratio > 2.0 && ratio < 3.6,
            "correlated/white spread ratio {ratio:.2}"
        );
    }

    #[test]
    fn mismatched_lengths_and_no_noise_are_errors() {
        assert!(linearised_spread(&[vec![1.0, 2.0]], &[vec![1.0]]).is_err());
        assert!(linearised_spread(&[vec![1.0, 2.0]], &[]).is_err());
    }

    #[test]
    fn repeated_columns_are_undetermined_and_the_others_are_not() {
        let c = vec![1.0, 2.0, 3.0];
        let other = vec![1.0, 0.0, -1.0];
        let s = linearised_spread(&[c.clone(), other, c], &[vec![0.1, -0.1, 0.2]]).unwrap();
        // Neither copy is determined; the third column still is.
        assert!(s[0].is_none() && s[2].is_none() && s[1].is_some());
    }
}
