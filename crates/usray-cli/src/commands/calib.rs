//! Shared pieces of `grad`, `fit` and `demo`: building the objective from the
//! command line, and the files a fit and a gradient check write (the
//! finite-difference sweeps themselves are `usray_optim::fd_sweeps`).

use crate::output::OutDir;
use crate::plots::{
    bmode_figure, line_figure, overlay_figure, param_name, param_unit, Axis, Grid, Panel, Scale,
    Series,
};
use anyhow::{Context, Result};
use serde_json::{json, Map, Value};
use usray_optim::{FdPoint, FitOptions, FitResult, Objective, ParamSpec, ParamSpecError};
use usray_signal::io::write_bmode_npy;
use usray_transport::Scene;

/// Parses `--params` entries (`PATH` or `PATH=MIN:MAX`) against `scene`: every path
/// must exist; a missing range takes [`usray_optim::default_range`] around the
/// current value.
pub fn parse_params(scene: &Scene, params: &[String]) -> Result<Vec<ParamSpec>> {
    let mut specs: Vec<ParamSpec> = Vec::new();
    for text in params {
        let spec = ParamSpec::parse(text, scene).map_err(|e| match e {
            ParamSpecError::Unknown { path, .. } if path.is_empty() => anyhow::anyhow!(
                "--params: empty entry in `{}` (expected PATH or PATH=MIN:MAX, comma-separated)",
                params.join(",")
            ),
            ParamSpecError::Unknown { path, source } => {
                anyhow::Error::new(source).context(format!(
                    "--params: `{path}` is not a parameter of the scene (see `usray params SCENE`)"
                ))
            }
            e => e.into(),
        })?;
        let value = scene.get(&spec.key)?;
        anyhow::ensure!(
            !specs.iter().any(|s| s.key == spec.key),
            "--params: `{}` is named twice",
            spec.key
        );
        anyhow::ensure!(
            value >= spec.min && value <= spec.max,
            "--params: `{}` = {value} lies outside its range {}:{}",
            spec.key,
            spec.min,
            spec.max
        );
        specs.push(spec);
    }
    Ok(specs)
}

/// A file-name-safe form of a parameter path.
pub fn slug(path: &str) -> String {
    path.replace(['.', '/'], "_")
}

/// `grad.json` exactly as CONTRACT §4.
pub fn grad_json(
    loss: f64,
    specs: &[ParamSpec],
    gradient: &[f64],
    sweeps: Option<&[Vec<FdPoint>]>,
) -> Value {
    let mut g = Map::new();
    for (s, v) in specs.iter().zip(gradient) {
        g.insert(s.key.to_string(), json!(v));
    }
    let mut fd = Map::new();
    if let Some(sweeps) = sweeps {
        for (s, sw) in specs.iter().zip(sweeps) {
            let pts: Vec<Value> = sw
                .iter()
                .map(|p| json!({"eps": p.eps, "fd": p.fd}))
                .collect();
            fd.insert(s.key.to_string(), Value::Array(pts));
        }
    }
    json!({"loss": loss, "gradient": g, "fd": fd})
}

/// The paper's FD-vs-AD figures, per parameter: `fd_<path>.png` (FD and AD vs ε,
/// log ε) and `fd_error_<path>.png` (|FD − AD| vs ε, log–log), in the units
/// the parameter is shown in ([`param_unit`]). Returns the names.
pub fn write_sweep_plots(
    out: &OutDir,
    specs: &[ParamSpec],
    gradient: &[f64],
    sweeps: &[Vec<FdPoint>],
) -> Result<Vec<String>> {
    let mut names = Vec::new();
    for ((s, &ad), sw) in specs.iter().zip(gradient).zip(sweeps) {
        let path = s.key.to_string();
        let unit = param_unit(&path);
        let per_unit = if unit.name == "dimensionless" {
            "dimensionless".to_string()
        } else {
            format!("1/{}", unit.name)
        };
        let step_label = format!("step ε ({})", unit.name);
        let step = Axis {
            label: &step_label,
            scale: Scale::Log,
        };
        // ∂L/∂θ per shown unit: the loss is dimensionless.
        let shown = |g: f64| g / unit.per_si;
        let a = format!("fd_{}.png", slug(&path));
        line_figure(
            &out.path(&a),
            &format!("{path}: FD and AD vs ε"),
            &[Panel {
                caption: "",
                x: step,
                y: Axis {
                    label: &format!("∂L/∂θ ({per_unit})"),
                    scale: Scale::Linear,
                },
                series: &[
                    Series {
                        name: "central FD".into(),
                        points: sw
                            .iter()
                            .map(|p| (p.eps * unit.per_si, shown(p.fd)))
                            .collect(),
                        truth: None,
                    },
                    Series {
                        name: "AD".into(),
                        points: sw
                            .iter()
                            .map(|p| (p.eps * unit.per_si, shown(ad)))
                            .collect(),
                        truth: None,
                    },
                ],
            }],
        )?;
        let b = format!("fd_error_{}.png", slug(&path));
        line_figure(
            &out.path(&b),
            &format!("{path}: |FD − AD| vs ε"),
            &[Panel {
                caption: "",
                x: step,
                y: Axis {
                    label: &format!("|FD − AD| ({per_unit})"),
                    scale: Scale::Log,
                },
                series: &[Series {
                    name: "|FD − AD|".into(),
                    points: sw
                        .iter()
                        .map(|p| (p.eps * unit.per_si, shown((p.fd - ad).abs())))
                        .collect(),
                    truth: None,
                }],
            }],
        )?;
        names.push(a);
        names.push(b);
    }
    Ok(names)
}

