//! The calibration objective: scene parameters → render → B-mode → image loss, with
//! its gradient through the whole pipeline (paper §"End-to-end objective",
//! eq. chain rule `∂L/∂θ = (∂P/∂θ)ᵀ (∂I/∂P)ᵀ ∂L/∂I`).
//!
//! One evaluation at physical parameters `θ`:
//! 1. set `θ` in a copy of the scene, render channel data `P(θ)` in `f64` with the
//!    objective's fixed [`RenderOptions`] (seed: common random numbers);
//! 2. form the B-mode `I = B(P)` on the scene's `[imaging]` grid
//!    ([`usray_signal::BMode`]);
//! 3. loss `L(C(I), C(I_ref))` and `∂L/∂I` (paper eq. `weighted_l1_l2_loss`), with
//!    `C` the [`Objective::comparison`] (smoothing and noise floor, the identity
//!    unless set: [`Comparison`]) and `∂L/∂I` pulled back through it;
//! 4. `∂L/∂P = Bᵀ ∂L/∂I` ([`usray_signal::BMode::vjp`], paper eq. `l2_backprop`);
//! 5. transport part `Σ ∂L/∂P · ∂P/∂θ_j` by path replay with the same random
//!    numbers ([`PathReplay`], behind the [`TransportGradient`] trait);
//! 6. image-formation parts, for parameters the beamformer also reads:
//!    - the beamformer's sound speed (`imaging.sound_speed_m_s`, or
//!      `medium.sound_speed_m_s` when the scene has no `imaging.sound_speed_m_s`,
//!      since the beamformer then assumes the medium's): `+ d_sound_speed` of
//!      [`usray_signal::BMode::calibration_vjp`];
//!    - `probe.pitch_m` (element positions of delay-and-sum): `+ d_pitch`;
//!    - `probe.center_frequency_hz` (IQ mixing phases, low-pass cut-off and the
//!      delay-and-sum's phase rotation): `+` [`usray_signal::BMode::center_frequency_vjp`],
//!      the exact derivative of `L(B_fc(P))` in `f_c` with the channel data `P`
//!      held (forward duals through the demodulation, the rotation from the
//!      delay-and-sum's delays). [`Evaluation::demod_fc_part`] reports it.
//!
//! **Paired loss** ([`Objective::paired_seed`], [`Objective::pair_seeds`]): steps 1–6
//! run for two independent seeds, the loss is
//! [`L1L2::paired_value_and_gradient`] of the two images (its ℓ2 term is
//! `λ₂ (I_a − R)(I_b − R)`, unbiased in the simulation's Monte Carlo variance), and
//! the two renders' gradients add.
//!
//! **Fixed-seed semantics.** The gradient is that of the sampled estimator with
//! common random numbers: the seed and ray budget are fixed, sampling decisions are
//! held, and visibility changes (a ray that stops hitting the object) carry no
//! derivative. Finite differences of the same fixed-seed pipeline
//! ([`Objective::value`]) are the reference it is checked against.

use crate::comparison::Comparison;
use crate::loss::L1L2;
use crate::params::ParamSpec;
use crate::OptimError;
use usray_signal::{BMode, ChannelData, Image};
use usray_transport::scene::ImagingRole;
use usray_transport::{render, ParamKey, RenderOptions, Scene, SceneError};

/// The transport part of the gradient: for each named parameter,
/// `Σ_samples d_channels · ∂P/∂θ_j` of the fixed-seed render of `scene` under `opts`.
///
/// Parameters only the image formation reads contribute 0 here.
pub trait TransportGradient: Send + Sync {
    /// `∂L/∂θ_j = Σ d_channels · ∂P/∂θ_j` for each parameter in `params`.
    fn channel_gradient(
        &self,
        scene: &Scene,
        params: &[ParamKey],
        d_channels: &[f64],
        opts: &RenderOptions,
    ) -> Result<Vec<f64>, SceneError>;
}

/// The transport crate's gradient by path replay with the same random numbers
/// ([`usray_transport::channel_gradient`]: forward duals for a few parameters,
/// per-path reverse tapes for many, chosen by the library; memory independent of
/// the ray count). Used by [`Objective::new`].
#[derive(Clone, Copy, Debug, Default)]
pub struct PathReplay;

impl TransportGradient for PathReplay {
    fn channel_gradient(
        &self,
        scene: &Scene,
        params: &[ParamKey],
        d_channels: &[f64],
        opts: &RenderOptions,
    ) -> Result<Vec<f64>, SceneError> {
        usray_transport::channel_gradient(scene, params, d_channels, opts)
    }
}

