//! `usray grad` / `usray fit` from the outside: file shapes and bad inputs.

use std::path::Path;
use std::process::Command;

const CYLINDER: &str = include_str!("../../../scenes/cylinder.toml");

/// A tiny cylinder scene (16 elements, one angle, 20 rays, 0.4 mm grid).
fn tiny_scene(dir: &Path) -> std::path::PathBuf {
    let mut text = CYLINDER
        .replace("n_elements = 128", "n_elements = 16")
        .replace(
            "angles_deg = [-10.0, -5.0, 0.0, 5.0, 10.0]",
            "angles_deg = [0.0]",
        )
        .replace("rays_per_element = 200", "rays_per_element = 20")
        .replace("rays_per_element = 1000", "rays_per_element = 20")
        .replace("x_range_m = [-0.015, 0.015]", "x_range_m = [-0.004, 0.004]")
        .replace("z_range_m = [0.002, 0.028]", "z_range_m = [0.008, 0.02]")
        .replace("pixel_m = 0.1e-3", "pixel_m = 0.4e-3");
    text.push('\n');
    let p = dir.join("tiny.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// [`tiny_scene`] in `dir` and its rendered B-mode (`dir/ref/bmode.npy`).
fn tiny_scene_and_reference(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let scene = tiny_scene(dir);
    let refdir = dir.join("ref");
    let o = usray(&[
        "render",
        scene.to_str().unwrap(),
        "--out",
        refdir.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (scene, refdir.join("bmode.npy"))
}

fn usray(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_usray"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn grad_writes_contract_json_and_bad_inputs_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, reference) = tiny_scene_and_reference(dir.path());
    let s = scene.to_str().unwrap();
    let r = reference.to_str().unwrap();

    // grad.json exactly as CONTRACT §4.
    let out = dir.path().join("g");
    let o = usray(&[
        "grad",
        s,
        "--reference",
        r,
        "--params",
        "objects.cylinder.radius_m=0.0045:0.0055,materials.target.roughness",
        "--fd-sweep",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("grad.json")).unwrap()).unwrap();
    let keys: Vec<&String> = v.as_object().unwrap().keys().collect();
    assert_eq!(keys, ["loss", "gradient", "fd"]);
    assert!(v["loss"].as_f64().unwrap().is_finite());
    for p in ["objects.cylinder.radius_m", "materials.target.roughness"] {
        assert!(v["gradient"][p].as_f64().unwrap().is_finite());
        let sweep = v["fd"][p].as_array().unwrap();
        // Eight steps from 10⁻² of the range down to 10⁻⁹ of it, spaced by 10.
        assert_eq!(sweep.len(), 8);
        let eps: Vec<f64> = sweep.iter().map(|e| e["eps"].as_f64().unwrap()).collect();
        assert!(eps.windows(2).all(|w| (w[0] / w[1] - 10.0).abs() < 1e-9));
        assert!(sweep.iter().all(|e| e["fd"].as_f64().is_some()));
        assert!(out.join(format!("fd_{}.png", p.replace('.', "_"))).exists());
    }

    // Bad inputs: one line on stderr, non-zero exit, nothing written.
    let bad_out = dir.path().join("bad");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["--params", "objects.cylinder.nope"],
            "objects.cylinder.nope",
        ),
        (
            vec!["--params", "objects.cylinder.radius_m=0.006:0.004"],
            "empty",
        ),
        (
            vec!["--params", "objects.cylinder.radius_m=a:b"],
            "not a finite number",
        ),
        (
            vec!["--params", "objects.cylinder.radius_m=0.004"],
            "PATH=MIN:MAX",
        ),
    ];
    for (extra, needle) in cases {
        let mut args = vec![
            "grad",
            s,
            "--reference",
            r,
            "--out",
            bad_out.to_str().unwrap(),
        ];
        args.extend(extra);
        let o = usray(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success());
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(needle), "{err}");
        assert!(!bad_out.exists(), "files written on bad input: {err}");
    }
    // Reference shape mismatch: a B-mode of another grid.
    let wrong = dir.path().join("wrong.npy");
    usray::write_npy(&wrong);
    for cmd in ["grad", "fit"] {
        let o = usray(&[
            cmd,
            s,
            "--reference",
            wrong.to_str().unwrap(),
            "--params",
            "objects.cylinder.radius_m",
            "--out",
            bad_out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success());
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(
            err.contains("differs from the scene's imaging grid"),
            "{err}"
        );
        assert!(!bad_out.exists());
    }
}

#[test]
fn fit_writes_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let s = scene.to_str().unwrap();
    let refdir = dir.path().join("ref");
    assert!(
        usray(&["render", s, "--out", refdir.to_str().unwrap(), "--quiet"])
            .status
            .success()
    );
    // render: the raw B-mode (one pixel per grid point: 21 × 31 on the tiny
    // grid) and its figure, as PNG and SVG.
    let raw = image::open(refdir.join("bmode.png")).unwrap();
    assert_eq!((raw.width(), raw.height()), (21, 31));
    let figure = image::open(refdir.join("bmode_figure.png")).unwrap();
    assert!(figure.width() >= 600, "{} px wide", figure.width());
    let svg = std::fs::read_to_string(refdir.join("bmode_figure.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    // A true value for a parameter that is not fitted is refused.
    let bad = usray(&[
        "fit",
        s,
        "--reference",
        refdir.join("channels.json").to_str().unwrap(),
        "--params",
        "materials.target.roughness=0.1:0.9",
        "--truth",
        "objects.cylinder.radius_m=0.005",
        "--out",
        dir.path().join("bad").to_str().unwrap(),
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--truth"));
    let out = dir.path().join("f");
    let o = usray(&[
        "fit",
        s,
        "--reference",
        refdir.join("channels.json").to_str().unwrap(),
        "--params",
        "materials.target.roughness=0.1:0.9",
        "--truth",
        "materials.target.roughness=0.5",
        "--iters",
        "3",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "fit.json",
        "fitted.toml",
        "initial.png",
        "initial.npy",
        "final.png",
        "final.npy",
        "reference.png",
        "reference.npy",
        "overlay_initial.png",
        "overlay_final.png",
        "loss.png",
        "params.png",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("fit.json")).unwrap()).unwrap();
    let h = v["history"].as_array().unwrap();
    assert_eq!(h.len(), 3);
    assert!(h[0]["loss"].as_f64().is_some());
    assert!(h[0]["params"]["materials.target.roughness"]
        .as_f64()
        .is_some());
    assert!(v["final"]["loss"].as_f64().is_some());
    // Only the outputs, no temporary files left behind.
    assert!(std::fs::read_dir(&out).unwrap().all(|e| !e
        .unwrap()
        .file_name()
        .to_string_lossy()
        .starts_with('.')));
}

mod usray {
    /// A float64 NPY `[3, 4]` of zeros (the wrong shape for any test grid).
    pub fn write_npy(path: &std::path::Path) {
        let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 4), }";
        let mut h = header.to_string();
        while (10 + h.len() + 1) % 64 != 0 {
            h.push(' ');
        }
        h.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend_from_slice(&(h.len() as u16).to_le_bytes());
        bytes.extend_from_slice(h.as_bytes());
        bytes.extend(std::iter::repeat_n(0u8, 12 * 8));
        std::fs::write(path, bytes).unwrap();
    }
}

/// Renders `scene` with `seed` into `dir/ref` (the reference of a test) and
/// returns that directory.
fn rendered(dir: &Path, scene: &str, seed: u64) -> std::path::PathBuf {
    render_into(&dir.join("ref"), scene, seed)
}

/// `usray render SCENE --seed SEED --out OUT`; returns `OUT`.
fn render_into(out: &Path, scene: &str, seed: u64) -> std::path::PathBuf {
    let o = usray(&[
        "render",
        scene,
        "--seed",
        &seed.to_string(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out.to_path_buf()
}

/// `usray diagnose` of the tiny scene, quick (2 iterations, 5 rays, one
/// refit), into `out`, with the `extra` arguments (`--measured` among them).
fn diagnose_tiny(scene: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "diagnose",
        scene,
        "--iters",
        "2",
        "--confirm",
        "1",
        "--rays",
        "5",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ];
    args.extend_from_slice(extra);
    usray(&args)
}

/// `usray diagnose` writes every output; `diagnosis.json` gives each fitted
/// parameter its spread (`params_std`) and each refit's shrink its standard
/// error, and `report.md` shows them and the kinds of residual as tables (not
/// debug output). `--paired` and `--held-out-seeds` are honoured.
#[test]
fn diagnose_writes_report_with_parameter_spreads() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let s = scene.to_str().unwrap();
    let refdir = rendered(dir.path(), s, 7);
    let out = dir.path().join("d");
    let bmode = refdir.join("bmode.npy");
    let o = diagnose_tiny(s, &out, &["--measured", bmode.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "diagnosis.json",
        "report.md",
        "measured.png",
        "measured.npy",
        "calibrated.png",
        "calibrated.npy",
        "after.png",
        "after.npy",
        "residual_calibrated.png",
        "residual_after.png",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("diagnosis.json")).unwrap())
            .unwrap();
    // The default comparison is the paper's pixel-wise one: no smoothing, no floor.
    assert_eq!(v["comparison"]["sigma_z_px"], 0.0, "{}", v["comparison"]);
    assert_eq!(v["comparison"]["floor"], 0.0, "{}", v["comparison"]);
    let params = v["calibrated"]["params"].as_object().unwrap();
    let stds = v["calibrated"]["params_std"].as_object().unwrap();
    assert_eq!(
        params.keys().collect::<Vec<_>>(),
        stds.keys().collect::<Vec<_>>()
    );
    // The radius is always seen by the image: a positive, finite spread.
    let r_std = stds["objects.cylinder.radius_m"].as_f64().unwrap();
    assert!(r_std > 0.0 && r_std < 1e-3, "radius spread {r_std}");
    let refitted: Vec<&serde_json::Value> = v["effects"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["shrink"].is_f64())
        .collect();
    // `--confirm 1`: the best-scoring candidate, and the medium's sound
    // speed, refitted whatever its score.
    let speed = |e: &&serde_json::Value| e["effect"] == "sound_speed";
    assert!(refitted.iter().any(speed), "the sound speed is refitted");
    assert!(refitted.len() <= 2, "{} refits", refitted.len());
    assert!(refitted[0]["params_std"]
        .as_object()
        .unwrap()
        .contains_key(refitted[0]["path"].as_str().unwrap()));
    assert!(v["timings"]["spread_s"].as_f64().unwrap() > 0.0);
    // The one-render loss and six held-out seeds by default: the refit's
    // shrink and its excess over the null refit carry standard errors, and
    // every held-out loss is listed seed by seed.
    assert_eq!(v["paired"].as_bool(), Some(false));
    assert_eq!(v["held_out_seeds"].as_u64(), Some(6));
    for key in ["shrink_std", "excess", "excess_std"] {
        assert!(refitted[0][key].is_f64(), "{key} missing");
    }
    for losses in [
        &refitted[0]["held_out_losses"],
        &v["calibrated"]["held_out_losses"],
        &v["null_refit"]["held_out_losses"],
    ] {
        assert_eq!(losses.as_array().map(Vec::len), Some(6));
    }
    assert!(v["null_refit"]["shrink"].is_f64());
    // Each effect states its null; the one refitted here (it has a null and a
    // spread) its limit of detection, three spreads.
    let path = refitted[0]["path"].as_str().unwrap();
    assert!(v["effects"]
        .as_array()
        .unwrap()
        .iter()
        .all(|e| e.get("null").is_some() && e.get("detection_limit").is_some()));
    assert!(refitted[0]["null"].is_f64(), "{}", refitted[0]);
    let limit = refitted[0]["detection_limit"].as_f64().unwrap();
    let spread = refitted[0]["params_std"][path].as_f64().unwrap();
    assert!(
        (limit - 3.0 * spread).abs() <= 1e-12 * limit,
        "{limit} vs {spread}"
    );
    assert_eq!(v["rule"]["min_excess_z"].as_f64(), Some(3.0));
    assert_eq!(v["rule"]["min_spatial_z"].as_f64(), Some(3.0));
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for needle in [
        "± (Monte Carlo spread)",
        "| echo position in |",
        "| texture in |",
        "| excess | gap explained | limit of detection |",
    ] {
        assert!(report.contains(needle), "report.md lacks `{needle}`");
    }
    assert!(
        !report.contains("EchoPosition {"),
        "debug output in report.md"
    );
    // The calibrated impedance comes with its mirror Z₁²/Z (water's 1.54 MRayl
    // around the cylinder), which a B-mode barely tells from it.
    let z = params["materials.target.impedance_mrayl"].as_f64().unwrap();
    let mirror = format!("its mirror `Z₁²/Z` = {:.3} MRayl", 1.54 * 1.54 / z);
    assert!(report.contains(&mirror), "report.md lacks `{mirror}`");
    // Without a named effect the report says what the data cannot rule out.
    let named = usray_optim::names_an_effect(v["verdict"]["effect"].as_str().unwrap());
    assert_eq!(
        report.contains("What these data cannot rule out"),
        !named,
        "verdict {}",
        v["verdict"]
    );
    let out1 = dir.path().join("d1");
    let o = diagnose_tiny(
        s,
        &out1,
        &[
            "--measured",
            bmode.to_str().unwrap(),
            "--paired",
            "--held-out-seeds",
            "1",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out1.join("diagnosis.json")).unwrap())
            .unwrap();
    assert_eq!(v["paired"].as_bool(), Some(true));
    assert_eq!(v["held_out_seeds"].as_u64(), Some(1));
    // One held-out seed gives no standard error.
    assert!(v["effects"]
        .as_array()
        .unwrap()
        .iter()
        .all(|e| e["shrink_std"].is_null()));
    // Settings that leave nothing to measure are refused, naming the flag.
    let o = usray(&[
        "diagnose",
        s,
        "--measured",
        refdir.join("bmode.npy").to_str().unwrap(),
        "--held-out-seeds",
        "0",
        "--out",
        dir.path().join("d0").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--held-out-seeds"));
    assert!(
        !dir.path().join("d0").exists(),
        "output written before refusing"
    );
}

/// `usray fit --paired` fits the paired loss and records its second seed.
#[test]
fn fit_paired_records_its_second_seed() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let s = scene.to_str().unwrap();
    let refdir = rendered(dir.path(), s, 3);
    let out = dir.path().join("f");
    let o = usray(&[
        "fit",
        s,
        "--reference",
        refdir.join("bmode.npy").to_str().unwrap(),
        "--params",
        "materials.target.roughness=0.1:0.9",
        "--iters",
        "2",
        "--paired",
        "--seed",
        "5",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("fit.json")).unwrap()).unwrap();
    assert_eq!(
        v["options"]["paired_seed"].as_u64(),
        Some(5 + usray_optim::PAIRED_SEED_OFFSET)
    );
    assert!(v["final"]["loss"].as_f64().is_some());
}

/// `--held-out-frames` fits the even frames of multi-frame channel data and
/// measures every held-out loss against the odd ones; `--held-out-measured`
/// names the held-out data directly, and given the odd frame's own file it
/// gives the same held-out losses bit for bit. Without held-out data the
/// losses differ. Inputs that cannot be split are refused, saying why.
#[test]
fn diagnose_holds_out_measured_frames() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let s = scene.to_str().unwrap();
    let frame = |seed: u64| {
        render_into(&dir.path().join(format!("frame{seed}")), s, seed).join("channels.json")
    };
    let (a, b) = (frame(7), frame(8));
    // Two frames in one file: `a` tagged frame 0, `b` frame 1.
    let (ca, cb) = (
        usray_signal::read_channels(&a).unwrap(),
        usray_signal::read_channels(&b).unwrap(),
    );
    let mut two = ca.clone();
    let tag = |t: &usray_signal::TransmitMeta, f: u64| {
        let mut t = t.clone();
        t.extra.insert("frame".into(), f.into());
        t
    };
    two.meta.transmits = ca
        .meta
        .transmits
        .iter()
        .map(|t| tag(t, 0))
        .chain(cb.meta.transmits.iter().map(|t| tag(t, 1)))
        .collect();
    two.samples.extend_from_slice(&cb.samples);
    let two_path = dir.path().join("two.json");
    usray_signal::io::write_channels(&two_path, &two).unwrap();
    let diagnose_with = |out: &str, extra: &[&str]| {
        let out = dir.path().join(out);
        let mut args = vec!["--held-out-seeds", "2"];
        args.extend_from_slice(extra);
        let o = diagnose_tiny(s, &out, &args);
        (out, o)
    };
    let run = |out: &str, extra: &[&str]| -> serde_json::Value {
        let (out, o) = diagnose_with(out, extra);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_str(&std::fs::read_to_string(out.join("diagnosis.json")).unwrap()).unwrap()
    };
    let split = run(
        "split",
        &[
            "--measured",
            two_path.to_str().unwrap(),
            "--held-out-frames",
        ],
    );
    let named = run(
        "named",
        &[
            "--measured",
            a.to_str().unwrap(),
            "--held-out-measured",
            b.to_str().unwrap(),
        ],
    );
    let fitted_only = run("fitted", &["--measured", a.to_str().unwrap()]);
    assert_eq!(split["held_out_frames"].as_bool(), Some(true));
    assert_eq!(fitted_only["held_out_frames"].as_bool(), Some(false));
    let losses = |v: &serde_json::Value| v["calibrated"]["held_out_losses"].clone();
    assert_eq!(losses(&split), losses(&named));
    assert_eq!(
        split["null_refit"]["held_out_losses"],
        named["null_refit"]["held_out_losses"]
    );
    assert_ne!(losses(&split), losses(&fitted_only));
    // What cannot be split.
    let refused = |extra: &[&str], needle: &str| {
        let (_, o) = diagnose_with("refused", extra);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(needle),
            "{extra:?}: {err}"
        );
    };
    refused(
        &["--measured", a.to_str().unwrap(), "--held-out-frames"],
        "at least two frames",
    );
    let bmode = a.with_file_name("bmode.npy");
    refused(
        &["--measured", bmode.to_str().unwrap(), "--held-out-frames"],
        "multi-frame channel data",
    );
    refused(
        &[
            "--measured",
            a.to_str().unwrap(),
            "--held-out-measured",
            dir.path().join("missing.npy").to_str().unwrap(),
        ],
        "missing.npy",
    );
}

/// `--sampler stratified` renders exactly what the scene key
/// `acquisition.sampler = "stratified"` does, and other data than the default
/// independent sampler; `--rays 0` is refused before anything is written.
#[test]
fn sampler_flag_equals_the_scene_key() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let s = scene.to_str().unwrap();
    let keyed = dir.path().join("keyed.toml");
    let text = std::fs::read_to_string(&scene).unwrap().replace(
        "emission = \"plane_wave\"",
        "emission = \"plane_wave\"\nsampler = \"independent\"",
    );
    assert!(text.contains("sampler = \"independent\""));
    std::fs::write(&keyed, text).unwrap();
    let render = |scene: &str, out: &str, extra: &[&str]| -> Vec<u8> {
        let out = dir.path().join(out);
        let mut args = vec!["render", scene, "--out", out.to_str().unwrap(), "--quiet"];
        args.extend_from_slice(extra);
        let o = usray(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(out.join("channels.npy")).unwrap()
    };
    let flag = render(s, "flag", &["--sampler", "independent"]);
    let key = render(keyed.to_str().unwrap(), "key", &[]);
    let default = render(s, "default", &[]);
    assert_eq!(
        flag, key,
        "--sampler independent differs from the scene key"
    );
    let info: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("flag/render.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(info["sampler"], "independent");
    let info: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("default/render.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(info["sampler"], "stratified", "the default sampler");
    assert_ne!(flag, default, "the independent sampler changed nothing");
    let keyed_back = render(
        keyed.to_str().unwrap(),
        "back",
        &["--sampler", "stratified"],
    );
    assert_eq!(
        keyed_back, default,
        "--sampler stratified does not override the key"
    );
    let out = dir.path().join("zero");
    let o = usray(&["render", s, "--rays", "0", "--out", out.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--rays must be at least 1"));
    assert!(!out.exists(), "--rays 0 left {out:?} behind");
    let o = usray(&[
        "render",
        s,
        "--sampler",
        "sobol",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("stratified"));
}

/// `usray fit` killed (SIGKILL) midway and continued with `--resume DIR` writes
/// the same fit as a run never interrupted (issue 23); a resume with other
/// arguments is refused.
#[test]
fn fit_killed_and_resumed_matches_an_uninterrupted_fit() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, reference) = tiny_scene_and_reference(dir.path());
    let start = dir.path().join("start.toml");
    std::fs::write(
        &start,
        std::fs::read_to_string(&scene)
            .unwrap()
            .replace("radius_m = 0.005", "radius_m = 0.0046"),
    )
    .unwrap();
    let args = |out: &Path| -> Vec<String> {
        [
            "fit",
            start.to_str().unwrap(),
            "--reference",
            reference.to_str().unwrap(),
            "--params",
            "objects.cylinder.radius_m,materials.target.roughness",
            "--iters",
            "60",
            "--threads",
            "1",
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ]
        .iter()
        .map(|a| a.to_string())
        .collect()
    };
    let whole = dir.path().join("whole");
    let o = Command::new(env!("CARGO_BIN_EXE_usray"))
        .args(args(&whole))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // Kill a second run once its checkpoint holds a few iterations.
    let cut = dir.path().join("cut");
    let mut child = Command::new(env!("CARGO_BIN_EXE_usray"))
        .args(args(&cut))
        .spawn()
        .unwrap();
    let checkpoint = cut.join("fit.checkpoint.json");
    let kept = || -> usize {
        std::fs::read_to_string(&checkpoint)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| {
                v["entries"]["fit.progress"]["history"]
                    .as_array()
                    .map(Vec::len)
            })
            .unwrap_or(0)
    };
    let t = std::time::Instant::now();
    while kept() < 3 && t.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    let status = child.wait().unwrap();
    let n = kept();
    assert!(
        !status.success() && (3..60).contains(&n),
        "the run was to be killed midway: {status}, {n} iterations kept"
    );
    assert!(
        !cut.join("fit.json").exists(),
        "a killed run wrote its results"
    );

    // Other arguments: refused, naming the cause.
    let mut other = args(&cut);
    other[7] = "59".into();
    other.push("--resume".into());
    other.push(cut.to_str().unwrap().into());
    let o = Command::new(env!("CARGO_BIN_EXE_usray"))
        .args(&other)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("another scene, data or options"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );

    let mut resume = args(&cut);
    resume.push("--resume".into());
    resume.push(cut.to_str().unwrap().into());
    let o = Command::new(env!("CARGO_BIN_EXE_usray"))
        .args(&resume)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fit_json = |d: &Path| -> serde_json::Value {
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("fit.json")).unwrap()).unwrap();
        // Wall-clock times differ; everything else must not.
        v["final"].as_object_mut().unwrap().remove("seconds");
        for h in v["history"].as_array_mut().unwrap() {
            h.as_object_mut().unwrap().remove("seconds");
        }
        v
    };
    assert_eq!(fit_json(&cut), fit_json(&whole));
    assert!(
        !checkpoint.exists(),
        "the checkpoint outlived the finished fit"
    );
    assert_eq!(
        std::fs::read(cut.join("fitted.toml")).unwrap(),
        std::fs::read(whole.join("fitted.toml")).unwrap()
    );
}

/// A run whose work estimate passes the threshold is refused before any work,
/// naming the estimate and `--yes`; `--rays` past the scene limit is refused
/// naming the key (it ran until killed).
#[test]
fn work_past_the_estimate_needs_yes_and_rays_past_the_limit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, reference) = tiny_scene_and_reference(dir.path());
    let s = scene.to_str().unwrap();
    let out = dir.path().join("big");
    let t = std::time::Instant::now();
    let o = usray(&[
        "fit",
        s,
        "--reference",
        reference.to_str().unwrap(),
        "--params",
        "objects.cylinder.radius_m",
        "--rays",
        "100000",
        "--iters",
        "10000",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("1.6e10 rays") && e.contains("--yes"), "{e}");
    assert!(t.elapsed().as_secs() < 30, "refused only after work");
    assert!(!out.exists(), "a refused run created its --out");

    let o = usray(&[
        "render",
        s,
        "--rays",
        "1000000000000",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("acquisition.rays_per_element"), "{e}");
}

/// Beamforming past the delay-and-sum estimate (pixels × records) needs `--yes`,
/// refused before the work: 4096 elements × 4 transmits onto 1.2·10⁷ pixels
/// (2·10¹¹ terms).
#[test]
fn beamforming_past_the_estimate_needs_yes() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("fine.toml");
    std::fs::write(
        &scene,
        CYLINDER.replace("pixel_m = 0.1e-3", "pixel_m = 0.8e-5"),
    )
    .unwrap();
    let meta: usray_signal::ChannelMeta = serde_json::from_value(serde_json::json!({
        "format": "usray-channels/1", "sampling_frequency_hz": 40e6, "t0_s": 0.0,
        "sound_speed_m_s": 1540.0, "center_frequency_hz": 5e6,
        "probe": {"kind": "linear", "n_elements": 4096, "pitch_m": 0.1e-3, "element_width_m": 0.1e-3},
        "transmits": [{"kind": "plane_wave", "angle_rad": -0.1}, {"kind": "plane_wave", "angle_rad": 0.0},
                      {"kind": "plane_wave", "angle_rad": 0.1}, {"kind": "plane_wave", "angle_rad": 0.2}]
    }))
    .unwrap();
    let data = usray_signal::ChannelData {
        meta,
        n_samples: 4,
        samples: vec![0.0; 4 * 4096 * 4],
    };
    let channels = dir.path().join("wide.json");
    usray_signal::write_channels(&channels, &data).unwrap();
    let out = dir.path().join("bf");
    let t = std::time::Instant::now();
    let o = usray(&[
        "beamform",
        channels.to_str().unwrap(),
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("delay-and-sum terms") && e.contains("--yes"),
        "{e}"
    );
    assert!(t.elapsed().as_secs() < 30, "refused only after work");
}

/// `usray grad SCENE --reference REFERENCE --params materials.target.roughness
/// --out OUT EXTRA…`: its output and its `grad.json`, if written.
fn grad_roughness(
    scene: &Path,
    reference: &Path,
    out: &Path,
    extra: &[&str],
) -> (std::process::Output, Option<serde_json::Value>) {
    let mut args = vec![
        "grad",
        scene.to_str().unwrap(),
        "--reference",
        reference.to_str().unwrap(),
        "--params",
        "materials.target.roughness",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ];
    args.extend_from_slice(extra);
    let o = usray(&args);
    let v = std::fs::read_to_string(out.join("grad.json"))
        .ok()
        .map(|t| serde_json::from_str(&t).unwrap());
    (o, v)
}

#[test]
fn data_that_declare_a_2d_simulation_are_compared_with_a_2d_trace() {
    // Channel data whose provenance names a 2-D simulation (what k-Wave's
    // generator writes): a scene that leaves `acquisition.dimensions` unset is
    // traced in 2-D, and the command says so; a scene that sets 3 is not; a
    // `dimensions` key other than 2 or 3 is refused by name.
    let dir = tempfile::tempdir().unwrap();
    let (scene, _) = tiny_scene_and_reference(dir.path());
    let channels = dir.path().join("ref").join("channels.json");
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&channels).unwrap()).unwrap();
    meta["simulation"] = "k-wave-python 0.6.2, 2-D (x, z); scattered field".into();
    std::fs::write(&channels, meta.to_string()).unwrap();
    let grad =
        |scene: &Path, out: &str| grad_roughness(scene, &channels, &dir.path().join(out), &[]);
    let (o, unset) = grad(&scene, "unset");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("traced in 2-D") && err.contains("`simulation`"),
        "{err}"
    );
    let three = dir.path().join("three.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&three, text.replace("seed = 1", "seed = 1\ndimensions = 3")).unwrap();
    let (o, explicit) = grad(&three, "three");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && !err.contains("2-D"), "{err}");
    // The two traces differ (the 3-D one is the data's own scene).
    assert_ne!(unset.unwrap()["loss"], explicit.unwrap()["loss"]);
    meta["dimensions"] = 4.into();
    std::fs::write(&channels, meta.to_string()).unwrap();
    let (o, _) = grad(&scene, "bad");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("channels.json") && err.contains("`dimensions` = 4"),
        "{err}"
    );
}