/// Writes a B-mode as `NAME.npy` (the data, float32 `[nz, nx]`) and `NAME.png`
/// (its figure: mm axes, dB colour bar, `title`).
pub fn write_bmode_files(
    out: &OutDir,
    name: &str,
    grid: &Grid,
    data: &[f64],
    dynamic_range_db: f64,
    title: &str,
) -> Result<()> {
    write_bmode_npy(out.path(&format!("{name}.npy")), grid.nz, grid.nx, data)?;
    bmode_figure(
        &out.path(&format!("{name}.png")),
        grid,
        data,
        dynamic_range_db,
        title,
    )
}

/// Everything a fit writes next to `fit.json`: images (figure and data),
/// overlays, plots, `fitted.toml`. `initial`/`final_` are the B-modes at the
/// start and the end; `truth` holds each parameter's true value where known
/// (drawn as dashed lines in `params.png`).
pub fn write_fit_outputs(
    out: &OutDir,
    objective: &Objective,
    start: &[f64],
    result: &FitResult,
    options: &FitOptions,
    initial: &[f64],
    final_: &[f64],
    truth: &[Option<f64>],
) -> Result<()> {
    let settings = objective.scene.imaging_settings();
    let grid = Grid::from_settings(&settings)?;
    let db = settings.dynamic_range_db;
    write_bmode_files(
        out,
        "initial",
        &grid,
        initial,
        db,
        "Initial: the start parameters",
    )?;
    write_bmode_files(
        out,
        "final",
        &grid,
        final_,
        db,
        "Final: the fitted parameters",
    )?;
    write_bmode_files(
        out,
        "reference",
        &grid,
        &objective.reference,
        db,
        "Reference",
    )?;
    overlay_figure(
        &out.path("overlay_initial.png"),
        &grid,
        initial,
        &objective.reference,
        "Initial",
    )?;
    overlay_figure(
        &out.path("overlay_final.png"),
        &grid,
        final_,
        &objective.reference,
        "Final",
    )?;
    write_history_plots(out, objective, result, truth)?;
    let fitted = objective.scene_at(&result.final_params)?;
    let toml = fitted.to_toml_string();
    // The writer must round-trip: parse it back and compare.
    let back = Scene::from_toml_str(&toml, "fitted.toml", fitted.base_dir.clone())
        .context("internal: fitted.toml does not parse back")?;
    let mut cmp = fitted.clone();
    cmp.source = back.source.clone();
    anyhow::ensure!(
        back == cmp,
        "internal: fitted.toml does not round-trip the fitted scene"
    );
    out.write_text("fitted.toml", &toml)?;
    out.write_json("fit.json", &fit_json(objective, start, result, options))?;
    Ok(())
}

/// `loss.png` (loss per iteration, log scale) and `params.png` (one panel per
/// parameter, in its unit, with its true value dashed where known). Iteration
/// `len(history)` is the final point.
fn write_history_plots(
    out: &OutDir,
    objective: &Objective,
    result: &FitResult,
    truth: &[Option<f64>],
) -> Result<()> {
    let iteration = Axis {
        label: "iteration",
        scale: Scale::Count,
    };
    let last = result.history.len() as f64;
    let mut loss_pts: Vec<(f64, f64)> = result
        .history
        .iter()
        .map(|h| (h.iter as f64, h.loss))
        .collect();
    loss_pts.push((last, result.final_loss));
    line_figure(
        &out.path("loss.png"),
        "Loss (weighted ℓ1 + ℓ2 of the grey levels, per pixel)",
        &[Panel {
            caption: "",
            x: iteration,
            y: Axis {
                label: "loss (dimensionless)",
                scale: Scale::Log,
            },
            series: &[Series {
                name: "loss".into(),
                points: loss_pts,
                truth: None,
            }],
        }],
    )?;
    let specs = &objective.specs;
    let paths: Vec<String> = specs.iter().map(|s| s.key.to_string()).collect();
    let labels: Vec<String> = paths
        .iter()
        .map(|p| format!("{} ({})", param_name(p), param_unit(p).name))
        .collect();
    let series: Vec<[Series; 1]> = paths
        .iter()
        .enumerate()
        .map(|(j, p)| {
            let per_si = param_unit(p).per_si;
            let mut points: Vec<(f64, f64)> = result
                .history
                .iter()
                .map(|h| (h.iter as f64, h.params[j] * per_si))
                .collect();
            points.push((last, result.final_params[j] * per_si));
            [Series {
                name: "fit".into(),
                points,
                truth: truth.get(j).copied().flatten().map(|t| t * per_si),
            }]
        })
        .collect();
    let panels: Vec<Panel> = paths
        .iter()
        .zip(&labels)
        .zip(&series)
        .map(|((path, label), series)| Panel {
            caption: path,
            x: iteration,
            y: Axis {
                label,
                scale: Scale::Linear,
            },
            series,
        })
        .collect();
    line_figure(&out.path("params.png"), "Parameters per iteration", &panels)
}

