//! Phased (P4-2v) and convex (C5-2v) arrays, diverging and focused transmits:
//! usray's delay-and-sum on PyMUST's polar grid against PyMUST's own `dasmtx`
//! images of the same SIMUS channels, and the point targets' positions.
//! Fixtures and their settings: `tests/data/probes/README.md`, made by
//! `tests/python/pymust_probes.py` (committed, so these run in CI).

mod common;

use std::path::PathBuf;

use common::probes::{insonified, localise};
use common::pymust::{agreement, envelope, iq};
use usray_signal::array::ArrayGeometry;
use usray_signal::das::{linspace, Das};
use usray_signal::grid::PolarGrid;
use usray_signal::io::read_npy;
use usray_signal::transmit::TransmitWave;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("tests/data/probes/{name}"))
}

/// NCC of usray's dB image against PyMUST's over the pixels where PyMUST's is
/// above −40 dB and that some transmit insonifies ([`insonified`]: outside
/// that region PyMUST's transmit distance is an edge-wave construction, the
/// nearest normal of its virtual transducer, and usray's the circular wave;
/// neither describes the field there), and, when the reference says
/// `"compare_region": "insonified_before_focus"`, on the array's side of the
/// focus (the convex focused case: README). Prints the NCC over every pixel
/// above −40 dB as well.
fn compare(name: &str) -> f64 {
    let ch = usray_signal::read_channels(fixture(&format!("{name}.json"))).unwrap();
    let meta: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fixture(&format!("{name}_bmode_pymust.json"))).unwrap(),
    )
    .unwrap();
    let refdb = read_npy(fixture(&format!("{name}_bmode_pymust.npy"))).unwrap();
    let g = |k: &str, i: usize| meta[k][i].as_f64().unwrap();
    let n = |k: &str| meta[k].as_u64().unwrap() as usize;
    assert_eq!(refdb.shape, vec![n("n_r"), n("n_theta")]);
    // PyMUST's polar origin is usray's sector origin (impolgrid: the array
    // centre of a flat array, the arc's centre of a convex one).
    let array = ArrayGeometry::from_meta(&ch.meta.probe).unwrap();
    let o = array.sector_origin_m();
    assert!(
        (o[1] - g("origin_m", 1)).abs() < 1e-12,
        "{o:?} vs {}",
        meta["origin_m"]
    );
    let grid = PolarGrid::new(
        o,
        linspace(g("r_m", 0), g("r_m", 1), n("n_r")),
        linspace(g("theta_rad", 0), g("theta_rad", 1), n("n_theta")),
    )
    .unwrap();
    let das = Das::new_polar(
        &ch.meta,
        ch.n_samples,
        grid,
        1540.0,
        meta["f_number"].as_f64().unwrap(),
        true,
    )
    .unwrap();
    let env = envelope(&das, &iq(&ch));
    let max = env.iter().cloned().fold(0.0, f64::max);
    let waves: Vec<TransmitWave<f64>> = das.waves.clone();
    let half = array.elements()[array.n_elements - 1].centre_m[0];
    let nt = n("n_theta");
    let before_focus_only = match meta["compare_region"].as_str().unwrap() {
        "insonified" => false,
        "insonified_before_focus" => true,
        other => panic!("unknown compare_region {other}"),
    };
    let in_region = |px: [f64; 2]| {
        waves.iter().any(|w| {
            insonified(w, px, half)
                && match (before_focus_only, w) {
                    (true, TransmitWave::Focused { focus_m: f }) => {
                        (px[0] - f[0]) * f[0] + (px[1] - f[1]) * f[1] < 0.0
                    }
                    _ => true,
                }
        })
    };
    let db: Vec<f64> = env.iter().map(|e| 20.0 * (e / max).log10()).collect();
    let m = agreement(&db, &refdb.data, |k| in_region(das.pixel(k / nt, k % nt)));
    let all = agreement(&db, &refdb.data, |k| db[k].is_finite());
    eprintln!(
        "{name}: NCC over {} insonified px of {} (PyMUST > -40 dB) = {:.6}, max |ΔdB| = {:.3}; over all {} px > -40 dB (finite in usray's image): {:.6}",
        m.pixels,
        env.len(),
        m.ncc,
        m.max_diff_db,
        all.pixels,
        all.ncc
    );
    m.ncc
}

#[test]
fn phased_diverging_matches_pymust() {
    let v = compare("p4_diverging");
    assert!(v >= 0.99, "NCC {v}");
}

#[test]
fn phased_focused_matches_pymust() {
    let v = compare("p4_focused");
    assert!(v >= 0.99, "NCC {v}");
}

#[test]
fn convex_diverging_matches_pymust() {
    let v = compare("c5_diverging");
    assert!(v >= 0.99, "NCC {v}");
}

#[test]
fn convex_focused_matches_pymust() {
    let v = compare("c5_focused");
    assert!(v >= 0.99, "NCC {v}");
}

/// The diverging waves reach all five targets; the focused beam at least one.
fn points_localised(probe: &str) {
    let fixture_points = |name: &str| {
        let ch = usray_signal::read_channels(fixture(&format!("{name}.json"))).unwrap();
        let coords = |k: &str| -> Vec<f64> {
            ch.meta.extra["scatterers"][k]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect()
        };
        let (xs, zs) = (coords("x_m"), coords("z_m"));
        localise(name, &ch, &xs, &zs)
    };
    let (wd, nd) = fixture_points(&format!("{probe}_diverging"));
    let (wf, nf) = fixture_points(&format!("{probe}_focused"));
    assert_eq!(nd, 5, "{probe}: diverging waves insonify {nd} of 5 targets");
    assert!(nf >= 1, "{probe}: the focused beam insonifies no target");
    eprintln!(
        "{probe}: worst localisation error {:.3} mm (diverging), {:.3} mm (focused, {nf} targets in the beam)",
        wd * 1e3,
        wf * 1e3
    );
}

#[test]
fn phased_points_localised() {
    points_localised("p4");
}

#[test]
fn convex_points_localised() {
    points_localised("c5");
}
