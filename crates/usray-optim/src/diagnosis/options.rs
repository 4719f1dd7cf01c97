//! The settings of a diagnosis.

use super::noise_budget::DEFAULT_NOISE_SHARE;
use super::verdict::VerdictRule;
use crate::fit::FitOptions;
use crate::journal::Journal;
use crate::OptimError;
use std::collections::BTreeMap;
use usray_signal::ChannelData;
use usray_transport::RenderOptions;

/// What the first round of a compound diagnosis found, against which a later
/// round tests whether an effect adds to it ([`super::EffectResult::additivity`]).
#[derive(Clone, Debug, Default)]
pub struct FirstRound {
    /// Each candidate's score in the first round, by its parameter's path.
    pub scores: BTreeMap<String, f64>,
    /// The first round's calibrated held-out loss.
    pub loss_held_out: f64,
    /// The first round's whole time over its calibration stage's (step 1 with
    /// its held-out evaluation), both on the wall clock: a later round, whose
    /// scene may render far slower, estimates its own time as this many times
    /// its calibration stage, and stops there when that is more than its
    /// budget ([`DiagnoseOptions::budget_s`]).
    pub seconds_over_calibration: f64,
}

/// Measured channel data beside the measured image
/// ([`DiagnoseOptions::measured_channels`]); shown by its shape alone.
#[derive(Clone)]
pub struct MeasuredChannels(pub std::sync::Arc<ChannelData>);

impl std::fmt::Debug for MeasuredChannels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (t, e, n) = self.0.shape();
        write!(
            f,
            "MeasuredChannels({t} transmits × {e} elements × {n} samples)"
        )
    }
}

/// Settings of a diagnosis.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// Free parameters of the base model ([`super::FreeParam::parse`] reads
    /// `PATH` or `PATH=MIN:MAX`); empty = [`super::default_free_params`].
    pub free_params: Vec<super::calibration::FreeParam>,
    /// Adam iterations of the calibration (default 40).
    pub calibration_iters: usize,
    /// Adam iterations of each confirming refit (default 40).
    pub refit_iters: usize,
    /// How many of the best-scored candidates are refitted (default 3).
    pub confirm_top: usize,
    /// When the verdict names an effect, `"none"`, `"unexplained"` or
    /// `"inconclusive"`.
    pub rule: VerdictRule,
    /// Pairs of independent seeds whose image differences give the noise
    /// realisations of each fit's parameter spread
    /// ([`crate::parameter_spread`]; default 4, at least 1: the pair `s`,
    /// `s + 1` is rendered anyway).
    pub spread_pairs: usize,
    /// Independent seeds on which the held-out losses (and the noise level) are
    /// averaged ([`super::held_out_seed`]; default 6, at least 1; the standard errors
    /// of the shrinks and excesses come from the spread over these seeds).
    pub held_out_seeds: usize,
    /// Fresh seeds on which a borderline refit and the control are rendered
    /// again ([`super::Confirmation`], [`super::VerdictRule::borderline`];
    /// default 24, four times [`DiagnoseOptions::held_out_seeds`]: an excess
    /// at two standard errors over six seeds, if real, stands at about four
    /// over 24; 0 takes no second look).
    pub confirmation_seeds: usize,
    /// Use the paired loss ([`crate::Objective::pair_seeds`]) everywhere: the
    /// calibration, scoring, refits and held-out losses render twice with
    /// independent seeds (the loss's ℓ2 term is then unbiased in the
    /// simulation's Monte Carlo variance, so a fit gains far less by a
    /// quieter simulation: the paired ℓ1 term keeps 29% of the one-render
    /// bias), and the noise level is the paired loss of the calibrated model
    /// against its own image. Default `false`: the paper's one-render
    /// loss, at half the renders.
    pub paired: bool,
    /// Measured data held out from the fit — other frames of the same
    /// acquisition, on the same grid as the fitted image — against which every
    /// held-out loss is measured (the calibrated model's, each refit's and the
    /// null refit's, each still on the held-out simulation seeds). A refit that
    /// fits the fitted frames' own noise gains nothing on other frames, whose
    /// noise is independent of it. `None` (the default): the fitted data, on
    /// held-out seeds only ([`crate::load_reference_frames`] splits multi-frame
    /// channel data into the two).
    pub held_out_measured: Option<Vec<f64>>,
    /// Fit settings shared by calibration and refits (iterations overridden).
    pub fit: FitOptions,
    /// Render options of the simulation (rays, seed `s`, threads).
    pub render: RenderOptions,
    /// A time budget, seconds: within it the rays are raised until the
    /// simulation's noise is at most [`DiagnoseOptions::noise_share`] of the
    /// calibrated gap; where the budget cannot buy that, the diagnosis goes on
    /// at the rays it has and cannot say `"none"` ([`super::unnamed_verdict`]).
    /// The budget bounds the rays chosen (a whole diagnosis's time estimated
    /// as about six times its calibration stage's) and the compound rounds
    /// ([`super::diagnose_compound`]): a later round starts only where the
    /// budget left pays for a round as long as the last, and stops after its
    /// calibration where its own estimate is more than what is left. Within
    /// a round the steps after the calibration are not cut short.
    /// `None` (the default): the rays as given, and the same check reported.
    pub budget_s: Option<f64>,
    /// Largest share of the calibrated held-out loss the simulation's noise may
    /// hold for a `"none"` ([`crate::simulation_noise_share`]; default
    /// 0.25).
    pub noise_share: f64,
    /// Standard deviation of the Gaussian both images are smoothed by before
    /// every loss, in wavelengths at the probe's centre frequency
    /// ([`super::diagnosis_smoothing`]; default 0, none: the paper's
    /// pixel-wise comparison; smoothing with the noise floor named no more
    /// hidden effects on the benchmark's tiers and biased the refitted
    /// parameters, docs/diagnosis.md). Speckle and electronic noise, which no simulation reproduces
    /// pixel for pixel, average out over it; echoes keep their place. 0.5 is
    /// the tested value (docs/diagnosis.md, "How the images are compared").
    pub smoothing_wavelengths: f64,
    /// Floor both images at the measurement's noise level after the
    /// calibration ([`crate::noise_floor`]; default `false`): differences the
    /// measurement's own noise hides are no evidence of an effect. Opt-in: a
    /// floor also removes the gradient that grows an echo out of the dark,
    /// biasing a refit (docs/diagnosis.md, "How the images are compared").
    pub noise_floor: bool,
    /// Where the diagnosis keeps its fits and its wall-clock decisions as it
    /// goes ([`Journal`]; default: nowhere). Started again on the journal of
    /// a killed run, it skips what was done and ends with the same results.
    pub journal: Journal,
    /// The measured channel data the measured image was formed from, where
    /// the data are channels (default `None`: an image only). With them a
    /// centre-frequency refit is checked against how the echoes' spectra
    /// shift along their path ([`super::VerdictRule::min_spectral_z`]), and
    /// where the image names nothing, the attenuation that shift shows
    /// against the scene as given may be named
    /// ([`super::VerdictRule::spectra_show_attenuation`]).
    pub measured_channels: Option<MeasuredChannels>,
    /// Set by [`super::diagnose_compound`] for a later round (default `None`,
    /// a first round): what the first round found, for
    /// [`super::EffectResult::additivity`].
    pub first_round: Option<FirstRound>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            free_params: Vec::new(),
            calibration_iters: 40,
            refit_iters: 40,
            confirm_top: 3,
            rule: VerdictRule::default(),
            spread_pairs: 4,
            held_out_seeds: 6,
            confirmation_seeds: 24,
            paired: false,
            held_out_measured: None,
            fit: FitOptions::default(),
            render: RenderOptions::default(),
            budget_s: None,
            noise_share: DEFAULT_NOISE_SHARE,
            smoothing_wavelengths: 0.0,
            noise_floor: false,
            journal: Journal::default(),
            measured_channels: None,
            first_round: None,
        }
    }
}