/// `fit.json`: parameters with ranges, `history` (loss and every parameter per
/// iteration), `final`.
pub fn fit_json(
    objective: &Objective,
    start: &[f64],
    result: &FitResult,
    options: &FitOptions,
) -> Value {
    let specs = &objective.specs;
    let named = |v: &[f64]| -> Value {
        let mut m = Map::new();
        for (s, x) in specs.iter().zip(v) {
            m.insert(s.key.to_string(), json!(x));
        }
        Value::Object(m)
    };
    let history: Vec<Value> = result
        .history
        .iter()
        .map(|h| {
            json!({"iter": h.iter, "loss": h.loss, "params": named(&h.params),
                   "grad_norm": h.grad_norm, "seconds": h.seconds})
        })
        .collect();
    let params: Vec<Value> = specs
        .iter()
        .zip(start)
        .zip(&result.final_params)
        .map(|((s, a), b)| json!({"path": s.key.to_string(), "min": s.min, "max": s.max, "initial": a, "final": b}))
        .collect();
    let initial_loss = result.history.first().map_or(f64::NAN, |h| h.loss);
    json!({
        "params": params,
        "history": history,
        "final": {
            "loss": result.final_loss,
            "params": named(&result.final_params),
            "iterations": result.history.len(),
            "loss_drop_factor": initial_loss / result.final_loss,
            "seconds": result.seconds,
        },
        "options": {
            "iters": options.iters,
            "lr_material": options.lr_material,
            "lr_geometry": options.lr_geometry,
            "lr_acquisition": options.lr_acquisition,
            "lr_final_fraction": options.lr_final_fraction,
            "clip_factor": options.clip_factor,
            "resample_seed": options.resample_seed,
            "rays_per_element": objective.opts.rays_per_element.unwrap_or(objective.scene.acquisition.rays_per_element),
            "seed": objective.opts.seed.unwrap_or(objective.scene.acquisition.seed),
            "transmit_batches": objective.transmit_batches,
            "paired_seed": objective.paired_seed,
        }
    })
}

/// A progress bar of `len` steps on stderr (hidden with `--quiet`).
pub fn progress_bar(quiet: bool, len: u64, prefix: &str) -> indicatif::ProgressBar {
    let bar = if quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(len)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:30}] {pos}/{len} {msg} [{elapsed}, eta {eta}]",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar.set_prefix(prefix.to_string());
    bar
}

/// The scene at `scene_path` for a comparison with the measured data at
/// `reference`: traced in the dimensions those data declare when the scene
/// leaves them unset ([`usray_optim::follow_declared_dimensions`]), and at
/// absolute levels as `levels` asks ([`usray_optim::compare_absolute_levels`]).
/// Each sentence saying what was done is printed to standard error; the
/// dimensions' is returned for the report (which reads the levels from the
/// scene).
///
/// # Errors
/// `--levels absolute` where the data are not in the renders' unit (saying
/// why), and what loading the scene or reading the data refuses.
pub fn load_scene_for(
    scene_path: &std::path::Path,
    reference: &std::path::Path,
    levels: crate::cli::Levels,
) -> Result<(Scene, Option<String>)> {
    use crate::cli::Levels;
    use usray_optim::AbsoluteLevels;
    let mut scene = Scene::load(scene_path)?;
    let note = usray_optim::follow_declared_dimensions(&mut scene, reference)?;
    if let Some(note) = &note {
        eprintln!("usray: {note}");
    }
    if levels != Levels::Relative {
        match usray_optim::compare_absolute_levels(&mut scene, reference)? {
            AbsoluteLevels::Set(sentence) => eprintln!("usray: {sentence}"),
            AbsoluteLevels::NotApplicable(why) if levels == Levels::Absolute => {
                anyhow::bail!("--levels absolute: {why}")
            }
            AbsoluteLevels::NotApplicable(_) => {}
        }
    }
    Ok((scene, note))
}

/// Builds the objective of `grad`/`fit`: scene, reference, parameters, render
/// options. Everything is checked before anything is written.
pub fn build_objective(
    scene_path: &std::path::Path,
    reference: &std::path::Path,
    params: &[String],
    levels: crate::cli::Levels,
    sampling: &crate::cli::Sampling,
    threads: usize,
) -> Result<Objective> {
    let (scene, _) = load_scene_for(scene_path, reference, levels)?;
    let specs = parse_params(&scene, params)?;
    let opts = sampling.render_options(threads)?;
    let reference = usray_optim::load_reference(reference, &scene)?;
    Ok(Objective::new(scene, reference, specs, opts)?)
}
