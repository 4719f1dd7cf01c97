//! Step 1 of a diagnosis: the base model's free parameters and their ranges,
//! its calibration at one ray count with the held-out losses and noise level
//! that every later step compares with, and the rays raised within a time
//! budget until the simulation's noise is a small enough share of the gap.

use super::held_out::{held_out, held_out_seed, mean, mean_loss};
use super::noise_budget::{
    noise_exponent, rays_needed, simulation_noise_share, NoiseCheck, DEFAULT_NOISE_EXPONENT,
};
use super::options::DiagnoseOptions;
use super::results::Timings;
use crate::comparison::{noise_floor, Comparison};
use crate::fit::{fit_journaled, FitOptions};
use crate::objective::{Evaluation, Objective};
use crate::params::{ParamSpec, ParamSpecError};
use crate::OptimError;
use std::time::Instant;
use usray_transport::scene::Owner;
use usray_transport::{Field, ParamKey, RenderOptions, Scene};

/// The documented default free parameters of the base model: each object's
/// radius (cylinders, spheres) and, for each object's material, its impedance
/// and (if rough) roughness.
///
/// The probe's centre frequency is not among them, though echoes are rarely
/// centred at the nominal one: calibrated, it also lengthens the model's
/// echoes to match any effect that lengthens the data's (a thicker wall, a
/// longer pulse, a wrong speed blurring the transmits), and on the
/// benchmarks of `bench/` more effects were missed that way than the
/// offsets it took up had cost (`docs/diagnosis.md`, "Known limits"). It
/// stays a candidate ([`crate::parameter_candidates`]); `--params` frees it.
pub fn default_free_params(scene: &Scene) -> Vec<ParamKey> {
    let mut out = Vec::new();
    let mut seen = Vec::new();
    for o in &scene.objects {
        if o.radius_m.is_some() {
            out.push(ParamKey::object(&o.name, Field::Radius));
        }
        if !seen.contains(&o.material) {
            seen.push(o.material.clone());
            out.push(ParamKey::material(&o.material, Field::Impedance));
            if scene
                .materials
                .get(&o.material)
                .is_some_and(|m| m.roughness > 0.0)
            {
                out.push(ParamKey::material(&o.material, Field::Roughness));
            }
        }
    }
    out
}

/// Multiple of the calibration stage's time (calibration, held-out losses and
/// noise level) that a whole diagnosis takes at the same rays: scoring every
/// candidate, the null refit, three refits and the parameter spreads add the
/// rest. The middle of the ratios measured on the benchmarks of `bench/`
/// (docs/performance.md; fewer candidates refit quickly on data without an
/// effect), so an estimate from it may be off by about half.
pub(crate) const DIAGNOSIS_OVER_CALIBRATION: f64 = 6.0;

/// At most this many raises of the rays within a budget
/// ([`DiagnoseOptions::budget_s`]), each followed by a calibration of half the
/// iterations from the point reached.
const MAX_RAY_RAISES: usize = 3;

/// Largest factor by which one raise multiplies the rays (the noise's exponent
/// is extrapolated from at most this far).
const MAX_RAY_FACTOR: f64 = 8.0;

/// A margin kept between a material's impedance and the medium's in a
/// calibration whose range is the default one: at `|Z − Z₀|/Z₀ < 3%` the
/// object reflects under 0.02% of the incident energy (`R² = ((Z−Z₀)/(Z+Z₀))²`,
/// Szabo, *Diagnostic Ultrasound Imaging*, eq. 3.40), it vanishes from the
/// image, and a calibration against data the model cannot match may end there.
/// The range is kept on the scene's side of the medium's impedance.
const IMPEDANCE_MARGIN: f64 = 0.03;

/// A base parameter the calibration fits: its key and, when the user gave one,
/// its range (`--params PATH=MIN:MAX`); without one the calibration's default
/// ([`calibration_spec`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FreeParam {
    /// The parameter.
    pub key: ParamKey,
    /// `[min, max]` as given, kept as is.
    pub range: Option<(f64, f64)>,
}

impl FreeParam {
    /// A parameter with the calibration's default range.
    pub fn new(key: ParamKey) -> Self {
        Self { key, range: None }
    }

