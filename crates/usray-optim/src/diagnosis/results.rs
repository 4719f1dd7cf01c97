//! What a diagnosis found: the calibrated model, each candidate's score and
//! refit, the null refit, the verdict, the noise check and where the time went
//! (serialised as `diagnosis.json`, CONTRACT §5).

use super::calibration::DIAGNOSIS_OVER_CALIBRATION;
use super::noise_budget::NoiseCheck;
use super::residual::{RegionShare, ResidualReport};
use super::verdict::{Verdict, VerdictRule};
use crate::comparison::Comparison;
use std::collections::BTreeMap;
use usray_transport::Scene;

/// The medium's attenuation as the measured echoes' spectra show it
/// ([`Diagnosis::spectral_attenuation`]).
#[derive(Clone, Debug, serde::Serialize)]
pub struct SpectralAttenuation {
    /// The spectral shift of the measured channels against the round's scene
    /// as given, rendered at the calibration's rays and seed: its
    /// `attenuation_db_cm_mhz` is the attenuation beyond the scene's.
    pub shift: usray_signal::SpectralShift,
    /// Whether it named the medium's attenuation, at the scene's value plus
    /// the shift's estimate; the candidate's held-out numbers are then those
    /// of the control's scene with it switched on at that value.
    pub named: bool,
}

/// The probe's centre frequency as the measured echoes' spectra show it
/// ([`Diagnosis::spectral_centre`]).
#[derive(Clone, Debug, serde::Serialize)]
pub struct SpectralCentre {
    /// The scene's centre frequency plus the measured echoes' mean offset
    /// from the model's ([`usray_signal::SpectralShift::offset_hz`], against
    /// the round's scene as given), Hz.
    pub centre_hz: f64,
    /// Its standard error, Hz.
    pub centre_std_hz: f64,
    /// The offset itself, measured minus model, Hz.
    pub offset_hz: f64,
    /// The centre-frequency candidate's range, widened to cover ±15% about
    /// `centre_hz` as well as about the scene's value, Hz.
    pub range_hz: [f64; 2],
}

/// The calibrated base model.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Calibrated {
    /// Fitted free parameters.
    pub params: BTreeMap<String, f64>,
    /// How well each is determined: its standard deviation under the
    /// simulation's Monte Carlo noise ([`crate::parameter_spread`]), `None`
    /// (`null`) when the image does not determine it.
    pub params_std: BTreeMap<String, Option<f64>>,
    /// Loss at the calibrated parameters, seed `s` (the fit's own data).
    pub loss: f64,
    /// Loss at the calibrated parameters re-rendered with the held-out seeds,
    /// averaged ([`super::DiagnoseOptions::held_out_seeds`]).
    pub loss_held_out: f64,
    /// The held-out losses, one per held-out seed.
    pub held_out_losses: Vec<f64>,
}

/// The null refit: the base free parameters alone, refitted from the calibrated
/// point for as many iterations as each candidate's refit. Every refit also
/// continues the calibration of the base parameters, and that alone may shrink
/// the held-out loss where the calibration had not converged; an effect must
/// beat this control
/// ([`EffectResult::excess`]).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct NullRefit {
    /// Held-out loss after the null refit, averaged over the held-out seeds.
    pub loss_after: f64,
    /// `1 − loss_after / calibrated.loss_held_out`.
    pub shrink: f64,
    /// Standard error of [`NullRefit::shrink`] (as [`EffectResult::shrink_std`]).
    pub shrink_std: Option<f64>,
    /// The held-out losses, one per held-out seed.
    pub held_out_losses: Vec<f64>,
    /// Parameters the null refit found.
    pub params: BTreeMap<String, f64>,
}

