//! `usray diagnose SCENE --measured REF`: calibrate, locate the residual, rank and
//! confirm candidate effects, verdict (CONTRACT §4–5; `usray_optim::diagnose`).
//! The library diagnoses and writes the report (`usray_optim::Report`); this
//! command reads the arguments and data, and draws the figures.

use crate::cli::{Common, Sampling};
use crate::output::{spinner, OutDir};
use crate::plots::{residual_figure, Grid};
use anyhow::Result;
use std::path::Path;
use usray_optim::{diagnose_compound, DiagnoseOptions, Report};

/// Settings of `usray diagnose`.
pub struct DiagnoseArgs {
    /// Free parameters of the base model (empty = the documented default set).
    pub params: Vec<String>,
    /// Iterations of the calibration and of each refit.
    pub iters: usize,
    /// Candidates confirmed by a refit.
    pub confirm: usize,
    /// Rays, seed and sampler.
    pub sampling: Sampling,
    /// Held-out seeds averaged over.
    pub held_out_seeds: usize,
    /// The paired loss throughout.
    pub paired: bool,
    /// Measured data held out from the fit (other frames).
    pub held_out_measured: Option<std::path::PathBuf>,
    /// Fit the even frames of multi-frame channel data, hold out the odd ones.
    pub held_out_frames: bool,
    /// Time budget, seconds (`DiagnoseOptions::budget_s`).
    pub budget_s: Option<f64>,
    /// Rounds of the compound-gap diagnosis, at least 1.
    pub rounds: usize,
    /// Smoothing of the comparison, wavelengths (`DiagnoseOptions::smoothing_wavelengths`).
    pub smoothing_wavelengths: f64,
    /// Floor the images at the measurement's noise level.
    pub noise_floor: bool,
    /// `--levels`.
    pub levels: crate::cli::Levels,
    /// Continue from the checkpoint in `--out`.
    pub resume: bool,
}

/// Name of a diagnosis's checkpoint in its `--out`.
const CHECKPOINT: &str = "diagnose.checkpoint.json";