    /// Parses `PATH` or `PATH=MIN:MAX` against `scene` (the CLI's `--params`).
    ///
    /// # Errors
    /// A path the scene lacks, or a malformed range.
    pub fn parse(text: &str, scene: &Scene) -> Result<Self, OptimError> {
        let spec = ParamSpec::parse(text, scene).map_err(|e| match e {
            ParamSpecError::Unknown { source, .. } => OptimError::Scene(source),
            e => OptimError::Param(e),
        })?;
        let range = text.contains('=').then_some((spec.min, spec.max));
        Ok(Self {
            key: spec.key,
            range,
        })
    }
}

/// The calibration's parameter spec for `free` at `scene`'s value: the range
/// given, else the default range ([`crate::default_range`]), except that an
/// object material's impedance keeps to the scene's side of the medium's
/// impedance, at least 3% from it (a target of nearly the medium's impedance
/// vanishes from the image).
///
/// ```
/// use usray_optim::{calibration_spec, FreeParam};
/// let scene = usray_transport::Scene::load("../../scenes/cylinder.toml").unwrap();
/// let z0 = scene.medium.impedance_mrayl;
/// let free = FreeParam::parse("materials.target.impedance_mrayl", &scene).unwrap();
/// let s = calibration_spec(&scene, &free).unwrap();
/// assert!(s.min >= 1.03 * z0 - 1e-12 && s.max > scene.get(&s.key).unwrap());
/// ```
///
/// # Errors
/// A parameter the scene lacks.
pub fn calibration_spec(scene: &Scene, free: &FreeParam) -> Result<ParamSpec, OptimError> {
    let value = scene.get(&free.key)?;
    if let Some((min, max)) = free.range {
        return Ok(ParamSpec {
            key: free.key.clone(),
            min,
            max,
        });
    }
    let mut spec = ParamSpec::around(free.key.clone(), value);
    let is_material_impedance =
        matches!(spec.key.owner, Owner::Material(_)) && spec.key.field == Field::Impedance;
    if is_material_impedance {
        let z0 = scene.medium.impedance_mrayl;
        if value > z0 {
            spec.min = spec.min.max((1.0 + IMPEDANCE_MARGIN) * z0).min(value);
        } else if value < z0 {
            spec.max = spec.max.min((1.0 - IMPEDANCE_MARGIN) * z0).max(value);
        }
    }
    Ok(spec)
}

/// The calibrated model at one ray count: the fit, its image on seed `s`, the
/// held-out evaluations and the noise level.
pub(crate) struct Stage {
    /// How this stage's losses are taken (the floor estimated at its
    /// calibration).
    pub setup: LossSetup,
    /// The calibration's objective, at the calibrated comparison.
    pub objective: Objective,
    /// The calibrated values of the free parameters, in the specs' order.
    pub params: Vec<f64>,
    /// The scene at those values.
    pub scene: Scene,
    /// Its evaluation on seed `s`.
    pub eval: Evaluation,
    /// Its evaluations on the held-out seeds.
    pub held: Vec<Evaluation>,
    /// Their losses, one per held-out seed.
    pub held_losses: Vec<f64>,
    /// Their mean.
    pub held_loss: f64,
    /// The Monte Carlo noise level ([`super::Diagnosis::noise_loss`]).
    pub noise_loss: f64,
    /// Render options of seed `s` at this stage's rays.
    pub render_s: RenderOptions,
    /// Render options of each held-out seed at this stage's rays.
    pub renders_held: Vec<RenderOptions>,
    /// Wall time of one model's held-out evaluation on one seed at this
    /// stage's rays, seconds: what a second look's renders cost
    /// ([`super::Confirmation`]).
    pub held_eval_s: f64,
}

/// How every loss of a diagnosis is taken: paired or not
/// ([`DiagnoseOptions::paired`]) and through which [`Comparison`] (the
/// smoothing of [`DiagnoseOptions::smoothing_wavelengths`] and, after the
/// calibration, the measurement's noise floor).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LossSetup {
    /// The paired loss ([`crate::Objective::pair_seeds`]).
    pub paired: bool,
    /// The comparison of the images ([`crate::Objective::comparison`]).
    pub comparison: Comparison,
}

impl LossSetup {
    /// The objective of `scene` against `measured` for `specs`, rendered with
    /// `render`, its loss taken this way.
    ///
    /// # Errors
    /// As [`Objective::new`].
    pub fn objective(
        &self,
        scene: Scene,
        measured: &[f64],
        specs: Vec<ParamSpec>,
        render: &RenderOptions,
    ) -> Result<Objective, OptimError> {
        Ok(
            Objective::new(scene, measured.to_vec(), specs, render.clone())?
                .with_pairing(self.paired)
                .with_comparison(self.comparison),
        )
    }
}