/// One scored (and possibly refitted) candidate.
#[derive(Clone, Debug, serde::Serialize)]
pub struct EffectResult {
    /// Effect name.
    pub effect: String,
    /// Its strength parameter.
    pub path: String,
    /// Predicted relative loss reduction (module docs, step 3).
    pub score: f64,
    /// The onset: the value of the effect parameter where it was scored (the
    /// best of [`super::Candidate::onsets`], refined), in its unit.
    pub onset: f64,
    /// Admissible range `[min, max]` of the effect parameter in its refit.
    pub range: [f64; 2],
    /// The effect parameter's null, where the effect is off ([`super::Candidate::null`];
    /// `None` for a wall).
    pub null: Option<f64>,
    /// `∂L/∂θ` of the effect parameter at its onset.
    pub gradient: f64,
    /// Loss with the effect at its onset.
    pub loss_onset: f64,
    /// Held-out loss after the refit, averaged over the held-out seeds (absent
    /// when not refitted).
    pub loss_after: Option<f64>,
    /// `1 − loss_after / calibrated.loss_held_out` (absent when not refitted).
    pub shrink: Option<f64>,
    /// Standard error of [`EffectResult::shrink`] from the spread of the
    /// per-seed loss differences, `sd(held_j − after_j) / √K / loss_held_out`
    /// (absent when not refitted or with one held-out seed).
    pub shrink_std: Option<f64>,
    /// How much more the effect's refit shrinks the held-out loss than the null
    /// refit does: `(null_after − after) / calibrated.loss_held_out`, seed by
    /// seed (common random numbers), averaged — against the calibrated
    /// model's held-out evaluations instead when the null refit ended worse
    /// than the calibration (absent when not refitted).
    pub excess: Option<f64>,
    /// Standard error of [`EffectResult::excess`] from its per-seed values
    /// (absent when not refitted or with one held-out seed).
    pub excess_std: Option<f64>,
    /// Standard error of [`EffectResult::excess`] from its spread over blocks
    /// of the image three wavelengths wide (`√B · sd` of the blocks' shares,
    /// averaged over the seeds): large when the gain is carried by a few
    /// places and paid for elsewhere, as where a candidate absorbs a structure
    /// it does not hold (absent when not refitted).
    pub excess_spatial_std: Option<f64>,
    /// Share of the gap above the noise level that the refit removes:
    /// `(loss_held_out − loss_after) / (loss_held_out − noise_loss)`; absent
    /// when not refitted or when the held-out loss is not above the noise level.
    pub gap_explained: Option<f64>,
    /// The held-out losses after the refit, one per held-out seed (empty when
    /// not refitted).
    pub held_out_losses: Vec<f64>,
    /// Parameters found by the refit (effect and base).
    pub params: BTreeMap<String, f64>,
    /// How well the refit determines each of its parameters (standard
    /// deviation, as [`Calibrated::params_std`]; the fixed settings of the
    /// effect are absent).
    pub params_std: BTreeMap<String, Option<f64>>,
    /// The smallest departure of the effect parameter from its null that these
    /// data resolve: three times the refit's Monte Carlo
    /// spread of it, in the parameter's unit. An effect weaker than this could
    /// be present and go unnamed. A lower bound: the spread counts Monte Carlo
    /// noise only (absent when not refitted, without a null, or when the
    /// parameter is not determined).
    pub detection_limit: Option<f64>,
    /// The smallest departure of the effect parameter from its null that
    /// matters to the image ([`super::Candidate::tolerance`]; absent where any
    /// resolved departure matters). A refit within it is not named
    /// ([`EffectResult::within_tolerance`]).
    pub tolerance: Option<f64>,
    /// Where the refit ended within its limit of detection of the effect's
    /// null ([`EffectResult::detection_limit`],
    /// [`EffectResult::within_detection_limit`]): how much the held-out loss rises
    /// when the effect parameter alone is set back to its null, every other
    /// refitted value kept, `(L_null − L_refit)/calibrated.loss_held_out` averaged over the
    /// held-out seeds. It tells an effect whose strength is small in its unit
    /// but plain in the image (a speckle strength of 0.005 whose speckle fills
    /// an object: the B-mode is logarithmic in it) from one that is absent
    /// (absent elsewhere), and a refit whose gain is its own from one whose
    /// base parameters, refitted beside it, carry the gain
    /// ([`EffectResult::indistinct_from_null`]).
    pub absence_cost: Option<f64>,
    /// Standard error of [`EffectResult::absence_cost`]: the larger of its
    /// standard errors over the held-out seeds and over blocks of the image
    /// (as [`EffectResult::excess_std`] and
    /// [`EffectResult::excess_spatial_std`]).
    pub absence_cost_std: Option<f64>,
    /// In a later round of a compound diagnosis ([`super::diagnose_compound`]):
    /// the effect's score in the first round against the score an effect that
    /// simply adds to the first round's would have had there,
    /// `score₁ / (excess · L_k / L₁)` with `L₁`, `L_k` the first and this
    /// round's calibrated held-out losses (an additive effect removes the same
    /// loss in both rounds, a share `excess · L_k / L₁` of the first round's).
    /// Near 1 for an effect that adds; near 0 for one whose gain appears only
    /// beside the earlier effect's refit ([`super::VerdictRule::min_additivity`]).
    /// Absent in the first round, when not refitted or not gaining, and for a
    /// candidate the first round did not have.
    pub additivity: Option<f64>,
    /// Why the candidate's scoring or refit could not finish (absent when it
    /// did): the diagnosis goes on without it.
    pub failed: Option<String>,
    /// A borderline refit's second look on fresh held-out seeds
    /// ([`super::VerdictRule::borderline`]); absent for every other refit.
    pub confirmation: Option<Confirmation>,
    /// For a centre-frequency refit that would otherwise be named: the
    /// attenuation the measured echoes' spectral shift along their path
    /// shows beyond the null refit's model's, in its standard errors
    /// ([`usray_signal::SpectralShift::attenuation_z`];
    /// [`super::VerdictRule::min_spectral_z`]). Absent for every other
    /// candidate and without measured channel data.
    pub spectral_z: Option<f64>,
    /// For a refit that would otherwise be named: it and the control rendered
    /// again at more rays, and its excess extrapolated to a simulation
    /// without Monte Carlo noise ([`super::VerdictRule::holds_without_noise`]);
    /// absent for every other refit.
    pub more_rays: Option<MoreRays>,
}

