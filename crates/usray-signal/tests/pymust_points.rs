//! usray's B-mode against PyMUST's own delay-and-sum of the same SIMUS channels
//! (`peers/points.*`, see `shared/data/peers/README.md`).

mod common;

use common::pymust::{agreement, iq, one_transmit, peak_near};
use usray_signal::io::read_npy;
use usray_signal::{BMode, ChannelData, Demod, ImagingSettings};

fn reference(name: &str) -> Option<(ChannelData, serde_json::Value, Vec<f64>)> {
    let ch_path = usray_testdata::data_file(&format!("peers/{name}.json"))?;
    let ref_json = usray_testdata::data_file(&format!("peers/{name}_bmode_pymust.json"))?;
    let ref_npy = usray_testdata::data_file(&format!("peers/{name}_bmode_pymust.npy"))?;
    let ch = usray_signal::read_channels(&ch_path).unwrap();
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ref_json).unwrap()).unwrap();
    let r = read_npy(ref_npy).unwrap();
    assert_eq!(
        r.shape,
        vec![
            meta["nz"].as_u64().unwrap() as usize,
            meta["nx"].as_u64().unwrap() as usize
        ]
    );
    Some((ch, meta, r.data))
}

fn settings_from(meta: &serde_json::Value) -> ImagingSettings {
    let r = |k: &str| [meta[k][0].as_f64().unwrap(), meta[k][1].as_f64().unwrap()];
    let mut s = ImagingSettings::new(
        r("x_range_m"),
        r("z_range_m"),
        meta["pixel_m"].as_f64().unwrap(),
    );
    s.f_number = meta["f_number"].as_f64().unwrap();
    s.demod = Demod::Iq;
    s.dynamic_range_db = 60.0;
    s
}

/// NCC of the dB images over pixels where PyMUST > −40 dB.
pub fn compare(name: &str, demod: Demod) -> Option<f64> {
    let (ch, meta, refdb) = reference(name)?;
    let mut s = settings_from(&meta);
    s.demod = demod;
    let b = BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
    assert_eq!(
        b.image_shape(),
        (
            meta["nz"].as_u64().unwrap() as usize,
            meta["nx"].as_u64().unwrap() as usize
        )
    );
    let mut ws = b.workspace();
    b.forward(&ch, &mut ws).unwrap();
    let m = agreement(ws.db(), &refdb, |_| true);
    eprintln!(
        "{name} ({demod:?}): NCC over {} px (PyMUST > -40 dB) = {:.7}, max |ΔdB| = {:.4}",
        m.pixels, m.ncc, m.max_diff_db
    );
    Some(m.ncc)
}

#[test]
fn points_ncc_against_pymust() {
    let Some(v) = compare("points", Demod::Iq) else {
        return;
    };
    assert!(v >= 0.99, "NCC {v}");
}

#[test]
fn points_localised_per_transmit() {
    let Some((ch, _, _)) = reference("points") else {
        return;
    };
    let truth = &ch.meta.extra["scatterers"];
    let xs: Vec<f64> = truth["x_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let zs: Vec<f64> = truth["z_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let mut worst: f64 = 0.0;
    for t in 0..ch.n_transmits() {
        let c1 = one_transmit(&ch, t);
        // IQ demodulation as in B: Butterworth(5) at bandwidth/2 (probe's 77 %).
        let iq = iq(&c1);
        for (&xt, &zt) in xs.iter().zip(&zs) {
            let (xf, zf) = peak_near(&c1.meta, c1.n_samples, &iq, xt, zt);
            let err = ((xf - xt).powi(2) + (zf - zt).powi(2)).sqrt();
            eprintln!(
                "transmit {t} ({:+.0} deg): point ({:.1}, {:.1}) mm found at ({:.3}, {:.3}) mm, error {:.3} mm",
                c1.meta.transmits[0].angle_rad.to_degrees(),
                xt * 1e3, zt * 1e3, xf * 1e3, zf * 1e3, err * 1e3
            );
            worst = worst.max(err);
            assert!(
                err < 0.1e-3,
                "transmit {t}, point ({xt}, {zt}): error {err} m"
            );
        }
    }
    eprintln!("worst localisation error: {:.3} mm", worst * 1e3);
}

#[test]
fn disk_ncc_against_pymust() {
    let Some(v) = compare("disk", Demod::Iq) else {
        return;
    };
    assert!(v >= 0.99, "NCC {v}");
}

/// A correct beamformer that does not copy PyMUST's IQ low-pass (Hilbert analytic
/// signal, no low-pass) lands at 0.94–0.98 on the disk (peers README).
#[test]
fn disk_ncc_hilbert_variant() {
    let Some(v) = compare("disk", Demod::Hilbert) else {
        return;
    };
    assert!(v >= 0.94, "NCC {v}");
}
