//! The diagnosis's report from the library (`usray_optim::Report`): the files
//! `usray diagnose` writes, from a Rust caller, on a tiny scene.

use std::path::Path;
use usray_optim::{
    diagnose, diagnose_compound, grid_shape, Confirmation, DiagnoseOptions, Diagnosis, FirstRound,
    OptimError, Report, VerdictRule,
};
mod common;
use common::tiny_scene;
use usray_transport::{RenderOptions, Scene};

/// Data from the same scene with a longer pulse (5 cycles for the model's 3),
/// and the options of a quick diagnosis.
fn tiny_case() -> (Scene, Vec<f64>, DiagnoseOptions) {
    let scene = tiny_scene();
    let mut truth = scene.clone();
    truth.set(&"probe.cycles".parse().unwrap(), 5.0).unwrap();
    let render = RenderOptions {
        rays_per_element: Some(10),
        ..Default::default()
    };
    let (nz, nx) = grid_shape(&scene).unwrap();
    // The objective's reference is unused here: only the image is wanted.
    let measured = usray_optim::Objective::new(truth, vec![0.0; nz * nx], vec![], render)
        .unwrap()
        .value(&[])
        .unwrap()
        .image
        .data;
    let opts = DiagnoseOptions {
        calibration_iters: 2,
        refit_iters: 2,
        confirm_top: 1,
        held_out_seeds: 2,
        spread_pairs: 1,
        render: RenderOptions {
            rays_per_element: Some(5),
            ..Default::default()
        },
        ..Default::default()
    };
    (scene, measured, opts)
}

/// [`tiny_case`] and the two rounds of its quick diagnosis.
fn diagnosed() -> (Scene, Vec<f64>, Vec<Diagnosis>) {
    let (scene, measured, opts) = tiny_case();
    let rounds = diagnose_compound(&scene, &measured, &opts, 2, |_| {}).unwrap();
    (scene, measured, rounds)
}

/// A later round stops after its calibration when its time, estimated from
/// that calibration as many times over as the first round's whole time was
/// over its own, is more than the budget it was given; within it, it runs.
#[test]
fn a_later_round_stops_after_its_calibration_when_it_would_overrun_its_budget() {
    let (scene, measured, opts) = tiny_case();
    let later = |seconds_over_calibration| DiagnoseOptions {
        first_round: Some(FirstRound {
            scores: Default::default(),
            loss_held_out: 1.0,
            seconds_over_calibration,
        }),
        budget_s: Some(600.0),
        ..opts.clone()
    };
    match diagnose(&scene, &measured, &later(1e12), |_| {}) {
        Err(OptimError::Budget {
            message,
            estimate_s,
        }) => {
            assert!(message.contains("more than the 600 s left"), "{message}");
            assert!(estimate_s > 600.0, "{estimate_s}");
        }
        other => panic!("a round estimated at 1e12 times its calibration ran: {other:?}"),
    }
    // Estimated at its calibration's own time, well within 600 s: it completes.
    diagnose(&scene, &measured, &later(1.0), |_| {}).unwrap();
}

