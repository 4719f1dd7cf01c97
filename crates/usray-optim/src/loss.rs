//! Image losses with their gradients.

/// Weights of the paper's image loss (eq. weighted_l1_l2_loss).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct L1L2 {
    /// Weight `λ₁` of the ℓ1 term.
    pub lambda1: f64,
    /// Weight `λ₂` of the squared ℓ2 term.
    pub lambda2: f64,
}

impl Default for L1L2 {
    /// `λ₁ = λ₂ = 1`.
    fn default() -> Self {
        Self {
            lambda1: 1.0,
            lambda2: 1.0,
        }
    }
}

impl L1L2 {
    /// The pixel-normalised weighted ℓ1 + ℓ2 loss (paper eq. weighted_l1_l2_loss):
    ///
    /// `L = (1/N_pix) [ λ₁ Σ_u |I_u − R_u| + λ₂ Σ_u (I_u − R_u)² ]`
    ///
    /// and writes `∂L/∂I_u = (λ₁ sign(I_u − R_u) + 2 λ₂ (I_u − R_u)) / N_pix` into
    /// `grad` (sign 0 at 0, the subgradient the optimiser sees at an exact match).
    ///
    /// ```
    /// use usray_optim::L1L2;
    /// let mut g = [0.0; 2];
    /// let l = L1L2::default().value_and_gradient(&[0.5, 0.0], &[0.0, 0.0], &mut g);
    /// assert_eq!(l, (0.5 + 0.25) / 2.0);
    /// assert_eq!(g, [(1.0 + 1.0) / 2.0, 0.0]);
    /// ```
    ///
    /// # Panics
    /// If the three slices differ in length (a programming error, not bad input:
    /// image shapes are checked where images are read).
    pub fn value_and_gradient(&self, image: &[f64], reference: &[f64], grad: &mut [f64]) -> f64 {
        assert_eq!(
            image.len(),
            reference.len(),
            "image and reference sizes differ"
        );
        assert_eq!(image.len(), grad.len(), "image and gradient sizes differ");
        let n = image.len().max(1) as f64;
        let mut sum = 0.0;
        for ((g, &i), &r) in grad.iter_mut().zip(image).zip(reference) {
            let d = i - r;
            sum += self.pixel(d);
            *g = self.pixel_derivative(d) / n;
        }
        sum / n
    }

    /// The pixel loss `ℓ(d) = λ₁|d| + λ₂d²` of a residual `d`.
    fn pixel(&self, d: f64) -> f64 {
        self.lambda1 * d.abs() + self.lambda2 * d * d
    }

    /// `ℓ'(d) = λ₁ sign(d) + 2λ₂d`, with sign 0 at 0 (the subgradient the
    /// optimiser sees at an exact match).
    fn pixel_derivative(&self, d: f64) -> f64 {
        let sign = if d > 0.0 {
            1.0
        } else if d < 0.0 {
            -1.0
        } else {
            0.0
        };
        self.lambda1 * sign + 2.0 * self.lambda2 * d
    }

    /// The loss alone.
    pub fn value(&self, image: &[f64], reference: &[f64]) -> f64 {
        let mut g = vec![0.0; image.len()];
        self.value_and_gradient(image, reference, &mut g)
    }