impl DiagnoseOptions {
    /// Checks the settings a diagnosis cannot run with, and returns the data
    /// every held-out loss is measured against: [`DiagnoseOptions::held_out_measured`]
    /// or else `measured` itself.
    ///
    /// # Errors
    /// [`OptimError::Diagnosis`] naming the setting: `spread_pairs` or
    /// `held_out_seeds` of 0, a `noise_share` outside (0, 1), a time budget
    /// that is not a positive number, or held-out data of another size than
    /// `measured`.
    pub(crate) fn held_out_data<'a>(
        &'a self,
        measured: &'a [f64],
    ) -> Result<&'a [f64], OptimError> {
        let opts = self;
        if opts.spread_pairs == 0 {
            return Err(OptimError::Diagnosis(
                "spread_pairs must be at least 1 (the seeds s, s + 1 are rendered anyway)".into(),
            ));
        }
        if opts.held_out_seeds == 0 {
            return Err(OptimError::Diagnosis(
                "held_out_seeds must be at least 1 (shrinks are measured on held-out seeds)".into(),
            ));
        }
        if !(opts.noise_share > 0.0 && opts.noise_share < 1.0) {
            return Err(OptimError::Diagnosis(format!(
                "noise_share must lie strictly between 0 and 1, found {}",
                opts.noise_share
            )));
        }
        if let Some(b) = opts.budget_s.filter(|b| !(b.is_finite() && *b > 0.0)) {
            return Err(OptimError::Diagnosis(format!(
                "the time budget must be a positive number of seconds, found {b}"
            )));
        }
        match &opts.held_out_measured {
            Some(h) if h.len() != measured.len() => Err(OptimError::Diagnosis(format!(
                "the held-out measured image has {} pixels but the measured image {}: both must be on the scene's imaging grid",
                h.len(),
                measured.len()
            ))),
            Some(h) => Ok(h),
            None => Ok(measured),
        }
    }
}