#[test]
fn data_in_source_pressure_are_compared_at_absolute_levels() {
    // A 2-D render is in the unit "Pa per 1 Pa source pressure"; channel data
    // that declare it are compared at absolute levels by `grad` and `fit`
    // (`--levels auto`, the default), and the command says so. `relative`
    // normalises each image to its own maximum; `absolute` is refused, saying
    // why, where the data are not in that unit.
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&scene, text.replace("seed = 1", "seed = 1\ndimensions = 2")).unwrap();
    let refdir = render_into(&dir.path().join("ref"), scene.to_str().unwrap(), 1);
    let channels = refdir.join("channels.json");
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&channels).unwrap()).unwrap();
    // The model: its target reflects less than the data's.
    let model = dir.path().join("model.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    let z = text
        .lines()
        .filter(|l| l.starts_with("impedance_mrayl"))
        .nth(1)
        .expect("the target's impedance")
        .to_string();
    std::fs::write(&model, text.replacen(&z, "impedance_mrayl = 1.6", 1)).unwrap();
    let grad = |reference: &Path, levels: &str, out: &str| {
        let out = dir.path().join(out);
        let (o, v) = grad_roughness(&model, reference, &out, &["--levels", levels]);
        (o, v.map(|v| v["loss"].clone()))
    };
    // No unit declared: `auto` stays relative, `absolute` is refused by name.
    let (o, plain) = grad(&channels, "auto", "plain");
    assert!(o.status.success());
    assert!(!String::from_utf8_lossy(&o.stderr).contains("absolutely"));
    let (o, none) = grad(&channels, "absolute", "refused");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && none.is_none());
    assert!(
        err.contains("--levels absolute") && err.contains("amplitude_unit"),
        "{err}"
    );
    // Declared: `auto` compares absolutely, and the loss is another one.
    meta["amplitude_unit"] = "Pa per 1 Pa source pressure".into();
    std::fs::write(&channels, meta.to_string()).unwrap();
    let (o, absolute) = grad(&channels, "auto", "absolute");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && err.contains("levels compared absolutely"),
        "{err}"
    );
    let (o, relative) = grad(&channels, "relative", "relative");
    assert!(o.status.success());
    assert_eq!(relative, plain);
    assert_ne!(absolute, relative);
    // A B-mode has no unit: `absolute` is refused.
    let (o, _) = grad(&refdir.join("bmode.npy"), "absolute", "bmode");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("B-mode"), "{err}");
}