/// A check, not AD: central finite difference of the fixed-seed channel data,
/// `Σ d_channels · (P(θ_j + h) − P(θ_j − h)) / 2h` with `h = 10⁻⁶·|θ_j|`, two `f64`
/// renders per parameter (the stand-in used before the transport's replay landed).
#[derive(Clone, Copy, Debug, Default)]
pub struct FdChannels;

impl TransportGradient for FdChannels {
    fn channel_gradient(
        &self,
        scene: &Scene,
        params: &[ParamKey],
        d_channels: &[f64],
        opts: &RenderOptions,
    ) -> Result<Vec<f64>, SceneError> {
        params
            .iter()
            .map(|p| {
                let v = scene.get(p)?;
                let h = 1e-6 * v.abs().max(1e-12);
                let mut a = scene.clone();
                a.set(p, v + h)?;
                let mut b = scene.clone();
                b.set(p, v - h)?;
                let (pa, _) = render(&a, opts)?;
                let (pb, _) = render(&b, opts)?;
                Ok(dot_records(&pa, &pb, d_channels) / (2.0 * h))
            })
            .collect()
    }
}

/// `Σ d · (a − b)` record by record; records of different lengths (the sample grid
/// depends on pitch and speeds) are compared over their common prefix (the tails
/// are past the last echo).
fn dot_records(a: &ChannelData, b: &ChannelData, d: &[f64]) -> f64 {
    let n_rec = a.n_transmits() * a.n_elements();
    let ns_d = d.len().checked_div(n_rec).unwrap_or(0);
    let n = ns_d.min(a.n_samples).min(b.n_samples);
    let mut sum = 0.0;
    for r in 0..n_rec {
        let (ra, rb, rd) = (
            &a.samples[r * a.n_samples..],
            &b.samples[r * b.n_samples..],
            &d[r * ns_d..],
        );
        for k in 0..n {
            sum += rd[k] * (ra[k] - rb[k]);
        }
    }
    sum
}

/// The result of one evaluation of the objective.
#[derive(Clone, Debug)]
pub struct Evaluation {
    /// The loss `L`.
    pub loss: f64,
    /// `∂L/∂θ` in physical units, one per parameter (empty for [`Objective::value`]).
    pub gradient: Vec<f64>,
    /// The simulated B-mode at `θ` (for a paired loss, the first seed's).
    pub image: Image,
    /// For each parameter, the part of the gradient from the image formation's
    /// centre frequency with the channel data held (IQ demodulation and the
    /// delay-and-sum's rotation; non-zero only for `probe.center_frequency_hz`).
    pub demod_fc_part: Vec<f64>,
    /// Render wall time, seconds.
    pub render_seconds: f64,
}

/// Scene + reference image + parameters + loss + render options: the function the
/// fit minimises (see the module docs for the chain rule).
pub struct Objective {
    /// The scene; parameter values not being fitted are taken from it.
    pub scene: Scene,
    /// The reference B-mode `I_ref`, `[nz, nx]` row-major on the scene's grid.
    pub reference: Vec<f64>,
    /// The parameters, in order.
    pub specs: Vec<ParamSpec>,
    /// The image loss.
    pub loss: L1L2,
    /// How the simulated image is compared with the reference before the loss
    /// (smoothing and noise floor, [`Comparison`]); the identity by default.
    pub comparison: Comparison,
    /// Render options (ray count, seed, threads): fixed across evaluations, so
    /// every evaluation uses common random numbers.
    pub opts: RenderOptions,
    /// Transmit micro-batches for the transport replay (see
    /// [`Objective::value_and_gradient`]); empty = one batch of every transmit.
    pub transmit_batches: Vec<Vec<usize>>,
    /// A second, independent seed: when set, every evaluation renders the scene
    /// with both seeds and uses [`L1L2::paired_value_and_gradient`], the loss
    /// whose ℓ2 term is unbiased in the simulation's Monte Carlo variance (twice
    /// the renders). `None` (the default): the paper's loss on one render.
    pub paired_seed: Option<u64>,
    transport: Box<dyn TransportGradient>,
    /// The part of the image formation each parameter also enters.
    roles: Vec<Option<ImagingRole>>,
}

impl std::fmt::Debug for Objective {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Objective")
            .field("specs", &self.specs)
            .field("loss", &self.loss)
            .field("opts", &self.opts)
            .finish_non_exhaustive()
    }
}

