//! # usray-optim: calibration on the differentiable pipeline
//!
//! Parameter ranges and the paper's `[0, 1]` clip map, image losses with their
//! gradients, Adam with parameter groups and gradient clipping, and finite-difference
//! sweeps to check AD gradients. The fit loop and the sim-to-real diagnosis
//! ([`diagnosis`], with its report) build on these.
//!
//! ```
//! use usray_optim::{Adam, AdamGroup, L1L2, ParamMap, ParamSpec};
//!
//! // Recover a "radius" r from a 4-pixel "image" that depends on it smoothly.
//! let render = |r: f64| -> Vec<f64> { (0..4).map(|u| (-(u as f64 - r * 1e3).powi(2)).exp()).collect() };
//! let reference = render(2.0e-3);
//! let key = usray_transport::ParamKey::object("c", usray_transport::Field::Radius);
//! let map = ParamMap::new(vec![ParamSpec { key, min: 0.001, max: 0.003 }]);
//! let mut state = map.state_from_physical(&[1.6e-3]);
//! let mut adam = Adam::new(vec![AdamGroup { learning_rate: 0.02, ..Default::default() }], vec![0]);
//! let loss = L1L2::default();
//! for _ in 0..300 {
//!     let r = map.physical(&state)[0];
//!     let mut d_image = vec![0.0; 4];
//!     loss.value_and_gradient(&render(r), &reference, &mut d_image);
//!     // dI/dr by hand here; usray obtains it from the whole pipeline.
//!     let d_r: f64 = (0..4).map(|u| {
//!         let a = u as f64 - r * 1e3;
//!         d_image[u] * (-a * a).exp() * 2.0 * a * 1e3
//!     }).sum();
//!     let g = map.state_gradient(&state, &[d_r]);
//!     adam.step(&mut state, &g);
//! }
//! assert!((map.physical(&state)[0] - 2.0e-3).abs() < 2e-5);
//! ```

mod adam;
#[doc(hidden)]
pub mod blind;
mod comparison;
pub mod diagnosis;
mod fd;
mod fit;
mod journal;
mod loss;
mod mirror;
mod objective;
mod params;
mod reference;
mod spread;
#[cfg(test)]
mod test_noise;

pub use adam::{Adam, AdamGroup, AdamState};
pub use comparison::{noise_floor, Comparison, MAX_NOISE_FLOOR, MIN_DARK_SHARE, MODEL_DARK_GREY};
pub use diagnosis::residual;
pub use diagnosis::residual::{analyse_residual, RegionShare, ResidualOptions, ResidualReport};
pub use diagnosis::{
    calibration_spec, catalogue, default_free_params, diagnose, diagnose_compound,
    diagnosis_bounces, diagnosis_smoothing, held_out_seed, mean_and_se, name_effect,
    names_an_effect, noise_exponent, parameter_candidates, rays_needed, score_candidate,
    simulation_noise_share, sound_speed_tolerance, unnamed_verdict, wall_thickness_tolerance,
    Calibrated, Candidate, Confirmation, DiagnoseOptions, Diagnosis, EffectResult, FirstRound,
    FreeParam, LossSetup, MeasuredChannels, MoreRays, NoiseCheck, NullRefit, Report, Score,
    SpectralAttenuation, SpectralCentre, Timings, Verdict, VerdictRule,
};
pub use fd::{best_fd, fd_sweep, fd_sweeps, log_steps, sweep_steps, FdPoint};
pub use fit::{fit, fit_journaled, FitOptions, FitResult, FitStep};
pub use journal::Journal;
pub use loss::L1L2;
pub use mirror::impedance_mirror;
pub use objective::{
    grid_shape, Evaluation, FdChannels, Objective, PathReplay, TransportGradient,
    PAIRED_SEED_OFFSET,
};
pub use params::{default_range, ParamMap, ParamSpec, ParamSpecError};
pub use reference::{
    compare_absolute_levels, follow_declared_dimensions, load_reference, load_reference_frames,
    reference_from_channels, AbsoluteLevels, SOURCE_PRESSURE_UNIT,
};
pub use spread::{linearised_spread, parameter_spread};
pub use usray_transport::scene::ParamGroup;

/// An error of the calibration layer, with a one-line message.
#[derive(Debug, thiserror::Error)]
pub enum OptimError {
    /// The scene rejected a path or a value.
    #[error(transparent)]
    Scene(#[from] usray_transport::SceneError),
    /// Image formation or data I/O failed.
    #[error(transparent)]
    Signal(#[from] usray_signal::SignalError),
    /// A `--params` entry is malformed.
    #[error(transparent)]
    Param(#[from] ParamSpecError),
    /// The reference cannot be used on this scene.
    #[error("reference: {0}")]
    Reference(String),
    /// A micro-batch is malformed.
    #[error("micro-batch: {0}")]
    Batch(String),
    /// The residual diagnosis got unusable images or options ([`residual`]).
    #[error("diagnosis: {0}")]
    Diagnosis(String),
    /// A finite-difference sweep ([`fd_sweeps`]) hit a failing render.
    #[error("finite differences of {key}")]
    FiniteDifference {
        /// The parameter being swept.
        key: usray_transport::ParamKey,
        /// Why its render failed.
        #[source]
        source: Box<OptimError>,
    },
    /// A checkpoint ([`Journal`]) cannot be read, written or resumed from.
    #[error("checkpoint: {0}")]
    Checkpoint(String),
    /// An optimiser's step left the scene's valid region in a way no projection
    /// repairs: the fit's doing, not the scene file's.
    #[error("fit step: {0}")]
    Step(String),
    /// A compound round ([`diagnose_compound`]) stopped after its calibration:
    /// the time it would take is more than the budget left.
    #[error("budget: {message}")]
    Budget {
        /// What the round's calibration took and what the round would take.
        message: String,
        /// The round's whole time, estimated, seconds.
        estimate_s: f64,
    },
}
