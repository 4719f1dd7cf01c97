//! The sim-to-real diagnosis (CONTRACT §4 `usray diagnose`, §5 `diagnosis.json`):
//! calibrate, locate the residual, rank candidate unmodelled effects by one
//! gradient each, confirm the leading ones by refitting, measure how far each
//! shrinks the gap on held-out data, and give a verdict.
//!
//! # Steps
//! 1. **Calibrate**: fit the base scene's free parameters ([`default_free_params`]
//!    unless named) to the measured B-mode, [`DiagnoseOptions::calibration_iters`]
//!    Adam iterations with common random numbers (seed `s`).
//! 2. **Where**: [`residual::analyse_residual`] of the calibrated image.
//! 3. **Which**: every candidate of [`catalogue`] is switched on at its *onset*
//!    (its null value where the model is smooth there; where the null is a change
//!    of structure — a wall appearing inside a solid cylinder — or the loss is
//!    far from quadratic within the range — a sound-speed error moving echoes by
//!    more than the pulse length — the best of a few values across the range by
//!    loss alone, refined at half and a quarter of their spacing; see
//!    [`score_candidate`]) and scored from **one value +
//!    gradient** of the loss `g = ∂L/∂θ` there, with the Gauss–Newton curvature
//!    of the ℓ2 term `c = (2λ₂/N) Σ_u J_u²` from one more render
//!    (`J_u = ∂I_u/∂θ` by a forward difference of 1% of the range):
//!
//!    `score = max(0, L_cal − min(L_on, L(θ_on − g/c))) / L_cal`
//!
//!    — the relative loss reduction of a Newton step along the effect (kept in
//!    its range; `c` the larger of the Gauss–Newton curvature and the secant
//!    `2(L(θ+h) − L − g h)/h²` of the same render, which includes the ℓ1 term's
//!    curvature), checked by one more render at the step because the quadratic
//!    model overshoots where the image is far from linear in the parameter (a
//!    speckle field appearing), and halved back towards the onset while that
//!    lowers the loss (at most three times). The
//!    [`DiagnoseOptions::confirm_top`] best are refitted (effect parameter + the
//!    base free parameters, [`DiagnoseOptions::refit_iters`] iterations), each
//!    starting from its best rendered point of the scoring (the checked step if
//!    it lowered the loss, else the onset). The medium's sound speed is
//!    refitted whatever its score ([`Candidate::refit_always`]), from its best
//!    onset away from the null when the null scored best: the calibration can
//!    take a speed error up in the geometry and leave it nothing to score.
//! 4. **How far it shrinks**: losses on **held-out** data: the simulation is
//!    re-rendered with [`DiagnoseOptions::held_out_seeds`] independent seeds
//!    ([`held_out_seed`]: `s + 1`, then further apart; other paths) at the
//!    calibrated and at the refitted parameters, so an effect that only fits the
//!    Monte Carlo noise of seed `s` does not look like an explanation:
//!    `shrink = 1 − mean loss_after / mean loss_calibrated` over those seeds,
//!    with its standard error from the per-seed differences. One held-out seed
//!    alone makes the shrink noisy: the calibrated model's loss varies from
//!    seed to seed, and an unlucky seed makes every refit look like an
//!    improvement. With
//!    [`DiagnoseOptions::held_out_measured`] (other frames of the acquisition)
//!    every held-out loss is measured against those frames instead, so that a
//!    refit that fits the fitted frames' own noise gains nothing there.
//!    **The null refit** is the control: the base parameters alone, refitted
//!    from the calibrated point for as many iterations as each candidate's
//!    refit. Continuing the calibration alone may shrink the held-out loss
//!    (where the calibration had not converged), so each refit's
//!    *excess* over it — `(null_after − loss_after) / loss_calibrated`, seed by
//!    seed, with its standard error — is what the effect itself explains (the
//!    baseline is the calibrated model instead if the null refit ended worse:
//!    every refit restarts Adam's moments and may).
//!    Every fitted parameter of the calibration and of each refit carries its
//!    Monte Carlo spread ([`crate::parameter_spread`]).
//!    **A second look** ([`Confirmation`]): a refit that would be named but
//!    for its excess's standard error over the seeds, at between
//!    [`VerdictRule::borderline_z`] and [`VerdictRule::min_excess_z`] of it,
//!    is rendered with the control again on
//!    [`DiagnoseOptions::confirmation_seeds`] fresh seeds, within the budget,
//!    and the seeds' test is decided on those alone.
//!    **A look at more rays** ([`MoreRays`]): every refit that would be
//!    named, and the control, rendered again on the held-out seeds at four
//!    times the rays; its excess extrapolated to a noise-free simulation must
//!    stay significant ([`VerdictRule::holds_without_noise`]): a candidate
//!    that only darkens the simulation's own clutter gains less the more rays.
//! 5. **Verdict** ([`name_effect`], [`unnamed_verdict`]): a refitted effect
//!    qualifies when its excess over the null refit is at least
//!    [`VerdictRule::min_excess_z`] of its standard errors over the held-out
//!    seeds (the simulation's noise) and [`VerdictRule::min_spatial_z`] of
//!    its standard error over blocks of the image (`spatial`: a gain won in a
//!    few places and paid for elsewhere is a candidate bending towards a
//!    structure it does not hold); where the simulation's noise failed its
//!    check, its excess must also reach [`VerdictRule::large_excess`] (the
//!    one-render loss rewards a quieter simulation). The share of the gap it
//!    explains,
//!    `gap_explained = (loss_calibrated − loss_after) / (loss_calibrated −
//!    noise)`, is reported beside it: with data the model cannot reproduce
//!    exactly a model-form residual stays whatever effect is added. The
//!    qualifying effect with the largest shrink is named — where several come
//!    within [`VerdictRule`]'s tie margin of it, the one with the highest
//!    score, the others listed as [`Verdict::alternatives`]. Without one,
//!    [`unnamed_verdict`] decides between `"unexplained"`, `"none"` and
//!    `"inconclusive"` from the noise check below.
//!
//! # Noise, candidates, failures
//! - **The simulation's noise** ([`crate::NoiseCheck`]): after calibrating, the
//!   share `(N/2)/H` of the held-out loss `H` that one simulated image's noise
//!   holds (`N` the noise level) is compared with
//!   [`DiagnoseOptions::noise_share`]. With a budget
//!   ([`DiagnoseOptions::budget_s`]) the rays are raised while the share is
//!   larger and the budget allows; a diagnosis that cannot get there goes on
//!   at the rays it has, may still name an effect that clears the held-out
//!   test, and otherwise says `"inconclusive"` (never `"none"`) with the rays
//!   and time it would need.
//! - **Candidates**: the structural [`catalogue`] and the
//!   [`crate::parameter_candidates`] ("this modelled value is wrong").
//! - **Failures**: a candidate whose scoring or refit fails is recorded
//!   ([`EffectResult::failed`]) and skipped; fits project coupled bounds
//!   ([`usray_transport::Scene::set_projected`]).
//! - **Compound gaps**: [`diagnose_compound`] switches a named effect on and
//!   diagnoses again.
//!
//! With [`DiagnoseOptions::paired`] every loss above is the paired loss
//! ([`crate::Objective::pair_seeds`]: two renders with independent seeds,
//! unbiased in the simulation's variance in its ℓ2 term), and the noise level is
//! the paired loss of the calibrated model against its own seed-`s` image.