/// A refit that would be named, and the control, rendered again on the
/// held-out seeds at [`MoreRays::rays`] (four times the first look's), and
/// the excess both looks give extrapolated to infinitely many rays.
///
/// Why: the held-out loss of a model rendered with `r` rays is, in
/// expectation, the loss of its noise-free image plus a Monte Carlo term
/// that falls as `r^(−p)`, as the noise level does (`p = 1` for the loss's
/// ℓ2 term, whose expectation adds the image's variance, `∝ 1/r`; `p = ½`
/// for its ℓ1 term; [`crate::noise_exponent`]). A candidate that darkens the
/// simulation's own noise (its clutter) gains in that term alone: on every
/// seed and in every block, yet less at more rays, and nothing without
/// noise. With the excess `e₁` at `r` rays and `e₂` at `4r`,
/// `e(r) = g + v·r^(−p)` gives the noise-free excess
/// `g = (4^p e₂ − e₁) / (4^p − 1)`, with standard error
/// `√(4^(2p) s₂² + s₁²) / (4^p − 1)` (the two looks' renders taken as
/// independent). `p` is measured from the control's noise level at the two
/// ray counts ([`MoreRays::noise_exponent`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MoreRays {
    /// Rays per element of these renders.
    pub rays: usize,
    /// The excess over the control at those rays, in units of the
    /// calibrated held-out loss, as [`EffectResult::excess`].
    pub excess: f64,
    /// Its standard error over the seeds (absent with one seed).
    pub excess_std: Option<f64>,
    /// The exponent `p` of the Monte Carlo term's `r^(−p)`: from the noise
    /// levels of the calibrated model at the first look's rays and of the
    /// control at these ([`crate::noise_exponent`], kept within
    /// [¼, 1.5]), or ¾ where they could not be measured (the paired loss).
    pub noise_exponent: f64,
    /// The excess extrapolated to infinitely many rays, `g`.
    pub noise_free_excess: f64,
    /// Its standard error (absent where either look's is).
    pub noise_free_std: Option<f64>,
}

