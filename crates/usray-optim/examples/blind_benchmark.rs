//! The diagnosis's blind benchmark (issue 6, `docs/diagnosis.md`):
//!
//! ```text
//! cargo run --release -p usray-optim --example blind_benchmark -- SCENE DRAWS RAYS ITERS [OUT.json [SEED [KIND,...]]] [--paired] [--data-rays=N] [--noise-db=X] [--held-out-frame] [--params=P1,P2] [--sampler=stratified|independent] [--depth-gain=LO,HI] [--depth-gain-both-signs]
//! ```
//!
//! Renders `DRAWS` hidden draws from the base scene `SCENE` (kinds cycle through
//! the five catalogue effects, none, and one outside the catalogue; random
//! strength, seed and measurement noise: `usray_optim::blind`), diagnoses each
//! against the base scene with `RAYS` rays per element and `ITERS` iterations of
//! calibration and refits, and prints one line per draw and the summary. `SEED`
//! (default 2026) is the master seed of the draws: another seed, other draws.
//! `KIND,...` keeps only the draws of those kinds (e.g. `depth_gain`).
//! `--paired` diagnoses with the paired loss (`DiagnoseOptions::paired`).
//! `--data-rays=N` renders the measured data with `N` rays per element instead
//! of `RAYS` (less Monte Carlo noise in the data, as in a real measurement);
//! `--noise-db=X` sets the measurement noise, dB below the largest channel
//! sample (default 60). `--held-out-frame` measures every held-out loss against
//! a second frame of the draw's data (`usray_optim::blind::measured_frame`).
//! `--params=P1,P2` names the base model's free parameters (default: the
//! documented default set). `--sampler=NAME` sets the base scene's
//! `acquisition.sampler` (so both the data and the model use it).
//! `--depth-gain=LO,HI` draws the depth gains' magnitude from [LO, HI] dB/cm
//! (default 3,6), and `--depth-gain-both-signs` draws their sign too (the
//! default draws gains up with depth; `--depth-gain=1,2 --depth-gain-both-signs`
//! gives the draws of sessions 2–10).
//!
//! For each rightly named effect it also prints how far each parameter of the
//! named refit lies from the truth of the hidden scene, in units of its reported
//! spread (`params_std`): `z = (found − true) / std`. If the spread told the
//! whole error, `z` would have a root mean square near 1.

use usray_optim::blind::{
    draw, measured_frame, measured_image, verdict_is_false_effect, verdict_is_right, BlindOptions,
};
use usray_optim::{diagnose, DiagnoseOptions, FreeParam};
use usray_transport::scene::Sampler;
use usray_transport::{RenderOptions, Scene};

