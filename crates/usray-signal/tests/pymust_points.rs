//! usray's B-mode against PyMUST's own delay-and-sum of the same SIMUS channels
//! (`peers/points.*`, see `shared/data/peers/README.md`).

use rustfft::num_complex::Complex64;
use usray_signal::das::{linspace, Das};
use usray_signal::io::read_npy;
use usray_signal::{BMode, ChannelData, Demod, ImagingSettings};

fn ncc(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

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
    let (mut a, mut r) = (vec![], vec![]);
    for (u, &p) in ws.db().iter().zip(&refdb) {
        if p > -40.0 {
            a.push(*u);
            r.push(p);
        }
    }
    let max_diff = a
        .iter()
        .zip(&r)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    let v = ncc(&a, &r);
    eprintln!(
        "{name} ({demod:?}): NCC over {} px (PyMUST > -40 dB) = {v:.7}, max |ΔdB| = {max_diff:.4}",
        a.len()
    );
    Some(v)
}

#[test]
fn points_ncc_against_pymust() {
    let Some(v) = compare("points", Demod::Iq) else {
        return;
    };
    assert!(v >= 0.99, "NCC {v}");
}

fn one_transmit(ch: &ChannelData, t: usize) -> ChannelData {
    let mut meta = ch.meta.clone();
    let mut tx = meta.transmits[t].clone();
    tx.t0_s = Some(ch.meta.t0_for(t));
    meta.transmits = vec![tx];
    let n = ch.n_elements() * ch.n_samples;
    ChannelData {
        meta,
        n_samples: ch.n_samples,
        samples: ch.samples[t * n..(t + 1) * n].to_vec(),
    }
}

fn peak(das_of: &dyn Fn(Vec<f64>, Vec<f64>) -> Vec<f64>, x: Vec<f64>, z: Vec<f64>) -> (f64, f64) {
    let env = das_of(x.clone(), z.clone());
    let k = usray_signal::post::argmax(&env);
    (x[k % x.len()], z[k / x.len()])
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
        let fc = c1.meta.center_frequency_hz;
        let fs = c1.meta.sampling_frequency_hz;
        let d = usray_signal::demod::IqDemod::new(
            fc,
            fs,
            c1.meta.probe.extra["bandwidth_percent"].as_f64().unwrap() / 100.0 * fc / 2.0,
            5,
        )
        .unwrap();
        let ns = c1.n_samples;
        let mut iq = vec![Complex64::new(0.0, 0.0); c1.samples.len()];
        for (rec, out) in iq.chunks_mut(ns).enumerate() {
            d.forward(
                &c1.samples[rec * ns..(rec + 1) * ns],
                c1.meta.t0_for(0),
                out,
            );
        }
        let das_of = |x: Vec<f64>, z: Vec<f64>| -> Vec<f64> {
            let das = Das::new(&c1.meta, ns, x.clone(), z.clone(), 1540.0, 0.0, true).unwrap();
            let mut out = vec![Complex64::new(0.0, 0.0); x.len() * z.len()];
            das.forward(&iq, &mut out);
            out.iter().map(|v| v.norm()).collect()
        };
        for (&xt, &zt) in xs.iter().zip(&zs) {
            // Coarse: ±1 mm × ±2 mm at 0.1 mm; fine: ±0.15 mm at 0.01 mm around it.
            let (xc, zc) = peak(
                &das_of,
                linspace(xt - 1e-3, xt + 1e-3, 21),
                linspace(zt - 2e-3, zt + 2e-3, 41),
            );
            let (xf, zf) = peak(
                &das_of,
                linspace(xc - 0.15e-3, xc + 0.15e-3, 31),
                linspace(zc - 0.15e-3, zc + 0.15e-3, 31),
            );
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