impl MoreRays {
    /// The noise-free excess and its standard error from a first look's
    /// `excess ± excess_std` at `rays` and a second's `more ± more_std` at
    /// `more_rays` rays, the Monte Carlo term falling as `r^(−p)`
    /// ([`MoreRays`]: `e(r) = g + v·r^(−p)`).
    ///
    /// ```
    /// use usray_optim::MoreRays;
    /// // A gain that is all Monte Carlo term (p = 1) falls 4× at 4× the rays: nothing is left.
    /// let (g, se) = MoreRays::extrapolate((0.028, Some(0.006)), 20, (0.007, Some(0.003)), 80, 1.0);
    /// assert!(g.abs() < 1e-12);
    /// assert!((se.unwrap() - (16.0f64 * 0.003 * 0.003 + 0.006 * 0.006).sqrt() / 3.0).abs() < 1e-15);
    /// // With p = ½ it falls 2×.
    /// let (g, _) = MoreRays::extrapolate((0.028, None), 20, (0.014, None), 80, 0.5);
    /// assert!(g.abs() < 1e-12);
    /// // A gain of the data's own stays what it was, whatever p.
    /// let (g, _) = MoreRays::extrapolate((0.3, Some(0.01)), 20, (0.3, Some(0.005)), 80, 0.75);
    /// assert!((g - 0.3).abs() < 1e-12);
    /// ```
    #[must_use]
    pub fn extrapolate(
        (excess, excess_std): (f64, Option<f64>),
        rays: usize,
        (more, more_std): (f64, Option<f64>),
        more_rays: usize,
        p: f64,
    ) -> (f64, Option<f64>) {
        let k = (more_rays as f64 / rays as f64).powf(p);
        let g = (k * more - excess) / (k - 1.0);
        let se = excess_std
            .zip(more_std)
            .map(|(s1, s2)| ((k * s2).powi(2) + s1 * s1).sqrt() / (k - 1.0));
        (g, se)
    }
}

/// A borderline refit measured again on fresh held-out seeds: one that passes
/// every test of [`super::name_effect`] but significance over the seeds, its
/// excess between [`super::VerdictRule::borderline_z`] and
/// [`super::VerdictRule::min_excess_z`] of its seed standard errors. That
/// standard error is the simulation's Monte Carlo noise, which more seeds
/// shrink (the image blocks' is the measured image's own structure, which
/// they do not); so the refit and the control are rendered on
/// [`super::DiagnoseOptions::confirmation_seeds`] seeds none of step 4 used,
/// and the seeds' test is decided on those alone. Deciding on independent
/// seeds keeps the test's false-alarm rate that of one look at three
/// standard errors (the first look only chooses what to measure again),
/// where adding seeds to a borderline result until it passes would not.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Confirmation {
    /// Measured: the excess over the control on the fresh seeds alone, as
    /// [`EffectResult::excess`] and [`EffectResult::excess_std`].
    Measured {
        /// Fresh seeds rendered.
        seeds: usize,
        /// Mean excess on them, in units of the calibrated held-out loss.
        excess: f64,
        /// Its standard error over them (absent with one seed).
        excess_std: Option<f64>,
        /// Wall time of the second look, seconds.
        seconds: f64,
    },
    /// Not measured: the budget left could not pay for it, so the verdict
    /// cannot say `"none"` ([`super::unnamed_verdict`]).
    OverBudget {
        /// Fresh seeds it would have rendered.
        seeds: usize,
        /// Its estimated time, seconds.
        estimate_s: f64,
        /// The budget left when it was due, seconds.
        left_s: f64,
    },
}

impl EffectResult {
    /// The excess over the null refit and its standard error over the seeds
    /// that decide the seeds' test: a borderline refit's second look on
    /// fresh seeds where one was measured ([`Confirmation::Measured`]), else
    /// step 4's first look. `None` when not refitted.
    #[must_use]
    pub fn seeds_look(&self) -> Option<(f64, Option<f64>)> {
        match self.confirmation {
            Some(Confirmation::Measured {
                excess, excess_std, ..
            }) => Some((excess, excess_std)),
            _ => self.excess.map(|x| (x, self.excess_std)),
        }
    }