fn main() {
    // Options start with `--`; the rest are positional.
    let (options, args): (Vec<String>, Vec<String>) =
        std::env::args().skip(1).partition(|a| a.starts_with("--"));
    let flag = |name: &str| options.iter().any(|a| a == name);
    let paired = flag("--paired");
    // `--held-out-frame`: a second frame of each draw's data for the held-out losses.
    let held_out_frame = flag("--held-out-frame");
    // `--data-rays=N`: rays per element of the measured data (default RAYS).
    let data_rays: Option<usize> = option_value(&options, "--data-rays");
    // `--noise-db=X`: measurement noise, dB below the largest channel sample.
    let noise_db: Option<f64> = option_value(&options, "--noise-db");
    // `--params=P1,P2`: the base model's free parameters (default: the
    // documented default set, `usray_optim::default_free_params`).
    let free_params: Vec<String> = option_value::<String>(&options, "--params")
        .map(|p| p.split(',').map(str::to_string).collect())
        .unwrap_or_default();
    // `--depth-gain=LO,HI`: range of the depth-gain draws' magnitude, dB/cm
    // (`usray_optim::blind::draw` refuses a range that is not 0 <= LO <= HI).
    let depth_gain = option_value::<String>(&options, "--depth-gain").map(|v| {
        let r: Result<Vec<f64>, _> = v.split(',').map(str::parse).collect();
        match r.as_deref() {
            Ok(&[lo, hi]) => (lo, hi),
            _ => {
                eprintln!("--depth-gain takes two numbers LO,HI, found `{v}`");
                std::process::exit(2)
            }
        }
    });
    if args.len() < 4 {
        eprintln!(
            "usage: blind_benchmark SCENE DRAWS RAYS ITERS [OUT.json [SEED [KIND,...]]] [--paired] [--data-rays=N] [--noise-db=X] [--held-out-frame] [--params=P1,P2] [--sampler=stratified|independent] [--depth-gain=LO,HI] [--depth-gain-both-signs]"
        );
        std::process::exit(2);
    }
    let parse = |i: usize| -> usize {
        args[i].parse().unwrap_or_else(|_| {
            eprintln!(
                "argument {} must be a whole number, found `{}`",
                i + 1,
                args[i]
            );
            std::process::exit(2)
        })
    };
    let mut base = Scene::load(&args[0]).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    // `--sampler=NAME`: `acquisition.sampler` of the base scene (data and model).
    if let Some(sampler) = option_value::<Sampler>(&options, "--sampler") {
        base.acquisition.sampler = sampler;
    }
    let (draws, rays, iters) = (parse(1), parse(2), parse(3));
    let render = RenderOptions {
        rays_per_element: Some(rays),
        ..Default::default()
    };
    let mut bopts = BlindOptions {
        render: RenderOptions {
            rays_per_element: Some(data_rays.unwrap_or(rays)),
            ..Default::default()
        },
        noise_db: noise_db.unwrap_or(BlindOptions::default().noise_db),
        depth_gain_db_per_cm: depth_gain.unwrap_or(BlindOptions::default().depth_gain_db_per_cm),
        depth_gain_both_signs: flag("--depth-gain-both-signs"),
        ..Default::default()
    };
    if args.len() > 5 {
        bopts.seed = parse(5) as u64;
    }
    let free_params = free_params
        .iter()
        .map(|p| FreeParam::parse(p, &base))
        .collect::<Result<Vec<_>, _>>()
        .unwrap_or_else(|e| {
            eprintln!("--params: {e}");
            std::process::exit(2)
        });
    let dopts = DiagnoseOptions {
        free_params,
        calibration_iters: iters,
        refit_iters: iters,
        paired,
        render,
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let mut rows = Vec::new();
    let (mut right_effects, mut n_effects, mut false_effects) = (0, 0, 0);
    // z-scores of the named refits' parameters: (effect's own, base ones).
    let (mut z_effect, mut z_base) = (Vec::new(), Vec::new());
    let only: Option<Vec<&str>> = args.get(6).map(|k| k.split(',').collect());
    for i in 0..draws {
        if only.as_ref().is_some_and(|k| {
            !k.contains(&usray_optim::blind::KINDS[i % usray_optim::blind::KINDS.len()])
        }) {
            continue;
        }
        let result = draw(&base, i, &bopts)
            .and_then(|d| measured_image(&d, &bopts).map(|m| (d, m)))
            .and_then(|(d, m)| {
                let held = held_out_frame
                    .then(|| measured_frame(&d, 1, &bopts))
                    .transpose()?;
                let opts = DiagnoseOptions {
                    held_out_measured: held,
                    ..dopts.clone()
                };
                diagnose(&base, &m, &opts, |_| {}).map(|r| (d, r))
            });
        let (d, r) = match result {
            Ok(x) => x,
            Err(e) => {
                eprintln!("draw {i}: {e}");
                std::process::exit(1)
            }
        };
        let right = verdict_is_right(d.kind, &r.verdict.effect);
        let false_effect = verdict_is_false_effect(d.kind, &r.verdict.effect);
        if !["none", "outside"].contains(&d.kind) {
            n_effects += 1;
            right_effects += usize::from(right);
        }
        false_effects += usize::from(false_effect);
        let mut z_line = Vec::new();
        if right {
            if let Some(e) = r.effects.iter().find(|e| e.effect == r.verdict.effect) {
                for (p, found) in &e.params {
                    let (Ok(truth), Some(Some(std))) = (
                        d.scene.key(p).and_then(|k| d.scene.get(&k)),
                        e.params_std.get(p),
                    ) else {
                        continue;
                    };
                    let z = (found - truth) / std;
                    z_line.push(format!("{p} {found:.4e} (true {truth:.4e}) z {z:+.1}"));
                    if *p == e.path {
                        &mut z_effect
                    } else {
                        &mut z_base
                    }
                    .push(z);
                }
            }
        }
        let ranked: Vec<String> = r
            .effects
            .iter()
            .map(|e| {
                format!(
                    "{}:{:.2e}/{}/{}",
                    e.effect,
                    e.score,
                    e.shrink.map_or("-".into(), |s| format!("{s:.2}")),
                    e.excess.map_or("-".into(), |x| format!(
                        "{x:+.3}±{:.3}",
                        e.excess_std.unwrap_or(f64::NAN)
                    ))
                )
            })
            .collect();
        println!(
            "draw {i:2}: {:<17} strength {:+.4e}  verdict {:<17} shrink {:.2}  cal {:.3e} held {:.3e} noise {:.3e} null {:+.3}  {}  [{}]  {:.0} s",
            d.kind,
            d.strength,
            r.verdict.effect,
            r.verdict.shrink,
            r.calibrated.loss,
            r.calibrated.loss_held_out,
            r.noise_loss,
            r.null_refit.shrink,
            if right { "right" } else if false_effect { "FALSE EFFECT" } else { "wrong" },
            ranked.join(" "),
            r.timings.calibration_s
                + r.timings.scoring_s
                + r.timings.refits_s
                + r.timings.null_refit_s
                + r.timings.held_out_s
                + r.timings.spread_s
        );
        if !z_line.is_empty() {
            println!("         found: {}", z_line.join("; "));
        }
        rows.push(serde_json::json!({
            "draw": i, "kind": d.kind, "strength": d.strength, "seed": d.seed,
            "verdict": r.verdict.effect, "shrink": r.verdict.shrink, "right": right,
            "false_effect": false_effect, "diagnosis": r,
        }));
    }
    let summary = format!(
        "top-1 accuracy on effect draws {right_effects}/{n_effects}; false effects {false_effects}/{}; {:.0} s",
        rows.len(),
        t0.elapsed().as_secs_f64()
    );
    let rms = |z: &[f64]| (z.iter().map(|v| v * v).sum::<f64>() / z.len().max(1) as f64).sqrt();
    let within2 = |z: &[f64]| z.iter().filter(|v| v.abs() <= 2.0).count();
    let summary = format!(
        "{summary}; found − true in reported spreads: effect parameter rms z {:.2} ({}/{} within 2), base parameters rms z {:.2} ({}/{} within 2)",
        rms(&z_effect),
        within2(&z_effect),
        z_effect.len(),
        rms(&z_base),
        within2(&z_base),
        z_base.len()
    );
    println!("{summary}");
    if let Some(out) = args.get(4) {
        let v = serde_json::json!({ "summary": summary, "draws": rows });
        if let Err(e) = std::fs::write(out, serde_json::to_string_pretty(&v).unwrap_or_default()) {
            eprintln!("writing {out}: {e}");
            std::process::exit(1)
        }
    }
}

/// The value of option `NAME=VALUE` among `options`, parsed; exits with a
/// message naming the option when it does not parse.
fn option_value<T: std::str::FromStr>(options: &[String], name: &str) -> Option<T> {
    let prefix = format!("{name}=");
    options.iter().find_map(|a| {
        a.strip_prefix(&prefix).map(|v| {
            v.parse().unwrap_or_else(|_| {
                eprintln!("{name} cannot take `{v}`");
                std::process::exit(2)
            })
        })
    })
}
