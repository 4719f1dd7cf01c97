//! Adam with parameter groups and gradient clipping.
//!
//! Kingma & Ba (2015), "Adam: A Method for Stochastic Optimization", Algorithm 1;
//! the paper's eq. adam with standard bias corrections. Groups let material
//! parameters (roughness, impedance) and acquisition parameters (pitch, frequency)
//! move at different learning rates (paper §"Optimization procedure").

/// Adam's settings for one parameter group.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdamGroup {
    /// Learning rate `η`, in units of the normalised state (a fraction of each
    /// parameter's range per step).
    pub learning_rate: f64,
    /// `β₁`, decay of the first moment.
    pub beta1: f64,
    /// `β₂`, decay of the second moment.
    pub beta2: f64,
    /// `ε` in the denominator.
    pub epsilon: f64,
}

impl Default for AdamGroup {
    /// `η = 0.02`, `β₁ = 0.9`, `β₂ = 0.999`, `ε = 1e-8`.
    fn default() -> Self {
        Self {
            learning_rate: 0.02,
            beta1: 0.9,
            beta2: 0.999,
            epsilon: 1e-8,
        }
    }
}

/// What [`Adam::state`] exports: first and second moments, updates taken, and
/// the clip norm.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AdamState {
    /// First moments `m`.
    pub m: Vec<f64>,
    /// Second moments `v`.
    pub v: Vec<f64>,
    /// Updates taken.
    pub step: i32,
    /// The clip norm in force.
    pub clip_norm: Option<f64>,
}

/// The Adam optimiser over a state vector whose entries belong to groups.
#[derive(Clone, Debug, PartialEq)]
pub struct Adam {
    /// The groups' settings.
    pub groups: Vec<AdamGroup>,
    /// For each state entry, the index of its group.
    pub group_of: Vec<usize>,
    /// Clip the gradient to this global ℓ2 norm before the update (`None`: no clipping).
    pub clip_norm: Option<f64>,
    m: Vec<f64>,
    v: Vec<f64>,
    step: i32,
}

impl Adam {
    /// Adam over `group_of.len()` entries.
    ///
    /// # Panics
    /// If a group index is out of range.
    ///
    /// ```
    /// use usray_optim::{Adam, AdamGroup};
    /// // Minimise (x − 3)²: the gradient is 2(x − 3).
    /// let mut adam = Adam::new(vec![AdamGroup { learning_rate: 0.1, ..Default::default() }], vec![0]);
    /// let mut x = [0.0];
    /// for _ in 0..500 {
    ///     let g = [2.0 * (x[0] - 3.0)];
    ///     adam.step(&mut x, &g);
    /// }
    /// assert!((x[0] - 3.0).abs() < 1e-2);
    /// ```
    pub fn new(groups: Vec<AdamGroup>, group_of: Vec<usize>) -> Self {
        assert!(
            group_of.iter().all(|&g| g < groups.len()),
            "a parameter names a group that does not exist"
        );
        let n = group_of.len();
        Self {
            groups,
            group_of,
            clip_norm: None,
            m: vec![0.0; n],
            v: vec![0.0; n],
            step: 0,
        }
    }

    /// The moments, step count and clip norm: what a checkpoint keeps to
    /// continue the same sequence of updates ([`Adam::restore`]).
    pub fn state(&self) -> AdamState {
        AdamState {
            m: self.m.clone(),
            v: self.v.clone(),
            step: self.step,
            clip_norm: self.clip_norm,
        }
    }

    /// Continues from a kept [`AdamState`].
    ///
    /// # Errors
    /// When its length is not this optimiser's.
    pub fn restore(&mut self, s: &AdamState) -> Result<(), String> {
        if s.m.len() != self.m.len() || s.v.len() != self.v.len() {
            return Err(format!(
                "the kept optimiser state has {} entries, this fit {}",
                s.m.len(),
                self.m.len()
            ));
        }
        self.m.clone_from(&s.m);
        self.v.clone_from(&s.v);
        self.step = s.step;
        self.clip_norm = s.clip_norm;
        Ok(())
    }

    /// Number of updates taken so far.
    pub fn steps_taken(&self) -> i32 {
        self.step
    }

    /// One update of `state` from `gradient` (clipped first if `clip_norm` is set).
    /// Returns the gradient norm before clipping.
    pub fn step(&mut self, state: &mut [f64], gradient: &[f64]) -> f64 {
        let norm = gradient.iter().map(|g| g * g).sum::<f64>().sqrt();
        let scale = match self.clip_norm {
            Some(c) if norm > c && norm > 0.0 => c / norm,
            _ => 1.0,
        };
        self.step += 1;
        for j in 0..state.len() {
            let grp = self.groups[self.group_of[j]];
            let g = gradient[j] * scale;
            self.m[j] = grp.beta1 * self.m[j] + (1.0 - grp.beta1) * g;
            self.v[j] = grp.beta2 * self.v[j] + (1.0 - grp.beta2) * g * g;
            let m_hat = self.m[j] / (1.0 - grp.beta1.powi(self.step));
            let v_hat = self.v[j] / (1.0 - grp.beta2.powi(self.step));
            state[j] -= grp.learning_rate * m_hat / (v_hat.sqrt() + grp.epsilon);
        }
        norm
    }
}