    /// Whether the refit left the effect parameter within 1% of its range's
    /// width from a bound: the data may want a stronger effect than the range
    /// allows (or a wall thinner than the thinnest tried), so the value found is
    /// a limit, not an estimate. `false` when not refitted. Near a bound that
    /// is the effect's null (a speckle strength's or an attenuation's 0) a
    /// small effect refits close to it without being pressed against anything:
    /// there the value counts as an estimate when it lies beyond its limit of
    /// detection from the null ([`EffectResult::detection_limit`]; a speckle
    /// strength of 0.0195 in a range of 0–2, limit 0.007, 80 standard errors
    /// over the null refit), and as at the bound otherwise.
    ///
    /// ```
    /// use std::collections::BTreeMap;
    /// use usray_optim::EffectResult;
    /// let mut e = EffectResult {
    ///     effect: "depth_gain".into(),
    ///     path: "acquisition.depth_gain_db_per_cm".into(),
    ///     score: 0.2, onset: 0.0, range: [0.0, 10.0], null: Some(0.0), gradient: -1e-3,
    ///     loss_onset: 1e-2, loss_after: Some(7e-3), shrink: Some(0.3),
    ///     shrink_std: Some(0.01), excess: Some(0.25), excess_std: Some(0.01), excess_spatial_std: None,
    ///     gap_explained: Some(0.8), held_out_losses: vec![7e-3],
    ///     params: BTreeMap::new(), params_std: BTreeMap::new(), detection_limit: None, tolerance: None, absence_cost: None, absence_cost_std: None, additivity: None,
    ///     failed: None, confirmation: None, spectral_z: None, more_rays: None,
    /// };
    /// e.params.insert(e.path.clone(), 9.999);
    /// assert!(e.at_range_bound());
    /// e.params.insert(e.path.clone(), 2.5);
    /// assert!(!e.at_range_bound());
    /// e.params.insert(e.path.clone(), 0.05); // near the null's own bound…
    /// assert!(e.at_range_bound()); // …without a limit of detection
    /// e.detection_limit = Some(0.02); // beyond it: an estimate
    /// assert!(!e.at_range_bound());
    /// e.detection_limit = Some(0.08); // within it: at the bound…
    /// assert!(e.at_range_bound());
    /// e.absence_cost = Some(0.4); // …unless switching it off costs
    /// e.absence_cost_std = Some(0.05); // eight standard errors
    /// assert!(!e.at_range_bound());
    /// ```
    pub fn at_range_bound(&self) -> bool {
        let [lo, hi] = self.range;
        let margin = 0.01 * (hi - lo);
        let Some(&v) = self.params.get(&self.path) else {
            return false;
        };
        let pressed = |bound: f64| self.null != Some(bound) || !self.detected_from(bound, v);
        (v <= lo + margin && pressed(lo)) || (v >= hi - margin && pressed(hi))
    }

    /// Whether the refitted value `v` is told from the effect's absence at
    /// `null`: beyond its limit of detection, or with an
    /// [`EffectResult::absence_cost`] of at least three of its standard errors
    /// (the limit of detection's convention, [`EffectResult::detection_limit`]).
    fn detected_from(&self, null: f64, v: f64) -> bool {
        self.beyond_detection_limit(null, v) || self.absence_is_costly()
    }

    /// Whether switching the effect back to its null costs the held-out loss
    /// at least three of its standard errors ([`EffectResult::absence_cost`]).
    fn absence_is_costly(&self) -> bool {
        match (self.absence_cost, self.absence_cost_std) {
            (Some(cost), Some(std)) => cost > 3.0 * std,
            _ => false,
        }
    }

    /// Whether `v` lies further from `null` than the limit of detection.
    fn beyond_detection_limit(&self, null: f64, v: f64) -> bool {
        self.detection_limit.is_some_and(|l| (v - null).abs() > l)
    }

