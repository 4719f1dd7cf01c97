//! Shared pieces of `grad`, `fit` and `demo`: building the objective from the
//! command line, finite-difference sweeps, and the files a fit writes.

use crate::output::OutDir;
use crate::plots::{line_plot, overlay_png, Scale, Series};
use anyhow::{Context, Result};
use serde_json::{json, Map, Value};
use usray_optim::{fd_sweep, log_steps, FdPoint, FitOptions, FitResult, Objective, ParamSpec};
use usray_signal::io::write_bmode_png;
use usray_transport::Scene;

/// Parses `--params` entries (`PATH` or `PATH=MIN:MAX`) against `scene`: every path
/// must exist; a missing range takes [`usray_optim::default_range`] around the
/// current value.
pub fn parse_params(scene: &Scene, params: &[String]) -> Result<Vec<ParamSpec>> {
    let mut specs: Vec<ParamSpec> = Vec::new();
    for text in params {
        let path = text
            .split_once('=')
            .map_or(text.as_str(), |(p, _)| p)
            .trim();
        anyhow::ensure!(
            !path.is_empty(),
            "--params: empty entry in `{}` (expected PATH or PATH=MIN:MAX, comma-separated)",
            params.join(",")
        );
        let value = scene.get(path).with_context(|| {
            format!("--params: `{path}` is not a parameter of the scene (see `usray params SCENE`)")
        })?;
        let spec = ParamSpec::parse(text, value)?;
        anyhow::ensure!(
            !specs.iter().any(|s| s.path == spec.path),
            "--params: `{}` is named twice",
            spec.path
        );
        anyhow::ensure!(
            value >= spec.min && value <= spec.max,
            "--params: `{}` = {value} lies outside its range {}:{}",
            spec.path,
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

/// The default steps of an FD sweep for a parameter: eight steps from 10⁻² of its
/// range down to 10⁻⁹ of it, spaced by 10. Large steps show the truncation error
/// and the visibility jumps the gradient does not see (rays crossing an edge);
/// small ones the agreement with the fixed-seed derivative, down to round-off.
pub fn sweep_steps(spec: &ParamSpec) -> Vec<f64> {
    log_steps(1e-2 * (spec.max - spec.min), 10.0, 8)
}

/// Central finite differences of the fixed-seed objective along each parameter.
pub fn fd_sweeps(
    objective: &Objective,
    at: &[f64],
    mut tick: impl FnMut(),
) -> Result<Vec<Vec<FdPoint>>> {
    let mut out = Vec::new();
    for (j, spec) in objective.specs.iter().enumerate() {
        let mut err = None;
        let sweep = fd_sweep(
            |x: &[f64]| {
                tick();
                match objective.value(x) {
                    Ok(e) => e.loss,
                    Err(e) => {
                        err.get_or_insert(e);
                        f64::NAN
                    }
                }
            },
            at,
            j,
            &sweep_steps(spec),
        );
        if let Some(e) = err {
            return Err(e).with_context(|| format!("finite differences of {}", spec.path));
        }
        out.push(sweep);
    }
    Ok(out)
}

/// The FD point closest to the AD value (the sweep's best step) and its relative
/// difference `|FD − AD| / |AD|`.
pub fn best_fd(sweep: &[FdPoint], ad: f64) -> Option<(FdPoint, f64)> {
    sweep
        .iter()
        .filter(|p| p.fd.is_finite())
        .min_by(|a, b| (a.fd - ad).abs().total_cmp(&(b.fd - ad).abs()))
        .map(|p| (*p, (p.fd - ad).abs() / ad.abs().max(f64::MIN_POSITIVE)))
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
        g.insert(s.path.clone(), json!(v));
    }
    let mut fd = Map::new();
    if let Some(sweeps) = sweeps {
        for (s, sw) in specs.iter().zip(sweeps) {
            let pts: Vec<Value> = sw
                .iter()
                .map(|p| json!({"eps": p.eps, "fd": p.fd}))
                .collect();
            fd.insert(s.path.clone(), Value::Array(pts));
        }
    }
    json!({"loss": loss, "gradient": g, "fd": fd})
}

/// The paper's FD-vs-AD figures, per parameter: `fd_<path>.png` (FD and AD vs ε,
/// log ε) and `fd_error_<path>.png` (|FD − AD| vs ε, log–log). Returns the names.
pub fn write_sweep_plots(
    out: &OutDir,
    specs: &[ParamSpec],
    gradient: &[f64],
    sweeps: &[Vec<FdPoint>],
) -> Result<Vec<String>> {
    let mut names = Vec::new();
    for ((s, &ad), sw) in specs.iter().zip(gradient).zip(sweeps) {
        let a = format!("fd_{}.png", slug(&s.path));
        line_plot(
            &out.path(&a),
            &format!("{}: FD and AD vs ε", s.path),
            "ε (parameter units)",
            "∂L/∂θ",
            &[
                Series {
                    name: "central FD".into(),
                    points: sw.iter().map(|p| (p.eps, p.fd)).collect(),
                },
                Series {
                    name: "AD".into(),
                    points: sw.iter().map(|p| (p.eps, ad)).collect(),
                },
            ],
            Scale::Log,
            Scale::Linear,
        )?;
        let b = format!("fd_error_{}.png", slug(&s.path));
        line_plot(
            &out.path(&b),
            &format!("{}: |FD − AD| vs ε", s.path),
            "ε (parameter units)",
            "|g_FD − g_AD|",
            &[Series {
                name: "|FD − AD|".into(),
                points: sw.iter().map(|p| (p.eps, (p.fd - ad).abs())).collect(),
            }],
            Scale::Log,
            Scale::Log,
        )?;
        names.push(a);
        names.push(b);
    }
    Ok(names)
}

/// Everything a fit writes next to `fit.json`: images, overlays, plots,
/// `fitted.toml`. `initial`/`final_` are the B-modes at the start and the end.
pub fn write_fit_outputs(
    out: &OutDir,
    objective: &Objective,
    start: &[f64],
    result: &FitResult,
    options: &FitOptions,
    initial: &[f64],
    final_: &[f64],
) -> Result<()> {
    let (nz, nx) = objective.shape()?;
    let specs = &objective.specs;
    write_bmode_png(out.path("initial.png"), nz, nx, initial)?;
    write_bmode_png(out.path("final.png"), nz, nx, final_)?;
    write_bmode_png(out.path("reference.png"), nz, nx, &objective.reference)?;
    overlay_png(
        &out.path("overlay_initial.png"),
        nz,
        nx,
        initial,
        &objective.reference,
    )?;
    overlay_png(
        &out.path("overlay_final.png"),
        nz,
        nx,
        final_,
        &objective.reference,
    )?;
    let mut loss_pts: Vec<(f64, f64)> = result
        .history
        .iter()
        .map(|h| (h.iter as f64, h.loss))
        .collect();
    loss_pts.push((result.history.len() as f64, result.final_loss));
    line_plot(
        &out.path("loss.png"),
        "Loss (weighted ℓ1 + ℓ2)",
        "iteration",
        "loss",
        &[Series {
            name: "loss".into(),
            points: loss_pts,
        }],
        Scale::Linear,
        Scale::Log,
    )?;
    let series: Vec<Series> = specs
        .iter()
        .enumerate()
        .map(|(j, s)| {
            let mut points: Vec<(f64, f64)> = result
                .history
                .iter()
                .map(|h| (h.iter as f64, s.normalised(h.params[j])))
                .collect();
            points.push((
                result.history.len() as f64,
                s.normalised(result.final_params[j]),
            ));
            Series {
                name: s.path.clone(),
                points,
            }
        })
        .collect();
    line_plot(
        &out.path("params.png"),
        "Parameters, normalised to their ranges (θ − min)/(max − min)",
        "iteration",
        "normalised value",
        &series,
        Scale::Linear,
        Scale::Linear,
    )?;
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
            m.insert(s.path.clone(), json!(x));
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
        .map(|((s, a), b)| json!({"path": s.path, "min": s.min, "max": s.max, "initial": a, "final": b}))
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

/// Builds the objective of `grad`/`fit`: scene, reference, parameters, render
/// options. Everything is checked before anything is written.
pub fn build_objective(
    scene_path: &std::path::Path,
    reference: &std::path::Path,
    params: &[String],
    sampling: &crate::cli::Sampling,
    threads: usize,
) -> Result<Objective> {
    let scene = Scene::load(scene_path)?;
    let specs = parse_params(&scene, params)?;
    let opts = sampling.render_options(threads)?;
    let reference = usray_optim::load_reference(reference, &scene)?;
    Ok(Objective::new(scene, reference, specs, opts)?)
}
