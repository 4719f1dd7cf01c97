//! PyMUST-style MATLAB files of a phased (P4-2v) and a convex (C5-2v) array
//! with diverging and focused transmits (`param.TXdelay` from PyMUST's
//! `txdelay`, SIMUS point targets; `tests/data/import/`, made by
//! `tests/python/pymust_txdelay_mat.py`), imported with no options: the
//! virtual sources and the focus fitted to the delays are the ones PyMUST used,
//! and usray's delay-and-sum puts every insonified point target within 0.2 mm
//! of where SIMUS put it.

mod common;

use std::path::PathBuf;

use common::probes::localise;
use usray_signal::array::ArrayGeometry;
use usray_signal::mat::{read_mat, MatValue};
use usray_signal::transmit::TransmitWave;
use usray_signal::{import_mat, ChannelData};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("tests/data/import/{name}"))
}

/// The `truth` struct's field `name`, as rows of two numbers (MATLAB `[n × 2]`).
fn truth(name: &str, field: &str) -> Vec<[f64; 2]> {
    let vars = read_mat(fixture(name)).unwrap();
    let t = &vars.iter().find(|(n, _)| n == "truth").unwrap().1;
    let Some(MatValue::Numeric { dims, re, .. }) = t.field(field) else {
        panic!("{name}: truth.{field}");
    };
    let n = dims[0];
    (0..n).map(|i| [re[i], re[n + i]]).collect()
}

/// Imports `name`, checks each transmit's kind and recovered point against
/// `truth.sources_m` (to `tol_m`) and the fit residual, and localises the
/// point targets; returns the worst recovery error and the data.
fn import_and_check(name: &str, kind: &str, probe: &str) -> (f64, ChannelData) {
    let ch = import_mat(fixture(name)).unwrap();
    assert_eq!(ch.meta.probe.kind, probe, "{name}");
    let sources = truth(name, "sources_m");
    assert_eq!(ch.n_transmits(), sources.len(), "{name}");
    let fit = &ch.meta.extra["source"]["transmit_fit"];
    let mut worst: f64 = 0.0;
    for (i, (t, want)) in ch.meta.transmits.iter().zip(&sources).enumerate() {
        assert_eq!(t.kind, kind, "{name} transmit {i}");
        let got = match TransmitWave::from_meta(i, t).unwrap() {
            TransmitWave::Diverging { source_m } => source_m,
            TransmitWave::Focused { focus_m } => focus_m,
            w => panic!("{name} transmit {i}: {w:?}"),
        };
        let err = (got[0] - want[0]).hypot(got[1] - want[1]);
        let residual = fit["transmits"][i]["max_residual_samples"]
            .as_f64()
            .unwrap();
        eprintln!(
            "{name} transmit {i}: {kind} point ({:.4}, {:.4}) mm recovered as ({:.4}, {:.4}) mm, error {:.2e} mm, largest delay residual {residual:.2e} samples",
            want[0] * 1e3, want[1] * 1e3, got[0] * 1e3, got[1] * 1e3, err * 1e3
        );
        assert!(
            residual < 1e-3,
            "{name} transmit {i}: residual {residual} samples"
        );
        // PyMUST's clock: the first element fires at 0 and SIMUS samples from
        // then on (t0 = 0), so sample 0 is at min_e τ_e on usray's clock.
        let truth_wave = match kind {
            "diverging" => TransmitWave::Diverging { source_m: *want },
            _ => TransmitWave::Focused { focus_m: *want },
        };
        let first_firing = ArrayGeometry::from_meta(&ch.meta.probe)
            .unwrap()
            .elements()
            .iter()
            .map(|e| truth_wave.element_delay_s(e.centre_m, ch.meta.sound_speed_m_s))
            .fold(f64::INFINITY, f64::min);
        let t0 = ch.meta.t0_for(i);
        eprintln!("{name} transmit {i}: t0_s {t0:.6e} s, first firing {first_firing:.6e} s");
        assert!(
            (t0 - first_firing).abs() < 1e-15,
            "{name} transmit {i}: t0_s {t0} vs first firing {first_firing}"
        );
        worst = worst.max(err);
    }
    let points = truth(name, "points_m");
    let (xs, zs): (Vec<f64>, Vec<f64>) = points.iter().map(|p| (p[0], p[1])).unzip();
    let (loc, seen) = localise(name, &ch, &xs, &zs);
    eprintln!(
        "{name}: worst localisation {:.3} mm over {seen} insonified targets",
        loc * 1e3
    );
    assert!(
        seen >= 3.min(points.len()),
        "{name}: only {seen} targets insonified"
    );
    (worst, ch)
}

#[test]
fn phased_diverging_sources_recovered_and_points_in_place() {
    let (err, ch) = import_and_check("p4_diverging.mat", "diverging", "phased");
    assert!(err < 1e-9, "virtual source off by {err} m");
    // A tilted virtual source's first firing precedes its wave's passing the
    // origin.
    assert!(ch.meta.t0_for(0) < 0.0 && ch.meta.t0_for(1) > -1e-12);
}

#[test]
fn phased_focused_in_wavelengths_recovered_and_points_in_place() {
    let (err, ch) = import_and_check("p4_focused.mat", "focused", "phased");
    assert!(err < 1e-9, "focus off by {err} m");
    let used = ch.meta.extra["source"]["used"]["transmit_delays"]
        .as_str()
        .unwrap();
    assert!(used.contains("wavelengths"), "{used}");
}