    /// Whether the refit ended within [`EffectResult::tolerance`] of the
    /// effect's null: a departure too small to matter to the image, which is
    /// not named however significant its gain (a water speed 2.3 m/s slow
    /// where a quarter wavelength of path at the deepest row takes 3.9 m/s).
    ///
    /// ```
    /// # use std::collections::BTreeMap;
    /// # use usray_optim::EffectResult;
    /// let mut e = EffectResult {
    ///     effect: "sound_speed".into(), path: "medium.sound_speed_m_s".into(), score: 0.1,
    ///     onset: 1480.0, range: [1376.4, 1583.6], null: Some(1480.0), gradient: 0.0,
    ///     loss_onset: 1.0, loss_after: Some(0.9), shrink: Some(0.1), shrink_std: None,
    ///     excess: Some(0.05), excess_std: None, excess_spatial_std: None, gap_explained: None,
    ///     held_out_losses: vec![], params: BTreeMap::new(), params_std: BTreeMap::new(),
    ///     detection_limit: None, tolerance: Some(3.9), absence_cost: None,
    ///     absence_cost_std: None, additivity: None, failed: None, confirmation: None, spectral_z: None, more_rays: None,
    /// };
    /// e.params.insert("medium.sound_speed_m_s".into(), 1477.7);
    /// assert!(e.within_tolerance());
    /// e.params.insert("medium.sound_speed_m_s".into(), 1505.0);
    /// assert!(!e.within_tolerance());
    /// e.tolerance = None;
    /// e.params.insert("medium.sound_speed_m_s".into(), 1477.7);
    /// assert!(!e.within_tolerance());
    /// ```
    pub fn within_tolerance(&self) -> bool {
        match (self.tolerance, self.null, self.params.get(&self.path)) {
            (Some(tol), Some(null), Some(&v)) => (v - null).abs() < tol,
            _ => false,
        }
    }

    /// Whether the refit ended within its limit of detection of the effect's
    /// null: where [`EffectResult::absence_cost`] is measured. `false`
    /// without a null or a limit.
    pub fn within_detection_limit(&self) -> bool {
        match (self.params.get(&self.path), self.null) {
            (Some(&v), Some(null)) => {
                self.detection_limit.is_some() && !self.beyond_detection_limit(null, v)
            }
            _ => false,
        }
    }

    /// Whether these data cannot tell the refitted effect from its absence:
    /// its value lies within its limit of detection of the null
    /// ([`EffectResult::within_detection_limit`]) and switching it back to
    /// the null, every other refitted value kept, does not cost the held-out
    /// loss three standard errors ([`EffectResult::absence_cost`]). Such a
    /// refit's gain over the null refit is not shown to be the effect's: the
    /// base parameters, refitted beside a parameter that barely moved, may
    /// carry it further than the null refit did. (On the k-Wave ring g2 with
    /// attenuation, a second round's element 0.23 mm wide for 0.27, limit
    /// 0.055 mm, passes: switched off it costs +0.010 ± 0.002.) Not named
    /// ([`super::name_effect`]). The test of
    /// [`EffectResult::at_range_bound`] near a null that is a bound, applied
    /// wherever the null lies.
    ///
    /// ```
    /// # use std::collections::BTreeMap;
    /// # use usray_optim::EffectResult;
    /// let path = "probe.element_width_m".to_string();
    /// let mut e = EffectResult {
    ///     effect: "element_width".into(), path: path.clone(), score: 0.03,
    ///     onset: 0.27e-3, range: [0.1e-3, 0.3e-3], null: Some(0.27e-3), gradient: 0.0,
    ///     loss_onset: 1.0, loss_after: Some(0.9), shrink: Some(0.1), shrink_std: None,
    ///     excess: Some(0.01), excess_std: Some(0.001), excess_spatial_std: Some(0.003),
    ///     gap_explained: None, held_out_losses: vec![],
    ///     params: BTreeMap::from([(path, 0.23e-3)]), params_std: BTreeMap::new(),
    ///     detection_limit: Some(0.055e-3), tolerance: None, absence_cost: None,
    ///     absence_cost_std: None, additivity: None, failed: None, confirmation: None, spectral_z: None, more_rays: None,
    /// };
    /// assert!(e.within_detection_limit() && e.indistinct_from_null());
    /// (e.absence_cost, e.absence_cost_std) = (Some(0.002), Some(0.003));
    /// assert!(e.indistinct_from_null()); // switching it off costs nothing…
    /// (e.absence_cost, e.absence_cost_std) = (Some(0.012), Some(0.003));
    /// assert!(!e.indistinct_from_null()); // …or four standard errors: its own
    /// e.detection_limit = Some(0.02e-3);
    /// assert!(!e.within_detection_limit()); // beyond its limit: resolved
    /// ```
    pub fn indistinct_from_null(&self) -> bool {
        self.within_detection_limit() && !self.absence_is_costly()
    }