    /// The loss of two images `a`, `b` of the same model rendered with
    /// independent seeds, in the form of the energy score (Gneiting & Raftery
    /// 2007, eq. 22) with the pixel loss `ℓ(d) = λ₁|d| + λ₂d²`:
    ///
    /// `L = (1/N_pix) Σ_u [ ½ℓ(a_u − R_u) + ½ℓ(b_u − R_u) − ½ℓ(a_u − b_u) ]`
    ///
    /// and its gradients `∂L/∂a`, `∂L/∂b` into `grad_a`, `grad_b`. Why: the
    /// one-render loss rewards a quieter simulation, `E(s − R)² = (E s − R)² +
    /// Var s`, so a fit at few rays drifts to parameters with less Monte Carlo
    /// noise (a smoother surface). Here the ℓ2 term is `λ₂ (a − R)(b − R)`,
    /// whose expectation over the two seeds is `λ₂ (E s − R)²` exactly; the ℓ1
    /// term, `E|s − R| − ½E|s − s'|`, still rewards a quieter simulation, but
    /// less: `0.23 σ` against the one-render loss's `0.80 σ` for a pixel of
    /// Gaussian noise `σ` with `E s = R` (it is a proper score: its expectation
    /// is least when the model's pixel distribution is the data's).
    ///
    /// ```
    /// use usray_optim::L1L2;
    /// let l2 = L1L2 { lambda1: 0.0, lambda2: 1.0 };
    /// let (a, b, r) = ([0.5, 0.2], [0.3, 0.0], [0.0, 0.1]);
    /// let (mut ga, mut gb) = ([0.0; 2], [0.0; 2]);
    /// let l = l2.paired_value_and_gradient(&a, &b, &r, &mut ga, &mut gb);
    /// // The ℓ2 term is the product of the two residuals.
    /// assert!((l - (0.5 * 0.3 + 0.1 * -0.1) / 2.0).abs() < 1e-15);
    /// assert!((ga[0] - 0.3 / 2.0).abs() < 1e-15 && (gb[0] - 0.5 / 2.0).abs() < 1e-15);
    /// ```
    ///
    /// # Panics
    /// If the five slices differ in length (a programming error).
    pub fn paired_value_and_gradient(
        &self,
        a: &[f64],
        b: &[f64],
        reference: &[f64],
        grad_a: &mut [f64],
        grad_b: &mut [f64],
    ) -> f64 {
        let n = a.len();
        assert!(
            [b.len(), reference.len(), grad_a.len(), grad_b.len()]
                .iter()
                .all(|&m| m == n),
            "paired loss: slices of different lengths"
        );
        let inv_n = 1.0 / n.max(1) as f64;
        let (ell, d_ell) = (|d| self.pixel(d), |d| self.pixel_derivative(d));
        let mut sum = 0.0;
        for u in 0..n {
            let (da, db, dab) = (a[u] - reference[u], b[u] - reference[u], a[u] - b[u]);
            sum += 0.5 * (ell(da) + ell(db) - ell(dab));
            grad_a[u] = 0.5 * (d_ell(da) - d_ell(dab)) * inv_n;
            grad_b[u] = 0.5 * (d_ell(db) + d_ell(dab)) * inv_n;
        }
        sum * inv_n
    }