/// Runs the diagnosis and writes `diagnosis.json`, `report.md` and the images.
pub fn run(scene_path: &Path, measured: &Path, args: &DiagnoseArgs, common: &Common) -> Result<()> {
    let (scene, dimensions_note) = super::calib::load_scene_for(scene_path, measured, args.levels)?;
    anyhow::ensure!(args.iters >= 1, "--iters must be at least 1");
    anyhow::ensure!(args.rounds >= 1, "--rounds must be at least 1");
    anyhow::ensure!(
        args.smoothing_wavelengths.is_finite()
            && (0.0..=10.0).contains(&args.smoothing_wavelengths),
        "--smoothing must be between 0 and 10 wavelengths, got {}",
        args.smoothing_wavelengths
    );
    anyhow::ensure!(
        args.held_out_seeds >= 1,
        "--held-out-seeds must be at least 1"
    );
    // Validates every named parameter against the scene before any work.
    super::calib::parse_params(&scene, &args.params)?;
    let held_out_measured = args
        .held_out_measured
        .as_deref()
        .map(|p| usray_optim::load_reference(p, &scene))
        .transpose()?;
    let (measured_img, held_out_measured, measured_channels) = if args.held_out_frames {
        let (fit, held) = usray_optim::load_reference_frames(measured, &scene)?;
        (fit, Some(held), None)
    } else if is_channel_file(measured) {
        // Read once: the image is beamformed from the channels, which the
        // diagnosis keeps to check a centre-frequency refit against their spectra.
        let channels = usray_signal::read_channels(measured)?;
        let img = usray_optim::reference_from_channels(&channels, &scene)?;
        let channels = usray_optim::MeasuredChannels(std::sync::Arc::new(channels));
        (img, held_out_measured, Some(channels))
    } else {
        let img = usray_optim::load_reference(measured, &scene)?;
        (img, held_out_measured, None)
    };
    let opts = DiagnoseOptions {
        free_params: args
            .params
            .iter()
            .map(|p| usray_optim::FreeParam::parse(p, &scene))
            .collect::<std::result::Result<Vec<_>, _>>()?,
        calibration_iters: args.iters,
        refit_iters: args.iters,
        confirm_top: args.confirm,
        held_out_seeds: args.held_out_seeds,
        paired: args.paired,
        held_out_measured,
        render: args.sampling.render_options(common.threads)?,
        budget_s: args.budget_s,
        smoothing_wavelengths: args.smoothing_wavelengths,
        noise_floor: args.noise_floor,
        measured_channels,
        ..Default::default()
    };
    // The calibration and the refits (the null and each confirmed candidate),
    // twice over with the paired loss, and the held-out renders of each model.
    let fits = (args.iters * (args.confirm + 2)) as f64 * if args.paired { 2.0 } else { 1.0 };
    let held_out = (args.held_out_seeds * (args.confirm + 3)) as f64;
    crate::work::confirm_work(fits + held_out, &scene, &opts.render, common.yes)?;
    let mut out = OutDir::create(&common.out)?;
    // Everything that determines the results: the options (their journal is
    // still the default, holding no path), the scene, the data, the rounds.
    let journal = out.journal(
        CHECKPOINT,
        &[&scene, &measured_img, &opts, &args.rounds],
        args.resume,
    )?;
    let opts = DiagnoseOptions { journal, ..opts };
    let bar = spinner(common.quiet, "diagnose");
    let t0 = std::time::Instant::now();
    let rounds = diagnose_compound(&scene, &measured_img, &opts, args.rounds, |msg| {
        bar.set_message(msg.to_string())
    })?;
    bar.finish_and_clear();
    let wall = t0.elapsed().as_secs_f64();
    let d = &rounds[0];
    let report = Report {
        rounds: &rounds,
        scene: &scene,
        scene_path,
        measured_path: measured,
        measured: &measured_img,
        wall_s: wall,
        dimensions_note: dimensions_note.as_deref(),
    };
    out.write_json("diagnosis.json", &report.json()?)?;
    let settings = scene.imaging_settings();
    let grid = Grid::from_settings(&settings)?;
    let db = settings.dynamic_range_db;
    let bmode = |name: &str, data: &[f64], title: &str| {
        super::calib::write_bmode_files(&out, name, &grid, data, db, title)
    };
    bmode("measured", &measured_img, "Measured")?;
    bmode("calibrated", &d.calibrated_image, "Calibrated model")?;
    bmode("after", &d.after_image, "After the verdict's refit")?;
    residual_figure(
        &out.path("residual_calibrated.png"),
        &grid,
        &d.calibrated_image,
        &measured_img,
        db,
        "Residual of the calibrated model",
    )?;
    residual_figure(
        &out.path("residual_after.png"),
        &grid,
        &d.after_image,
        &measured_img,
        db,
        "Residual after the verdict's refit",
    )?;
    out.write_text("report.md", &report.markdown()?)?;
    out.finish()?;
    let named: Vec<&str> = rounds.iter().map(|r| r.verdict.effect.as_str()).collect();
    eprintln!(
        "usray diagnose: verdict {} (held-out shrink {:.2}){}; simulation noise {:.0}% of the gap at {} rays; {:.1} s; wrote diagnosis.json, report.md and images to {}",
        d.verdict.effect,
        d.verdict.shrink,
        if rounds.len() > 1 {
            format!(", then {}", named[1..].join(", then "))
        } else {
            String::new()
        } + &rounds
            .last()
            .and_then(|r| r.next_round_stopped.as_ref())
            .map(|why| format!(" ({why})"))
            .unwrap_or_default(),
        100.0 * d.noise_check.share,
        d.noise_check.rays,
        wall,
        common.out.display()
    );
    Ok(())
}

/// Whether `measured` is a channel-data file (`.json`, CONTRACT §2), whose
/// channels the diagnosis keeps beside the image it beamforms from them.
fn is_channel_file(measured: &Path) -> bool {
    measured
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}