/// The smoothing of a diagnosis's comparison: a Gaussian of
/// [`DiagnoseOptions::smoothing_wavelengths`] wavelengths `λ = c/f_c` (the
/// medium's speed, the probe's centre frequency) on the scene's pixel grid.
pub fn diagnosis_smoothing(scene: &Scene, wavelengths: f64) -> Comparison {
    let wavelength_m = scene.medium.sound_speed_m_s / scene.probe.center_frequency_hz;
    Comparison::smoothing(wavelengths * wavelength_m, scene.imaging.pixel_m)
}

/// Calibrates `specs` of `scene` from `start` for `iters` iterations at `rays`,
/// then measures the held-out losses and the noise level (steps 1 and 4's
/// baseline).
#[allow(clippy::too_many_arguments)]
pub(crate) fn calibrate(
    scene: &Scene,
    measured: &[f64],
    held_data: &[f64],
    specs: &[ParamSpec],
    start: Option<&[f64]>,
    iters: usize,
    rays: usize,
    opts: &DiagnoseOptions,
    key: &str,
    timings: &mut Timings,
) -> Result<Stage, OptimError> {
    let seed = opts.render.seed.unwrap_or(scene.acquisition.seed);
    let render_s = RenderOptions {
        seed: Some(seed),
        rays_per_element: Some(rays),
        ..opts.render.clone()
    };
    let renders_held: Vec<RenderOptions> = (0..opts.held_out_seeds)
        .map(|j| RenderOptions {
            seed: Some(held_out_seed(seed, j)),
            ..render_s.clone()
        })
        .collect();
    let t = Instant::now();
    // The calibration compares smoothed images; the floor needs a calibrated
    // model to say where the scene is empty.
    let smoothing = diagnosis_smoothing(scene, opts.smoothing_wavelengths);
    let mut setup = LossSetup {
        paired: opts.paired,
        comparison: smoothing,
    };
    let mut objective = setup.objective(scene.clone(), measured, specs.to_vec(), &render_s)?;
    let x0 = start.map_or_else(|| objective.initial_physical(), <[f64]>::to_vec);
    let cal = fit_journaled(
        &mut objective,
        &x0,
        &FitOptions {
            iters,
            ..opts.fit.clone()
        },
        &opts.journal,
        key,
        |_| {},
    )?;
    let cal_scene = objective.scene_at(&cal.final_params)?;
    let mut eval = objective.value(&cal.final_params)?;
    if opts.noise_floor {
        let (nz, nx) = (eval.image.nz, eval.image.nx);
        setup.comparison.floor = noise_floor(
            &smoothing.smooth(&eval.image.data, nz, nx),
            &smoothing.smooth(measured, nz, nx),
        );
        objective.comparison = setup.comparison;
        eval = objective.value(&cal.final_params)?;
    }
    timings.calibration_s += t.elapsed().as_secs_f64();
    let t = Instant::now();
    let held = held_out(&cal_scene, held_data, &renders_held, &setup)?;
    let held_eval_s = t.elapsed().as_secs_f64() / renders_held.len().max(1) as f64;
    let held_losses: Vec<f64> = held.iter().map(|e| e.loss).collect();
    let held_loss = mean(&held_losses);
    // The noise level: the same loss with the calibrated model's own image (seed
    // s) in the place of the data.
    let noise_loss = if opts.paired {
        let own = held_out(&cal_scene, &eval.image.data, &renders_held, &setup)?;
        mean_loss(&own)
    } else {
        mean(
            &held
                .iter()
                .map(|e| objective.loss_between(&e.image, &eval.image))
                .collect::<Vec<_>>(),
        )
    };
    timings.held_out_s += t.elapsed().as_secs_f64();
    Ok(Stage {
        setup,
        objective,
        params: cal.final_params,
        scene: cal_scene,
        eval,
        held,
        held_losses,
        held_loss,
        noise_loss,
        render_s,
        renders_held,
        held_eval_s,
    })
}