/// A refit that would be named but for its first look's standard error over
/// the seeds is rendered again with the control on fresh seeds, and the
/// seeds' test decided there; where the budget left cannot pay for that, the
/// verdict cannot be `none`.
#[test]
fn a_borderline_refit_is_measured_again_on_fresh_seeds() {
    let (scene, measured, opts) = tiny_case();
    let opts = DiagnoseOptions {
        confirmation_seeds: 4,
        ..opts
    };
    let first = diagnose(&scene, &measured, &opts, |_| {}).unwrap();
    let refitted = |d: &Diagnosis| {
        d.effects
            .iter()
            .find(|e| e.excess.is_some())
            .cloned()
            .expect("the quick diagnosis refits one candidate")
    };
    let e1 = refitted(&first);
    let (x1, se1) = (e1.excess.unwrap(), e1.excess_std.unwrap());
    let z1 = x1 / se1;
    assert!(
        z1 > 0.0 && !e1.at_range_bound() && !e1.within_tolerance() && !e1.indistinct_from_null(),
        "premise: a refit that gains and passes the tests other than significance: {e1:?}"
    );
    // A rule that puts this first look in the borderline band (and passes
    // the blocks' test, which is not what is tested here).
    let rule = VerdictRule {
        borderline_z: 0.5 * z1,
        min_excess_z: 2.0 * z1,
        min_spatial_z: 0.0,
        ..opts.rule
    };
    let forced = DiagnoseOptions { rule, ..opts };
    let second = diagnose(&scene, &measured, &forced, |_| {}).unwrap();
    let e2 = refitted(&second);
    // The first look is untouched by the second: same seeds, same bits.
    assert_eq!((e2.excess, e2.excess_std), (e1.excess, e1.excess_std));
    let Some(Confirmation::Measured {
        seeds,
        excess,
        excess_std: Some(se2),
        ..
    }) = e2.confirmation
    else {
        panic!("no second look measured: {:?}", e2.confirmation);
    };
    assert_eq!(seeds, 4);
    // Both looks estimate the same excess on independent seeds.
    assert!(
        (excess - x1).abs() <= 4.0 * (se1 * se1 + se2 * se2).sqrt(),
        "first look {x1:+.4} ± {se1:.4}, second {excess:+.4} ± {se2:.4}"
    );
    // Named only if the fresh seeds alone pass the seeds' test.
    assert_eq!(
        second.verdict.effect == e2.effect,
        excess >= rule.min_excess_z * se2,
        "{:?}",
        second.verdict
    );
    // Without the budget for the second look: recorded, and `inconclusive`
    // (the first look alone is below the bar, so nothing is named).
    let short = DiagnoseOptions {
        budget_s: Some(1e-3),
        ..forced
    };
    let third = diagnose(&scene, &measured, &short, |_| {}).unwrap();
    let e3 = refitted(&third);
    match e3.confirmation {
        Some(Confirmation::OverBudget {
            seeds: 4,
            estimate_s,
            left_s,
        }) => assert!(estimate_s > left_s, "{estimate_s} within {left_s}"),
        other => panic!("a second look without the budget for it: {other:?}"),
    }
    assert_eq!(third.verdict.effect, "inconclusive");
    let md = markdown_of(&scene, &measured, std::slice::from_ref(&third));
    assert!(md.contains("Rerun with a budget about"), "{md}");
}