    /// How far the refit moved the effect parameter from its null, in its
    /// Monte Carlo spreads: `(found − null) / spread`; `None` when not
    /// refitted, without a null or spread. `|z|` below 3 (the limit of
    /// detection, [`EffectResult::detection_limit`]) means these data do not tell the effect
    /// from its absence by its parameter.
    ///
    /// ```
    /// use std::collections::BTreeMap;
    /// use usray_optim::EffectResult;
    /// let path = "acquisition.depth_gain_db_per_cm".to_string();
    /// let e = EffectResult {
    ///     effect: "depth_gain".into(), path: path.clone(), score: 0.1, onset: 0.0,
    ///     range: [0.0, 10.0], null: Some(0.0), gradient: -1e-3, loss_onset: 1e-2,
    ///     loss_after: Some(9e-3), shrink: Some(0.1), shrink_std: Some(0.01),
    ///     excess: Some(0.05), excess_std: Some(0.01), excess_spatial_std: None, gap_explained: None,
    ///     held_out_losses: vec![9e-3],
    ///     params: BTreeMap::from([(path.clone(), 1.5)]),
    ///     params_std: BTreeMap::from([(path, Some(0.75))]),
    ///     detection_limit: Some(2.25), tolerance: None, absence_cost: None, absence_cost_std: None, additivity: None, failed: None, confirmation: None, spectral_z: None, more_rays: None,
    /// };
    /// // Found +1.5 dB/cm at a spread of 0.75: two spreads from no gain.
    /// assert_eq!(e.null_z(), Some(2.0));
    /// ```
    pub fn null_z(&self) -> Option<f64> {
        let found = self.params.get(&self.path)?;
        let spread = (*self.params_std.get(&self.path)?)?;
        Some((found - self.null?) / spread)
    }
}

/// Wall time of the diagnosis steps, seconds.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Timings {
    /// Step 1.
    pub calibration_s: f64,
    /// Step 3, scoring every candidate.
    pub scoring_s: f64,
    /// Step 3–4, the candidates' refits and their held-out evaluation.
    pub refits_s: f64,
    /// Step 4's control, the null refit and its held-out evaluation.
    pub null_refit_s: f64,
    /// Noise level and held-out evaluation of the calibrated model.
    pub held_out_s: f64,
    /// How well the calibration and each refit determine their parameters
    /// (the Jacobian's and the extra seeds' renders).
    pub spread_s: f64,
    /// Step 4's second look at borderline refits on fresh seeds
    /// ([`Confirmation`]).
    pub confirmation_s: f64,
    /// Step 4's look at more rays: the refits that would be named and the
    /// control on the held-out seeds at four times the rays ([`MoreRays`]).
    pub more_rays_s: f64,
    /// The echoes' spectra: against the scene as given, once per round where
    /// the data are channels (the centre they show,
    /// [`Diagnosis::spectral_centre`], and the attenuation they show where
    /// the image names nothing, [`Diagnosis::spectral_attenuation`]), and
    /// against the null refit's model where a centre-frequency refit is
    /// checked ([`Diagnosis::spectral_shift`]): one render of the model's
    /// channels each, and the held-out renders of an attenuation they name.
    pub spectral_s: f64,
    /// The whole diagnosis.
    pub total_s: f64,
}

impl Timings {
    /// Step 1 with its held-out evaluation: the calibration stage whose time a
    /// later round's estimate scales ([`super::FirstRound::seconds_over_calibration`]).
    pub fn calibration_stage_s(&self) -> f64 {
        self.calibration_s + self.held_out_s
    }