/// Step 1 in full: calibrates `specs` of `scene` at the options' rays; then,
/// with a budget ([`DiagnoseOptions::budget_s`]), raises the rays while the
/// simulation's noise holds more of the gap than [`DiagnoseOptions::noise_share`]
/// and the budget, counted from `started`, affords the rest of the diagnosis
/// at the raised rays (its time estimated from the first calibration's). Each
/// raise recalibrates for half the iterations from the point reached. Returns
/// the last stage and its noise check.
pub(crate) fn calibrate_within_budget(
    scene: &Scene,
    measured: &[f64],
    held_data: &[f64],
    specs: &[ParamSpec],
    opts: &DiagnoseOptions,
    started: Instant,
    timings: &mut Timings,
    progress: &mut dyn FnMut(&str),
) -> Result<(Stage, NoiseCheck), OptimError> {
    let mut rays = opts
        .render
        .rays_per_element
        .unwrap_or(scene.acquisition.rays_per_element);
    progress(&format!(
        "calibrating {} parameter(s) at {rays} rays",
        specs.len()
    ));
    let t_stage = Instant::now();
    let mut stage = calibrate(
        scene,
        measured,
        held_data,
        specs,
        None,
        opts.calibration_iters,
        rays,
        opts,
        "calibration 0",
        timings,
    )?;
    // Time of a full-length calibration stage per ray (as first measured, on
    // a resumed run).
    let stage_s_per_ray = opts.journal.remember("calibration seconds per ray", || {
        Ok(t_stage.elapsed().as_secs_f64() / rays as f64)
    })?;
    let share = |s: &Stage| simulation_noise_share(s.noise_loss, s.held_loss);
    let mut history = vec![(rays, share(&stage), stage.noise_loss)];
    let check = |history: &[(usize, f64, f64)], stage: &Stage, rays: usize| {
        let exponent = match history {
            [.., (ra, _, na), (rb, _, nb)] => noise_exponent(*ra, *na, *rb, *nb),
            _ => None,
        }
        .unwrap_or(DEFAULT_NOISE_EXPONENT);
        let s = share(stage);
        let needed = rays_needed(
            rays,
            stage.noise_loss,
            stage.held_loss,
            opts.noise_share,
            exponent,
        );
        NoiseCheck {
            rays,
            share: s,
            target: opts.noise_share,
            passed: s <= opts.noise_share,
            rays_needed: needed,
            seconds_needed: needed.map(|r| DIAGNOSIS_OVER_CALIBRATION * stage_s_per_ray * r as f64),
            history: history.iter().map(|(r, s, _)| (*r, *s)).collect(),
        }
    };
    let mut noise_check = check(&history, &stage, rays);
    if let Some(budget) = opts.budget_s {
        for raise in 1..=MAX_RAY_RAISES {
            if noise_check.passed {
                break;
            }
            let Some(needed) = noise_check.rays_needed else {
                break;
            };
            let next = needed
                .min((MAX_RAY_FACTOR * rays as f64) as usize)
                .max(rays + 1);
            // A recalibration of half the iterations at `next`, then the rest.
            let cost = stage_s_per_ray * next as f64 * (0.5 + DIAGNOSIS_OVER_CALIBRATION - 1.0);
            // Decided on the wall clock, so kept for a resumed run.
            let affordable = opts
                .journal
                .remember(&format!("raise {raise} affordable"), || {
                    Ok(started.elapsed().as_secs_f64() + cost <= budget)
                })?;
            if !affordable {
                break;
            }
            progress(&format!(
                "simulation noise {:.0}% of the gap (target {:.0}%): recalibrating at {next} rays",
                100.0 * noise_check.share,
                100.0 * opts.noise_share
            ));
            rays = next;
            stage = calibrate(
                scene,
                measured,
                held_data,
                specs,
                Some(&stage.params),
                opts.calibration_iters.div_ceil(2),
                rays,
                opts,
                &format!("calibration {raise}"),
                timings,
            )?;
            history.push((rays, share(&stage), stage.noise_loss));
            noise_check = check(&history, &stage, rays);
        }
        if !noise_check.passed {
            // The budget buys no more rays: go on at these. An effect that
            // clears the held-out test can still be named; `none` cannot be
            // said at this noise (unnamed_verdict).
            progress(&format!(
                "simulation noise {:.0}% of the gap at {rays} rays, above the {:.0}% a `none` needs; the budget buys no more rays",
                100.0 * noise_check.share,
                100.0 * opts.noise_share
            ));
        }
    }
    Ok((stage, noise_check))
}