impl Objective {
    /// An objective on `scene` against `reference` (`[nz, nx]` on the scene's
    /// imaging grid) for `specs`, using the transport's path-replay gradient.
    ///
    /// # Errors
    /// An unknown parameter path, or a reference whose length is not the scene's
    /// grid `nz·nx`.
    pub fn new(
        scene: Scene,
        reference: Vec<f64>,
        specs: Vec<ParamSpec>,
        opts: RenderOptions,
    ) -> Result<Self, OptimError> {
        Self::with_transport(scene, reference, specs, opts, Box::new(PathReplay))
    }

    /// [`Objective::new`] with another transport gradient (tests, checks).
    pub fn with_transport(
        scene: Scene,
        reference: Vec<f64>,
        specs: Vec<ParamSpec>,
        opts: RenderOptions,
        transport: Box<dyn TransportGradient>,
    ) -> Result<Self, OptimError> {
        opts.check(&scene)?;
        for s in &specs {
            scene.get(&s.key)?;
        }
        let (nz, nx) = grid_shape(&scene)?;
        if reference.len() != nz * nx {
            return Err(OptimError::Reference(format!(
                "the reference has {} pixels but the scene's imaging grid is {nz} × {nx} = {}",
                reference.len(),
                nz * nx
            )));
        }
        let roles = specs.iter().map(|s| s.key.imaging_role(&scene)).collect();
        Ok(Self {
            scene,
            reference,
            specs,
            loss: L1L2::default(),
            comparison: Comparison::identity(),
            opts,
            transmit_batches: Vec::new(),
            paired_seed: None,
            transport,
            roles,
        })
    }

    /// The parameters' current values in the scene.
    pub fn initial_physical(&self) -> Vec<f64> {
        self.specs
            .iter()
            .map(|s| self.scene.get(&s.key).unwrap_or(f64::NAN))
            .collect()
    }

    /// The image grid shape `(nz, nx)`.
    pub fn shape(&self) -> Result<(usize, usize), OptimError> {
        grid_shape(&self.scene)
    }

    /// The scene with the parameters set to `physical`.
    pub fn scene_at(&self, physical: &[f64]) -> Result<Scene, OptimError> {
        let mut scene = self.scene.clone();
        let values: Vec<(&ParamKey, f64)> = self
            .specs
            .iter()
            .zip(physical)
            .map(|(s, &v)| (&s.key, v))
            .collect();
        // Coupled bounds (a wall thinner than its radius) are projected: a step
        // of the optimiser that crosses one is not a fault of the user's scene.
        scene.set_projected(&values).map_err(|e| {
            OptimError::Step(format!(
                "the fitted parameters {values:?} leave the scene's valid region ({e}); \
                 narrow their ranges"
            ))
        })?;
        Ok(scene)
    }

    /// Channel data and B-mode of the scene at `physical`, plus the operator and its
    /// workspace after the forward pass.
    fn forward(
        &self,
        scene: &Scene,
        opts: &RenderOptions,
    ) -> Result<(ChannelData, BMode, usray_signal::Workspace, Image, f64), OptimError> {
        let (ch, stats) = render(scene, opts)?;
        let op = BMode::new(&scene.imaging_settings(), &ch.meta, ch.n_samples)?;
        let mut ws = op.workspace();
        let image = op.forward(&ch, &mut ws)?;
        Ok((ch, op, ws, image, stats.seconds))
    }

    /// The loss alone at `physical` (the fixed-seed pipeline that finite differences
    /// check the gradient against).
    pub fn value(&self, physical: &[f64]) -> Result<Evaluation, OptimError> {
        let scene = self.scene_at(physical)?;
        let (_, _, _, image, mut secs) = self.forward(&scene, &self.opts)?;
        let loss = match self.paired_opts() {
            None => self.image_loss(&image, None),
            Some(paired) => {
                let (_, _, _, other, s) = self.forward(&scene, &paired)?;
                secs += s;
                self.image_loss(&image, Some(&other))
            }
        };
        Ok(Evaluation {
            loss,
            gradient: Vec::new(),
            image,
            demod_fc_part: Vec::new(),
            render_seconds: secs,
        })
    }