//!
//! # Where each job lives
//! | module | job |
//! |---|---|
//! | `options` | [`DiagnoseOptions`], the settings |
//! | `calibration` | step 1: the free parameters and their ranges, the calibration at one ray count, the rays raised within a budget; how every loss is taken ([`LossSetup`]) |
//! | [`residual`] | step 2: where the residual lies and of what kind |
//! | `catalogue` | the structural candidate effects ([`catalogue`], [`Candidate`]) |
//! | `parameter_candidates` | the candidates "this modelled value is wrong" |
//! | `screening` | step 3: one score per candidate ([`score_candidate`]) |
//! | `refits` | step 4: the null refit and the leading candidates' refits |
//! | `held_out` | step 4's statistics: held-out seeds, losses, means and standard errors |
//! | `spatial` | step 4's spatial standard error of an excess (blocks of the image) |
//! | `confirmation` | step 4's second look at a borderline refit on fresh seeds ([`Confirmation`]) |
//! | `more_rays` | step 4's look at more rays at every refit that would be named ([`MoreRays`]) |
//! | `spectral_check` | the measured echoes' spectral shift along their path: the centre they show widens the centre frequency's range ([`VerdictRule::spectra_show_centre`]), step 5 checks a centre-frequency refit against it ([`VerdictRule::min_spectral_z`]) and, where the image names nothing, names the attenuation it shows (test 10) |
//! | `noise_budget` | the simulation's noise against the gap ([`NoiseCheck`]) |
//! | `verdict` | step 5 ([`name_effect`], [`unnamed_verdict`], [`VerdictRule`]) |
//! | `results` | what a diagnosis found ([`Diagnosis`]) |
//! | `run` | [`diagnose`] and [`diagnose_compound`]: the steps in order |
//! | `report` | `report.md` and `diagnosis.json` ([`Report`]) |

mod calibration;
mod catalogue;
mod confirmation;
mod held_out;
mod more_rays;
mod noise_budget;
mod options;
mod parameter_candidates;
mod refits;
mod report;
pub mod residual;
mod results;
mod run;
mod screening;
mod spatial;
mod spectral_check;
mod verdict;

pub use calibration::{
    calibration_spec, default_free_params, diagnosis_smoothing, FreeParam, LossSetup,
};
pub(crate) use catalogue::SCATTERER_DENSITY_PER_MM3;
pub use catalogue::{
    catalogue, diagnosis_bounces, sound_speed_tolerance, wall_thickness_tolerance, Candidate,
};
pub use held_out::{held_out_seed, mean_and_se};
pub use noise_budget::{noise_exponent, rays_needed, simulation_noise_share, NoiseCheck};
pub use options::{DiagnoseOptions, FirstRound, MeasuredChannels};
pub use parameter_candidates::parameter_candidates;
pub use report::Report;
pub use results::{
    Calibrated, Confirmation, Diagnosis, EffectResult, MoreRays, NullRefit, SpectralAttenuation,
    SpectralCentre, Timings,
};
pub use run::{diagnose, diagnose_compound};
pub use screening::{score_candidate, Score};
pub use verdict::{name_effect, names_an_effect, unnamed_verdict, Verdict, VerdictRule};
