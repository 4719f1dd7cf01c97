//! PyMUST's point-target channel data written with `scipy.io.savemat` under other
//! names, sample types (uint8, int16, single, uint16) and axis orders, with and
//! without frames and transmit delays (`tests/python/pymust_as_mat.py`), imported with
//! no options: each import recovers the acquisition and its B-mode puts the five
//! points where `peers/points.json` says.

use usray_signal::{import_mat, BMode, ChannelData, Demod, ImagingSettings};

/// The files the script writes, with the transmits each import must give.
const FILES: [(&str, usize); 4] = [
    ("uint8_sea.mat", 3),
    ("int16_aes.mat", 3),
    ("single_esa.mat", 3),
    ("uint16_frames.mat", 6),
];

fn numbers(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The peak of the dB image within ±1 mm of `(x, z)`, metres.
fn peak_near(db: &[f64], xs: &[f64], zs: &[f64], x: f64, z: f64) -> (f64, f64) {
    let mut best = (f64::NEG_INFINITY, 0.0, 0.0);
    for (iz, &zp) in zs.iter().enumerate() {
        for (ix, &xp) in xs.iter().enumerate() {
            let v = db[iz * xs.len() + ix];
            if (xp - x).abs() <= 1e-3 && (zp - z).abs() <= 1e-3 && v > best.0 {
                best = (v, xp, zp);
            }
        }
    }
    (best.1, best.2)
}

/// Largest distance, m, between a point target and its B-mode peak.
fn worst_localisation(ch: &ChannelData, truth: &[(f64, f64)]) -> f64 {
    let mut s = ImagingSettings::new([-7e-3, 7e-3], [7e-3, 33e-3], 0.05e-3);
    s.f_number = 1.0;
    s.demod = Demod::Iq;
    let (xs, zs) = s.grid().unwrap();
    let b = BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
    let mut ws = b.workspace();
    b.forward(ch, &mut ws).unwrap();
    truth
        .iter()
        .map(|&(x, z)| {
            let (px, pz) = peak_near(ws.db(), &xs, &zs, x, z);
            ((px - x).powi(2) + (pz - z).powi(2)).sqrt()
        })
        .fold(0.0, f64::max)
}

#[test]
fn pymust_points_in_other_layouts_import_and_image_in_place() {
    let Some(points) = usray_testdata::data_file("peers/points.json") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let args = [points.as_os_str(), dir.path().as_os_str()];
    if usray_testdata::run_python(
        &["numpy", "scipy.io"],
        "tests/python/pymust_as_mat.py",
        &args,
    )
    .is_none()
    {
        return;
    }
    let original = usray_signal::read_channels(&points).unwrap();
    let s = &original.meta.extra["scatterers"];
    let truth: Vec<(f64, f64)> = numbers(&s["x_m"])
        .into_iter()
        .zip(numbers(&s["z_m"]))
        .collect();
    let reference = worst_localisation(&original, &truth);
    eprintln!(
        "points.json itself: worst point error {:.3} mm",
        reference * 1e3
    );
    for (file, n_transmits) in FILES {
        let ch = import_mat(dir.path().join(file)).unwrap();
        let m = &ch.meta;
        assert_eq!(ch.shape(), (n_transmits, 128, original.n_samples), "{file}");
        assert_eq!(m.sampling_frequency_hz, original.meta.sampling_frequency_hz);
        assert_eq!(m.sound_speed_m_s, original.meta.sound_speed_m_s);
        assert!((m.probe.pitch_m - original.meta.probe.pitch_m).abs() < 1e-12);
        // Angles and the CONTRACT §1 clock of every transmit, as points.json has them.
        for t in 0..n_transmits {
            let want = t % 3;
            let da = m.transmits[t].angle_rad - original.meta.transmits[want].angle_rad;
            assert!(da.abs() < 1e-6, "{file} transmit {t}: angle off by {da}");
            let dt = m.t0_for(t) - original.meta.t0_for(want);
            assert!(dt.abs() < 1e-12, "{file} transmit {t}: t0 off by {dt} s");
        }
        // The samples, up to the file's quantisation and scale.
        let n = original.samples.len();
        let gain = ch.samples[..n]
            .iter()
            .zip(&original.samples)
            .map(|(a, b)| a * b)
            .sum::<f64>()
            / original.samples.iter().map(|b| b * b).sum::<f64>();
        let peak = original.samples.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = ch.samples[..n]
            .iter()
            .zip(&original.samples)
            .map(|(a, b)| (a / gain - b).abs())
            .fold(0.0, f64::max);
        assert!(
            worst <= peak / 127.0,
            "{file}: sample error {worst} of peak {peak}"
        );
        let err = worst_localisation(&ch, &truth);
        eprintln!(
            "{file}: fc {:.3} MHz, worst point error {:.3} mm, assumed {}",
            m.center_frequency_hz / 1e6,
            err * 1e3,
            m.extra["source"]["assumed"]
        );
        assert!(
            err < 0.1e-3,
            "{file}: a point is {err} m from where points.json puts it"
        );
    }
}
