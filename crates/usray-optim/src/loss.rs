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
            sum += self.lambda1 * d.abs() + self.lambda2 * d * d;
            let sign = if d > 0.0 {
                1.0
            } else if d < 0.0 {
                -1.0
            } else {
                0.0
            };
            *g = (self.lambda1 * sign + 2.0 * self.lambda2 * d) / n;
        }
        sum / n
    }

    /// The loss alone.
    pub fn value(&self, image: &[f64], reference: &[f64]) -> f64 {
        let mut g = vec![0.0; image.len()];
        self.value_and_gradient(image, reference, &mut g)
    }
}