    /// Loss and `∂L/∂θ` (physical units) at `physical`: the chain of the module
    /// docs. With [`Objective::transmit_batches`] set, the transport replay runs once
    /// per batch of transmits with `∂L/∂P` restricted to that batch's records and
    /// the parts are summed: `∂L/∂θ = Σ_b Σ_{tx∈b} ∂L/∂P_tx · ∂P_tx/∂θ`, exact for
    /// a deterministic split (the image and loss are always of the full compounded
    /// acquisition: the B-mode is nonlinear in the coherent sum over transmits, so
    /// image losses do not split over angles).
    pub fn value_and_gradient(&self, physical: &[f64]) -> Result<Evaluation, OptimError> {
        let scene = self.scene_at(physical)?;
        let (ch, op, mut ws, image, mut secs) = self.forward(&scene, &self.opts)?;
        // The paired loss's second render, with its options.
        let mut second = match self.paired_opts() {
            Some(o) => Some((self.forward(&scene, &o)?, o)),
            None => None,
        };
        let (loss, d_image, d_image_b) = match &second {
            None => self.image_loss_and_gradient(&image, None),
            Some(((_, _, _, image_b, s), _)) => {
                secs += s;
                self.image_loss_and_gradient(&image, Some(image_b))
            }
        };
        let (mut gradient, mut demod_fc_part) =
            self.backward(&scene, &self.opts, &ch, &op, &mut ws, &d_image)?;
        // Each render carries its own part of the gradient.
        if let Some(((ch_b, op_b, ws_b, _, _), o)) = &mut second {
            let (g_b, d_b) = self.backward(&scene, o, ch_b, op_b, ws_b, &d_image_b)?;
            for (g, p) in gradient.iter_mut().zip(g_b) {
                *g += p;
            }
            for (g, p) in demod_fc_part.iter_mut().zip(d_b) {
                *g += p;
            }
        }
        Ok(Evaluation {
            loss,
            gradient,
            image,
            demod_fc_part,
            render_seconds: secs,
        })
    }

    /// This objective, comparing images through `comparison`.
    #[must_use]
    pub fn with_comparison(mut self, comparison: Comparison) -> Self {
        self.comparison = comparison;
        self
    }

    /// An image as the loss sees it: through [`Objective::comparison`].
    #[must_use]
    pub fn compared(&self, image: &Image) -> Vec<f64> {
        if self.comparison.is_identity() {
            return image.data.clone();
        }
        self.comparison.apply(&image.data, image.nz, image.nx)
    }

    /// The loss of two images of the same grid through the comparison: `a`
    /// in the place of the simulation, `b` in the reference's (the noise level
    /// compares a simulation with another seed's).
    #[must_use]
    pub fn loss_between(&self, a: &Image, b: &Image) -> f64 {
        self.loss.value(&self.compared(a), &self.compared(b))
    }

    /// The reference through the comparison.
    fn compared_reference(&self, nz: usize, nx: usize) -> Vec<f64> {
        if self.comparison.is_identity() {
            return self.reference.clone();
        }
        self.comparison.apply(&self.reference, nz, nx)
    }

    /// The loss of `image` (and, for a paired loss, of the second seed's
    /// `paired`) against the reference, both through the comparison.
    fn image_loss(&self, image: &Image, paired: Option<&Image>) -> f64 {
        let reference = self.compared_reference(image.nz, image.nx);
        match paired {
            None => self.loss.value(&self.compared(image), &reference),
            Some(b) => self
                .loss
                .paired_value(&self.compared(image), &self.compared(b), &reference),
        }
    }

    /// [`Objective::image_loss`] with `∂L/∂I` of each image (the second is
    /// empty without a paired image), pulled back through the comparison.
    fn image_loss_and_gradient(
        &self,
        image: &Image,
        paired: Option<&Image>,
    ) -> (f64, Vec<f64>, Vec<f64>) {
        let (nz, nx) = (image.nz, image.nx);
        let reference = self.compared_reference(nz, nx);
        let a = self.compared(image);
        let mut d_a = vec![0.0; a.len()];
        let (loss, d_b) = match paired {
            None => (
                self.loss.value_and_gradient(&a, &reference, &mut d_a),
                Vec::new(),
            ),
            Some(b_image) => {
                let b = self.compared(b_image);
                let mut d_b = vec![0.0; b.len()];
                let l = self
                    .loss
                    .paired_value_and_gradient(&a, &b, &reference, &mut d_a, &mut d_b);
                (l, d_b)
            }
        };
        if self.comparison.is_identity() {
            return (loss, d_a, d_b);
        }
        let d_a = self.comparison.pullback(&image.data, nz, nx, &d_a);
        let d_b = match paired {
            Some(b_image) => self.comparison.pullback(&b_image.data, nz, nx, &d_b),
            None => d_b,
        };
        (loss, d_a, d_b)
    }