    /// The whole diagnosis's time over its calibration stage's
    /// ([`Timings::calibration_stage_s`]); six, the budget's usual estimate,
    /// where the stage took no measurable time (a run resumed from its
    /// checkpoint).
    pub fn over_calibration(&self) -> f64 {
        let ratio = self.total_s / self.calibration_stage_s();
        if ratio.is_finite() && ratio >= 1.0 {
            ratio
        } else {
            DIAGNOSIS_OVER_CALIBRATION
        }
    }
}

/// Everything a diagnosis found (serialised as `diagnosis.json`, CONTRACT §5).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Diagnosis {
    /// Step 1.
    pub calibrated: Calibrated,
    /// Step 2: region shares of the calibrated residual (all partitions).
    #[serde(rename = "where")]
    pub where_: Vec<RegionShare>,
    /// Step 3–4, ranked by score, most responsible first.
    pub effects: Vec<EffectResult>,
    /// Step 4's control: the base parameters refitted alone.
    pub null_refit: NullRefit,
    /// The thresholds the verdict applied.
    pub rule: VerdictRule,
    /// Step 5.
    pub verdict: Verdict,
    /// Monte Carlo noise level: loss between the calibrated model's images for
    /// seed `s` and for each held-out seed, averaged (the paired loss against
    /// its own seed-`s` image with [`super::DiagnoseOptions::paired`]).
    pub noise_loss: f64,
    /// The simulation's noise as a share of the gap, at the rays used, and
    /// what a decision would have needed ([`crate::simulation_noise_share`]).
    pub noise_check: NoiseCheck,
    /// Noise realisations (pairs of seeds) behind each `params_std`.
    pub spread_pairs: usize,
    /// Held-out seeds behind each held-out loss and the noise level.
    pub held_out_seeds: usize,
    /// Whether every loss was the paired loss ([`super::DiagnoseOptions::paired`]).
    pub paired: bool,
    /// How the images were compared in every loss after the calibration (its
    /// smoothing and the measurement's noise floor).
    pub comparison: Comparison,
    /// Whether the held-out losses were measured against held-out measured
    /// data (other frames, [`super::DiagnoseOptions::held_out_measured`]) rather than
    /// the fitted data.
    pub held_out_frames: bool,
    /// The bounce limit every model was rendered at
    /// ([`super::diagnosis_bounces`]: the scene's, or 2 more when a solid
    /// cylinder is a `wall_thickness` candidate).
    pub max_bounces: u32,
    /// Where each step's time went.
    pub timings: Timings,
    /// How the measured echoes' spectra shift against the null refit's
    /// model's along their path ([`usray_signal::spectral_shift()`]): measured where a
    /// centre-frequency refit would otherwise be named and the measured data
    /// are channels ([`super::VerdictRule::min_spectral_z`]). Absent
    /// otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spectral_shift: Option<usray_signal::SpectralShift>,
    /// Where the image names no effect and the measured data are channels:
    /// how the measured echoes' spectra shift against the round's scene as
    /// given (before its calibration), and whether that named the medium's
    /// attenuation ([`super::VerdictRule::spectra_show_attenuation`]).
    /// Absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spectral_attenuation: Option<SpectralAttenuation>,
    /// The centre frequency the measured echoes' spectra show, where the data
    /// are channels and the shift is alike along the path
    /// ([`super::VerdictRule::spectra_show_centre`]); the centre-frequency
    /// candidate's range then covers it. Absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spectral_centre: Option<SpectralCentre>,
    /// Why no further compound round followed this one where one was asked
    /// ([`super::diagnose_compound`]): the budget left could not pay for it,
    /// or it failed. Absent when the rounds ran out or nothing was named.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub next_round_stopped: Option<String>,
    /// The full residual analysis of the calibrated model (kinds of residual).
    #[serde(skip)]
    pub residual: ResidualReport,
    /// Calibrated simulated image (seed `s`).
    #[serde(skip)]
    pub calibrated_image: Vec<f64>,
    /// Simulated image after the verdict's refit (the calibrated one when none).
    #[serde(skip)]
    pub after_image: Vec<f64>,
    /// The scene of the verdict's refit: the named effect switched on at its
    /// fitted value (absent when no effect is named).
    #[serde(skip)]
    pub after_scene: Option<Scene>,
}