/// A compound round starts only where the budget left pays for a round as
/// long as the last; the report says why it did not run.
#[test]
fn no_compound_round_starts_without_the_budget_for_it() {
    let (scene, measured, opts) = tiny_case();
    // A budget shorter than any round: the first runs (it always does, at the
    // rays given), the second does not start.
    let opts = DiagnoseOptions {
        budget_s: Some(1e-3),
        ..opts
    };
    let rounds = diagnose_compound(&scene, &measured, &opts, 2, |_| {}).unwrap();
    assert_eq!(rounds.len(), 1);
    // The first round named an effect, so a second was wanted.
    assert!(
        rounds[0].after_scene.is_some(),
        "the quick diagnosis names an effect"
    );
    let why = rounds[0].next_round_stopped.as_deref().unwrap();
    assert!(
        why.starts_with("round 2 stopped: the budget left, 0 s, is less than the last round took"),
        "{why}"
    );
    // The advice: a budget, in tens of seconds, of at least twice the first
    // round's time (the time already spent and as much again).
    let advised: f64 = why
        .split("`--budget ")
        .nth(1)
        .and_then(|t| t.split('`').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no budget advised: {why}"));
    assert!(
        advised % 10.0 == 0.0 && advised >= 2.0 * rounds[0].timings.total_s,
        "{why}"
    );
    assert!(why.ends_with("would let it start"), "{why}");
    let md = markdown_of(&scene, &measured, &rounds);
    assert!(md.contains("Round 2 stopped: the budget left"), "{md}");
}

/// The Markdown report of `rounds` of `tiny.toml` against `measured.npy`.
fn markdown_of(scene: &Scene, measured: &[f64], rounds: &[Diagnosis]) -> String {
    Report {
        rounds,
        scene,
        scene_path: Path::new("tiny.toml"),
        measured_path: Path::new("measured.npy"),
        measured,
        wall_s: 1.0,
        dimensions_note: None,
    }
    .markdown()
    .unwrap()
}

/// `Report::write` writes exactly `markdown()` and the pretty-printed `json()`;
/// the JSON holds CONTRACT §5's keys in order and one summary per round, and
/// the Markdown names the files and the verdict.
#[test]
fn report_writes_markdown_and_json_of_every_round() {
    let (scene, measured, rounds) = diagnosed();
    let report = Report {
        rounds: &rounds,
        scene: &scene,
        scene_path: Path::new("tiny.toml"),
        measured_path: Path::new("measured.npy"),
        measured: &measured,
        wall_s: 1.5,
        dimensions_note: None,
    };
    let dir = tempfile::tempdir().unwrap();
    report.write(dir.path()).unwrap();
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    let json = std::fs::read_to_string(dir.path().join("diagnosis.json")).unwrap();
    assert_eq!(md, report.markdown().unwrap());
    assert_eq!(
        json,
        serde_json::to_string_pretty(&report.json().unwrap()).unwrap()
    );

    let first = &rounds[0];
    assert!(
        md.starts_with(&format!(
            "# usray diagnose: `tiny.toml` against `measured.npy`\n\n## Verdict: **{}**\n",
            first.verdict.effect
        )),
        "{md}"
    );
    for section in [
        "## 1. Calibrated base model",
        "## 2. Where the residual lies",
        "## 3–4. Candidate effects",
        "## Time\n\n1.5 s in all;",
    ] {
        assert!(md.contains(section), "no `{section}` in\n{md}");
    }
    // Every candidate has its row in the table.
    for e in &first.effects {
        assert!(md.contains(&format!("| {} | `{}` |", e.effect, e.path)));
    }

    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
    assert_eq!(
        keys,
        [
            "calibrated",
            "where",
            "effects",
            "null_refit",
            "rule",
            "verdict",
            "noise_loss",
            "noise_check",
            "spread_pairs",
            "held_out_seeds",
            "paired",
            "comparison",
            "held_out_frames",
            "max_bounces",
            "timings",
            "residual_kinds",
            "wall_seconds",
            "dimensions",
            "dimensions_from_data",
            "reference_amplitude",
            "rounds",
        ]
    );
    assert_eq!(v["wall_seconds"], 1.5);
    // A scene that leaves its dimensions unset, compared with a B-mode: 3-D.
    assert_eq!(v["dimensions"], 3);
    assert!(v["dimensions_from_data"].is_null());
    assert!(v["reference_amplitude"].is_null());
    // The cylinder is solid, so a wall is a candidate and every model renders
    // at two bounces more than the scene's; the report says so.
    assert_eq!(v["max_bounces"], scene.acquisition.max_bounces + 2);
    assert!(
        md.contains(&format!(
            "rendered at **{} bounces**, the scene's {}",
            scene.acquisition.max_bounces + 2,
            scene.acquisition.max_bounces
        )),
        "{md}"
    );
    assert_eq!(v["verdict"]["effect"], first.verdict.effect.as_str());
    assert_eq!(v["rounds"].as_array().unwrap().len(), rounds.len());
    for (r, d) in v["rounds"].as_array().unwrap().iter().zip(&rounds) {
        assert_eq!(r["verdict"]["effect"], d.verdict.effect.as_str());
        assert_eq!(r["loss_held_out"], d.calibrated.loss_held_out);
        assert_eq!(r["effects"].as_array().unwrap().len(), d.effects.len());
    }
    // Only a later round tests whether its effects add to the first round's.
    assert!(rounds[0].effects.iter().all(|e| e.additivity.is_none()));
}

/// A report of no rounds, or against a measured image of another size, is an
/// error that says so, not a panic.
#[test]
fn report_refuses_no_rounds_and_a_measured_image_off_the_grid() {
    let (scene, measured, rounds) = diagnosed();
    let none = Report {
        rounds: &[],
        scene: &scene,
        scene_path: Path::new("tiny.toml"),
        measured_path: Path::new("measured.npy"),
        measured: &measured,
        wall_s: 0.0,
        dimensions_note: None,
    };
    let err = none.markdown().unwrap_err().to_string();
    assert!(err.contains("at least one round"), "{err}");
    assert!(none.json().is_err());
    let short = Report {
        rounds: &rounds,
        measured: &measured[1..],
        ..none
    };
    let err = short.markdown().unwrap_err().to_string();
    assert!(err.starts_with("diagnosis:"), "{err}");
    assert!(
        short.json().is_ok(),
        "the JSON does not read the measured image"
    );
}

/// A verdict that names nothing lists the refits it passed over because they
/// ended within their tolerance of the model's value although their gain was
/// significant, and only those.
#[test]
fn report_lists_significant_refits_within_their_tolerance() {
    let (scene, measured, mut rounds) = diagnosed();
    rounds.truncate(1);
    let d = &mut rounds[0];
    d.verdict.effect = "none".into();
    d.verdict.path = None;
    let e = &mut d.effects[0];
    let path = e.path.clone();
    (e.null, e.tolerance) = (Some(1.0), Some(0.1));
    (e.excess, e.excess_std, e.excess_spatial_std) = (Some(0.08), Some(0.004), Some(0.015));
    let markdown = |rounds: &[Diagnosis]| markdown_of(&scene, &measured, rounds);
    const HEAD: &str = "**Significant, but too small to matter:**";

    rounds[0].effects[0].params.insert(path.clone(), 1.05);
    let md = markdown(&rounds);
    assert!(md.contains(HEAD), "{md}");
    assert!(
        md.contains(&format!(
            "(`{path}`) gained +0.080 ± 0.004 (± 0.015 over the image)"
        )),
        "{md}"
    );
    // Beyond its tolerance it is not passed over for that reason.
    rounds[0].effects[0].params.insert(path.clone(), 1.2);
    assert!(!markdown(&rounds).contains(HEAD));
    // Within it, but a gain the image's blocks do not share: no gain to explain.
    rounds[0].effects[0].params.insert(path.clone(), 1.05);
    rounds[0].effects[0].excess_spatial_std = Some(0.05);
    assert!(!markdown(&rounds).contains(HEAD));
}

/// Section 1 sets each calibrated parameter beside the scene's value, and
/// points out those the calibration moved by more than a tenth, only those.
#[test]
fn report_points_out_calibrated_parameters_far_from_the_scene() {
    let (scene, measured, mut rounds) = diagnosed();
    rounds.truncate(1);
    let markdown = |rounds: &[Diagnosis]| markdown_of(&scene, &measured, rounds);
    const HEAD: &str = "**Far from your scene's value:**";
    let path = rounds[0].calibrated.params.keys().next().unwrap().clone();
    let given = scene.get(&scene.key(&path).unwrap()).unwrap();
    assert!(given != 0.0, "{path} = 0");
    for (p, _) in rounds[0].calibrated.params.clone() {
        let g = scene.get(&scene.key(&p).unwrap()).unwrap();
        rounds[0].calibrated.params.insert(p, g);
    }
    let md = markdown(&rounds);
    assert!(!md.contains(HEAD), "{md}");
    assert!(
        md.contains(&format!("| `{path}` | {given:.6e} | {given:.6e} | +0% |")),
        "{md}"
    );

    rounds[0]
        .calibrated
        .params
        .insert(path.clone(), 1.5 * given);
    let md = markdown(&rounds);
    assert!(md.contains(HEAD), "{md}");
    assert!(
        md.contains(&format!("`{path}` {given:.3} → {:.3} (+50%)", 1.5 * given)),
        "{md}"
    );
    // A tenth or less is not pointed out.
    rounds[0]
        .calibrated
        .params
        .insert(path.clone(), 1.09 * given);
    assert!(!markdown(&rounds).contains(HEAD));
}