    /// Sets [`Objective::paired_seed`] to the render seed plus
    /// [`PAIRED_SEED_OFFSET`]: the paired loss, with a second seed independent
    /// of the first (and of the seeds `s + k` that held-out renders and
    /// resampled fits use).
    ///
    /// ```
    /// use usray_optim::{Objective, PAIRED_SEED_OFFSET};
    /// use usray_transport::{RenderOptions, Scene};
    /// let scene = Scene::from_toml_str(include_str!("../../../scenes/cylinder.toml"), "cylinder.toml", ".")?;
    /// let (nz, nx) = usray_optim::grid_shape(&scene)?;
    /// let opts = RenderOptions { seed: Some(5), ..Default::default() };
    /// let mut obj = Objective::new(scene, vec![0.0; nz * nx], vec![], opts)?;
    /// obj.pair_seeds();
    /// assert_eq!(obj.paired_seed, Some(5 + PAIRED_SEED_OFFSET));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn pair_seeds(&mut self) {
        let seed = self.opts.seed.unwrap_or(self.scene.acquisition.seed);
        self.paired_seed = Some(seed.wrapping_add(PAIRED_SEED_OFFSET));
    }

    /// This objective, with the paired loss ([`Objective::pair_seeds`]) when
    /// `paired`.
    #[must_use]
    pub fn with_pairing(mut self, paired: bool) -> Self {
        if paired {
            self.pair_seeds();
        }
        self
    }

    /// The render options of the paired seed, if any.
    fn paired_opts(&self) -> Option<RenderOptions> {
        self.paired_seed.map(|seed| RenderOptions {
            seed: Some(seed),
            ..self.opts.clone()
        })
    }

    /// `∂L/∂θ` of one render (`ch` under `opts`, B-mode operator `op` after its
    /// forward pass in `ws`) given `∂L/∂I` of its image: the transport part by
    /// path replay (per micro-batch) plus the image-formation parts, and the
    /// centre-frequency part of the image formation on its own.
    fn backward(
        &self,
        scene: &Scene,
        opts: &RenderOptions,
        ch: &ChannelData,
        op: &BMode,
        ws: &mut usray_signal::Workspace,
        d_image: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>), OptimError> {
        let d_channels = op.vjp(ws, d_image)?;
        let keys: Vec<ParamKey> = self.specs.iter().map(|s| s.key.clone()).collect();
        let mut gradient = vec![0.0; keys.len()];
        let n_tx = ch.n_transmits();
        let per_tx = ch.n_elements() * ch.n_samples;
        let batches: Vec<Vec<usize>> = if self.transmit_batches.is_empty() {
            vec![(0..n_tx).collect()]
        } else {
            self.transmit_batches.clone()
        };
        if !self.transmit_batches.is_empty() {
            let mut seen = vec![0usize; n_tx];
            for &t in batches.iter().flatten() {
                if t >= n_tx {
                    return Err(OptimError::Batch(format!(
                        "micro-batch names transmit {t}, the scene has {n_tx}"
                    )));
                }
                seen[t] += 1;
            }
            if seen.iter().any(|&c| c != 1) {
                return Err(OptimError::Batch(format!(
                    "micro-batches must name each of the {n_tx} transmits exactly once (an exact split)"
                )));
            }
        }
        for batch in &batches {
            let part = if batches.len() == 1 {
                self.transport
                    .channel_gradient(scene, &keys, &d_channels, opts)?
            } else {
                let mut masked = vec![0.0; d_channels.len()];
                for &t in batch {
                    let r = t * per_tx..(t + 1) * per_tx;
                    masked[r.clone()].copy_from_slice(&d_channels[r]);
                }
                self.transport
                    .channel_gradient(scene, &keys, &masked, opts)?
            };
            for (g, p) in gradient.iter_mut().zip(part) {
                *g += p;
            }
        }
        let mut demod_fc_part = vec![0.0; keys.len()];
        if self.roles.iter().any(Option::is_some) {
            let cal = op.calibration_vjp(ws, d_image)?;
            for (j, role) in self.roles.iter().enumerate() {
                match role {
                    Some(ImagingRole::SoundSpeed) => gradient[j] += cal.d_sound_speed,
                    Some(ImagingRole::Pitch) => gradient[j] += cal.d_pitch,
                    Some(ImagingRole::CenterFrequency) => {
                        let part = op.center_frequency_vjp(ch, ws, d_image)?;
                        demod_fc_part[j] = part;
                        gradient[j] += part;
                    }
                    None => {}
                }
            }
        }
        Ok((gradient, demod_fc_part))
    }
}

/// Offset of the paired loss's second seed from the first
/// ([`Objective::pair_seeds`]).
pub const PAIRED_SEED_OFFSET: u64 = 1 << 32;

/// The imaging grid shape `(nz, nx)` of a scene.
pub fn grid_shape(scene: &Scene) -> Result<(usize, usize), OptimError> {
    let (x, z) = scene.imaging_settings().grid()?;
    Ok((z.len(), x.len()))
}