    /// The paired loss alone ([`L1L2::paired_value_and_gradient`]).
    pub fn paired_value(&self, a: &[f64], b: &[f64], reference: &[f64]) -> f64 {
        let (mut ga, mut gb) = (vec![0.0; a.len()], vec![0.0; a.len()]);
        self.paired_value_and_gradient(a, b, reference, &mut ga, &mut gb)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paired loss's gradients against central differences, with both
    /// terms on and residuals away from the ℓ1 kinks.
    #[test]
    fn paired_gradient_matches_central_differences() {
        let loss = L1L2 {
            lambda1: 0.7,
            lambda2: 1.3,
        };
        let a = [0.31, -0.2, 0.05, 0.9];
        let b = [0.12, 0.4, -0.33, 0.6];
        let r = [0.0, 0.1, 0.2, 0.3];
        let (mut ga, mut gb) = ([0.0; 4], [0.0; 4]);
        loss.paired_value_and_gradient(&a, &b, &r, &mut ga, &mut gb);
        let h = 1e-6;
        for u in 0..4 {
            for (which, g) in [(0, ga[u]), (1, gb[u])] {
                let moved = |s: f64| {
                    let (mut x, mut y) = (a, b);
                    if which == 0 {
                        x[u] += s;
                    } else {
                        y[u] += s;
                    }
                    loss.paired_value(&x, &y, &r)
                };
                let fd = (moved(h) - moved(-h)) / (2.0 * h);
                assert!(
                    (fd - g).abs() < 1e-8,
                    "pixel {u}, image {which}: {g} vs FD {fd}"
                );
            }
        }
    }

    /// Equal images give the one-render loss; the paired loss is symmetric.
    #[test]
    fn paired_loss_of_equal_images_is_the_loss() {
        let loss = L1L2::default();
        let (a, b, r) = ([0.3, -0.1], [0.2, 0.4], [0.1, 0.0]);
        assert!((loss.paired_value(&a, &a, &r) - loss.value(&a, &r)).abs() < 1e-15);
        assert_eq!(loss.paired_value(&a, &b, &r), loss.paired_value(&b, &a, &r));
    }

    /// Two renders `a = μ + σε₁`, `b = μ + σε₂` of a model whose mean image `μ`
    /// lies a known distance from the reference: the paired ℓ2 loss estimates
    /// the squared distance `mean (μ − r)²` without the noise's `σ²` (within
    /// five of its standard errors, computed from the pixels), while the
    /// paired ℓ1 term of an exact model keeps the bias
    /// `(1 − 1/√2)·σ√(2/π)` (`E|ε| = σ√(2/π)`, `E|ε₁ − ε₂| = √2·E|ε|`):
    /// 29% of the one-render bias `E|ε|`, which still favours a quieter model.
    #[test]
    fn paired_l2_is_unbiased_and_paired_l1_is_not() {
        use crate::diagnosis::mean_and_se;
        use crate::test_noise::normal;
        let (n, sigma) = (200_000, 0.1);
        let e1: Vec<f64> = (0..n as u64).map(normal).collect();
        let e2: Vec<f64> = (n as u64..2 * n as u64).map(normal).collect();
        let mean_se = |terms: &[f64]| {
            let (m, se) = mean_and_se(terms);
            (m, se.unwrap())
        };
        let r: Vec<f64> = (0..n)
            .map(|u| 0.5 + 0.2 * ((u as f64) * 0.01).sin())
            .collect();
        let offset = |u: usize| 0.03 * ((u as f64) * 0.003).cos();
        let mu: Vec<f64> = (0..n).map(|u| r[u] + offset(u)).collect();
        let a: Vec<f64> = (0..n).map(|u| mu[u] + sigma * e1[u]).collect();
        let b: Vec<f64> = (0..n).map(|u| mu[u] + sigma * e2[u]).collect();
        let truth = (0..n).map(|u| offset(u).powi(2)).sum::<f64>() / n as f64;
        // Paired ℓ2, pixel by pixel: (a − r)(b − r).
        let terms: Vec<f64> = (0..n).map(|u| (a[u] - r[u]) * (b[u] - r[u])).collect();
        let (m, se) = mean_se(&terms);
        let l2 = L1L2 {
            lambda1: 0.0,
            lambda2: 1.0,
        };
        assert!((l2.paired_value(&a, &b, &r) - m).abs() < 1e-12);
        assert!(
            (m - truth).abs() < 5.0 * se,
            "paired ℓ2 {m} ± {se}, truth {truth}"
        );
        // The one-render ℓ2, `mean (a − r)²`, carries the noise's σ² on top.
        let terms: Vec<f64> = (0..n).map(|u| (a[u] - r[u]).powi(2)).collect();
        let (one, se) = mean_se(&terms);
        assert!((l2.value(&a, &r) - one).abs() < 1e-12);
        assert!(
            (one - truth - sigma * sigma).abs() < 5.0 * se,
            "one-render ℓ2 {one} ± {se}, truth {truth} + σ² {}",
            sigma * sigma
        );
        // The paired ℓ1 term on an exact model (μ = r).
        let l1 = L1L2 {
            lambda1: 1.0,
            lambda2: 0.0,
        };
        let terms: Vec<f64> = (0..n)
            .map(|u| {
                let (x, y) = (sigma * e1[u], sigma * e2[u]);
                0.5 * (x.abs() + y.abs() - (x - y).abs())
            })
            .collect();
        let (m, se) = mean_se(&terms);
        let bias = (1.0 - 0.5f64.sqrt()) * sigma * (2.0 / std::f64::consts::PI).sqrt();
        assert!(
            (m - bias).abs() < 5.0 * se,
            "paired ℓ1 {m} ± {se}, closed form {bias}"
        );
        assert!(m > 10.0 * se, "the paired ℓ1 bias is resolved: {m} ± {se}");
        let (ra, rb): (Vec<f64>, Vec<f64>) = (
            (0..n).map(|u| sigma * e1[u]).collect(),
            (0..n).map(|u| sigma * e2[u]).collect(),
        );
        assert!((l1.paired_value(&ra, &rb, &vec![0.0; n]) - m).abs() < 1e-12);
    }
}