#[test]
fn convex_diverging_sources_recovered_and_points_in_place() {
    let (err, ch) = import_and_check("c5_diverging.mat", "diverging", "convex");
    assert!(err < 1e-9, "virtual source off by {err} m");
    assert_eq!(ch.meta.probe.extra["radius_m"].as_f64(), Some(49.57e-3));
}

/// A `param` struct of 16 elements at 0.3 mm, 20 MHz, with `TXdelay` (seconds,
/// [1 × 16]) and a radius, and 32 samples of RF.
fn param_file(path: &std::path::Path, delays: &[f64], radius: f64) {
    use common::{double, int16, mat_file, structure};
    let p = structure(
        "param",
        &[
            ("fs", double("", &[1, 1], &[20e6])),
            ("fc", double("", &[1, 1], &[5e6])),
            ("c", double("", &[1, 1], &[1540.0])),
            ("pitch", double("", &[1, 1], &[0.3e-3])),
            ("Nelements", double("", &[1, 1], &[16.0])),
            ("radius", double("", &[1, 1], &[radius])),
            ("TXdelay", double("", &[1, 16], delays)),
        ],
    );
    let rf: Vec<i16> = (0..32 * 16).map(|i| (i % 7) as i16 - 3).collect();
    std::fs::write(path, mat_file(&[p, int16("RF", &[32, 16], &rf)])).unwrap();
}

/// Delays that are no wave (a diverging law with one element a sample late)
/// are refused, naming the variable, the transmit and each model's residual;
/// the same law intact imports; a radius that is not a length is refused.
#[test]
fn delays_that_fit_no_wave_are_refused_naming_the_transmit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.mat");
    let v = [1e-3, -8e-3];
    let law: Vec<f64> = (0..16)
        .map(|e| {
            let x = (e as f64 - 7.5) * 0.3e-3;
            ((x - v[0]).hypot(v[1]) - v[0].hypot(v[1])) / 1540.0
        })
        .collect();
    let min = law.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut d: Vec<f64> = law.iter().map(|t| t - min).collect();
    param_file(&path, &d, f64::INFINITY);
    let ch = import_mat(&path).unwrap();
    assert_eq!(ch.meta.transmits[0].kind, "diverging");
    d[5] += 1.0 / 20e6;
    param_file(&path, &d, f64::INFINITY);
    let e = import_mat(&path).unwrap_err().to_string();
    eprintln!("{e}");
    assert!(
        e.contains("bad.mat")
            && e.contains("param.TXdelay")
            && e.contains("transmit 0")
            && e.contains("fits no transmit model"),
        "{e}"
    );
    param_file(&path, &d, -0.04);
    let e = import_mat(&path).unwrap_err().to_string();
    assert!(e.contains("param.radius"), "{e}");
}

/// Verasonics keeps each transmit's delays, in wavelengths, in the struct
/// array `TX(k).Delay`: two diverging waves on a 16-element flat array come
/// back at their virtual sources.
#[test]
fn verasonics_tx_struct_array_delays_are_fitted() {
    use common::{double, int16, mat_file, struct_array, structure};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("vs.mat");
    let (fc, c) = (5e6, 1540.0);
    let sources = [[-2e-3, -6e-3], [2e-3, -6e-3]];
    let tx: Vec<Vec<Vec<u8>>> = sources
        .iter()
        .map(|v| {
            let tau: Vec<f64> = (0..16)
                .map(|e| {
                    let x = (e as f64 - 7.5) * 0.3e-3;
                    (x - v[0]).hypot(v[1]) / c
                })
                .collect();
            let min = tau.iter().cloned().fold(f64::INFINITY, f64::min);
            let wavelengths: Vec<f64> = tau.iter().map(|t| (t - min) * fc).collect();
            vec![
                double("", &[1, 3], &[0.0, 0.0, 0.0]),
                double("", &[1, 16], &wavelengths),
            ]
        })
        .collect();
    let p = structure(
        "P",
        &[
            ("fs", double("", &[1, 1], &[20e6])),
            ("fc", double("", &[1, 1], &[fc])),
            ("c", double("", &[1, 1], &[c])),
            ("pitch", double("", &[1, 1], &[0.3e-3])),
            ("Nelements", double("", &[1, 1], &[16.0])),
        ],
    );
    let rf: Vec<i16> = (0..32 * 16 * 2).map(|i| (i % 5) as i16 - 2).collect();
    std::fs::write(
        &path,
        mat_file(&[
            p,
            struct_array("TX", &["Origin", "Delay"], &tx),
            int16("RF", &[32, 16, 2], &rf),
        ]),
    )
    .unwrap();
    let ch = import_mat(&path).unwrap();
    let used = ch.meta.extra["source"]["used"]["transmit_delays"]
        .as_str()
        .unwrap();
    assert!(used.starts_with("TX(k).Delay (in wavelengths"), "{used}");
    for (i, want) in sources.iter().enumerate() {
        let TransmitWave::Diverging { source_m } =
            TransmitWave::from_meta(i, &ch.meta.transmits[i]).unwrap()
        else {
            panic!("transmit {i}: {:?}", ch.meta.transmits[i]);
        };
        let err = (source_m[0] - want[0]).hypot(source_m[1] - want[1]);
        assert!(err < 1e-12, "transmit {i}: {source_m:?} vs {want:?}");
    }
}
