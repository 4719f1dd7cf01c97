//! Files: round trips, every kind of bad input gives a clear error naming the file
//! (never a panic), and no partial output file is ever left.

mod common;
use common::*;
use std::path::Path;
use usray_signal::{
    import_mat, read_channels, write_atomic, write_channels, ChannelData, SignalError,
};

fn sample_channels() -> ChannelData {
    let m = meta(4, 20e6, 5e6, &[0.0, 0.1], &[0.0, -1e-7]);
    let mut r = Rng(1);
    ChannelData {
        meta: m,
        n_samples: 10,
        samples: r.vec(2 * 4 * 10),
    }
}

fn err_text(e: SignalError) -> String {
    e.to_string()
}

#[test]
fn channels_round_trip_keeps_extra_keys() {
    let dir = tempfile::tempdir().unwrap();
    let mut ch = sample_channels();
    ch.meta
        .extra
        .insert("generator".into(), serde_json::json!({"tool": "test"}));
    write_channels(dir.path().join("a.json"), &ch).unwrap();
    let back = read_channels(dir.path().join("a")).unwrap();
    assert_eq!(back.meta, ch.meta);
    for (a, b) in back.samples.iter().zip(&ch.samples) {
        assert_eq!(*a, *b as f32 as f64);
    }
    // Only the two files, no temporaries.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

fn write_pair(dir: &Path, ch: &ChannelData) -> std::path::PathBuf {
    let p = dir.join("d.json");
    write_channels(&p, ch).unwrap();
    p
}

#[test]
fn truncated_npy_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_pair(dir.path(), &sample_channels());
    let npy = dir.path().join("d.npy");
    let bytes = std::fs::read(&npy).unwrap();
    std::fs::write(&npy, &bytes[..bytes.len() - 7]).unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(e.contains("d.npy") && e.contains("truncated"), "{e}");
    // Cut inside the header.
    std::fs::write(&npy, &bytes[..20]).unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(e.contains("d.npy"), "{e}");
}

#[test]
fn mislabelled_npy_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_pair(dir.path(), &sample_channels());
    let npy = dir.path().join("d.npy");
    let text = std::fs::read(&npy).unwrap();
    let patch = |from: &[u8], to: &[u8]| -> Vec<u8> {
        let i = text
            .windows(from.len())
            .position(|w| w == from)
            .unwrap_or_else(|| {
                panic!(
                    "{:?} not in header {:?}",
                    String::from_utf8_lossy(from),
                    String::from_utf8_lossy(&text[..80])
                )
            });
        let mut v = text.clone();
        v[i..i + to.len()].copy_from_slice(to);
        v
    };
    // Claim float64 while the data is float32: sizes disagree.
    std::fs::write(&npy, patch(b"'<f4'", b"'<f8'")).unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(e.contains("d.npy") && e.contains("size mismatch"), "{e}");
    // Claim a shape with more samples than stored.
    std::fs::write(&npy, patch(b"(2, 4, 10,", b"(2, 4, 11,")).unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(e.contains("d.npy") && e.contains("truncated"), "{e}");
    // An integer dtype is refused by name.
    std::fs::write(&npy, patch(b"'<f4'", b"'<i4'")).unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(e.contains("d.npy") && e.contains("'<i4'"), "{e}");
    // Garbage instead of an NPY file.
    std::fs::write(&npy, b"hello world, not numpy").unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(e.contains("d.npy") && e.contains("NPY"), "{e}");
}

#[test]
fn json_shape_disagreeing_with_array_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_pair(dir.path(), &sample_channels());
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["probe"]["n_elements"] = 5.into();
    std::fs::write(&p, v.to_string()).unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(
        e.contains("d.npy") && e.contains("disagrees") && e.contains("[2, 5, n_samples]"),
        "{e}"
    );
}

#[test]
fn missing_keys_and_bad_json_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_pair(dir.path(), &sample_channels());
    let orig: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    for key in [
        "sampling_frequency_hz",
        "t0_s",
        "probe",
        "transmits",
        "format",
    ] {
        let mut v = orig.clone();
        v.as_object_mut().unwrap().remove(key);
        std::fs::write(&p, v.to_string()).unwrap();
        let e = err_text(read_channels(&p).unwrap_err());
        assert!(e.contains("d.json") && e.contains(key), "{key}: {e}");
    }
    let mut v = orig.clone();
    v["probe"].as_object_mut().unwrap().remove("pitch_m");
    std::fs::write(&p, v.to_string()).unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(e.contains("d.json") && e.contains("pitch_m"), "{e}");
    let mut v = orig.clone();
    v["format"] = "usray-channels/9".into();
    std::fs::write(&p, v.to_string()).unwrap();
    assert!(err_text(read_channels(&p).unwrap_err()).contains("usray-channels/1"));
    let mut v = orig;
    v["sampling_frequency_hz"] = (-1.0).into();
    std::fs::write(&p, v.to_string()).unwrap();
    assert!(err_text(read_channels(&p).unwrap_err()).contains("sampling_frequency_hz"));
    std::fs::write(&p, "{ \"format\": ").unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(e.contains("d.json") && e.contains("invalid JSON"), "{e}");
    // Missing companion file.
    std::fs::remove_file(dir.path().join("d.npy")).unwrap();
    write_pair(dir.path(), &sample_channels());
    std::fs::remove_file(dir.path().join("d.npy")).unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(e.contains("d.npy"), "{e}");
}

#[test]
fn nan_samples_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let mut ch = sample_channels();
    ch.samples[13] = f64::NAN;
    // The writer refuses it …
    let e = err_text(write_channels(dir.path().join("d.json"), &ch).unwrap_err());
    assert!(e.contains("13") && e.contains("not finite"), "{e}");
    assert!(!dir.path().join("d.npy").exists());
    // … and a file holding one (sample 13 overwritten in place) is refused on reading.
    ch.samples[13] = 0.0;
    let p = write_pair(dir.path(), &ch);
    let npy = dir.path().join("d.npy");
    let mut bytes = std::fs::read(&npy).unwrap();
    let data_at = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    bytes[data_at + 13 * 4..data_at + 14 * 4].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(&npy, bytes).unwrap();
    let e = err_text(read_channels(&p).unwrap_err());
    assert!(
        e.contains("d.npy") && e.contains("NaN") && e.contains("13"),
        "{e}"
    );
}

#[test]
fn failed_writes_leave_no_partial_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("out.npy");
    let r = write_atomic(&p, |w| {
        w.write_all(&[0u8; 1000])?;
        Err(std::io::Error::other("simulated failure"))
    });
    assert!(r.is_err());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "temporary left behind"
    );
    // An existing file survives a failed overwrite untouched.
    std::fs::write(&p, b"old").unwrap();
    let _ = write_atomic(&p, |w| {
        w.write_all(b"new but incomplete")?;
        Err(std::io::Error::other("simulated failure"))
    });
    assert_eq!(std::fs::read(&p).unwrap(), b"old");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    // Invalid channel data is refused before anything is written.
    let mut ch = sample_channels();
    ch.samples.pop();
    assert!(write_channels(dir.path().join("bad"), &ch).is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    // Writing into a missing directory fails cleanly.
    assert!(write_channels(dir.path().join("no/such/dir/x"), &sample_channels()).is_err());
}

#[test]
fn bmode_files_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let data = vec![0.0, 0.5, 1.0, 0.25, 0.75, 1.5];
    usray_signal::io::write_bmode_npy(dir.path().join("b.npy"), 2, 3, &data).unwrap();
    usray_signal::io::write_bmode_png(dir.path().join("b.png"), 2, 3, &data).unwrap();
    let a = usray_signal::io::read_npy(dir.path().join("b.npy")).unwrap();
    assert_eq!(a.shape, vec![2, 3]);
    let img = image::open(dir.path().join("b.png")).unwrap().to_luma8();
    assert_eq!((img.width(), img.height()), (3, 2));
    assert_eq!(img.get_pixel(2, 1).0[0], 255);
    assert_eq!(img.get_pixel(1, 0).0[0], 128);
    assert!(usray_signal::io::write_bmode_png(dir.path().join("c.png"), 2, 2, &data).is_err());
    assert!(!dir.path().join("c.png").exists());
}

// ---- MAT v5 ----------------------------------------------------------------

fn param(txdelay: f64, drop: Option<&str>) -> Vec<u8> {
    let mut f = vec![
        ("fs", double("", &[1, 1], &[20e6])),
        ("fc", double("", &[1, 1], &[5e6])),
        ("c", double("", &[1, 1], &[1540.0])),
        ("t0", double("", &[1, 1], &[2e-6])),
        ("pitch", double("", &[1, 1], &[0.3e-3])),
        ("width", double("", &[1, 1], &[0.25e-3])),
        ("Nelements", double("", &[1, 1], &[2.0])),
        ("TXdelay", double("", &[1, 2], &[0.0, txdelay])),
        ("bandwidth", double("", &[1, 1], &[60.0])),
    ];
    f.retain(|(n, _)| Some(*n) != drop);
    structure("param", &f)
}

#[test]
fn mat_import_maps_and_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.mat");
    // (time 3, element 2, frame 2) column-major → [frame, element, time].
    let rf: Vec<i16> = (0..12).collect();
    std::fs::write(
        &p,
        mat_file(&[param(0.0, None), int16("RF", &[3, 2, 2], &rf)]),
    )
    .unwrap();
    let ch = import_mat(&p).unwrap();
    assert_eq!((ch.n_transmits(), ch.n_elements(), ch.n_samples), (2, 2, 3));
    assert_eq!(ch.record(1, 0), &[6.0, 7.0, 8.0]);
    assert_eq!(ch.meta.t0_s, 2e-6);
    assert_eq!(ch.meta.probe.extra["bandwidth_percent"], 60.0);
    // Steered transmit: refused, named.
    std::fs::write(
        &p,
        mat_file(&[param(1e-7, None), int16("RF", &[3, 2, 2], &rf)]),
    )
    .unwrap();
    let e = import_mat(&p).unwrap_err().to_string();
    assert!(e.contains("x.mat") && e.contains("TXdelay"), "{e}");
    // Missing field, missing variable, wrong element count.
    std::fs::write(
        &p,
        mat_file(&[param(0.0, Some("t0")), int16("RF", &[3, 2, 2], &rf)]),
    )
    .unwrap();
    // A missing t0 is assumed 0, and the assumption is recorded.
    let ch = import_mat(&p).unwrap();
    assert_eq!(ch.meta.t0_s, 0.0);
    let source = &ch.meta.extra["source"];
    assert_eq!(source["used"]["t0_s"], "assumed");
    assert!(source["assumed"].to_string().contains("time of sample 0"));
    assert_eq!(source["used"]["sampling_frequency_hz"], "param.fs");
    std::fs::write(&p, mat_file(&[param(0.0, None)])).unwrap();
    assert!(import_mat(&p)
        .unwrap_err()
        .to_string()
        .contains("no RF array"));
    // No axis of the RF holds `param.Nelements` = 2 elements.
    std::fs::write(&p, mat_file(&[param(0.0, None), int16("RF", &[3, 4], &rf)])).unwrap();
    assert!(import_mat(&p)
        .unwrap_err()
        .to_string()
        .contains("Nelements"));
    std::fs::write(&p, mat_file(&[int16("data", &[3, 2], &rf[..6])])).unwrap();
    let e = import_mat(&p).unwrap_err().to_string();
    assert!(
        e.contains("no sampling frequency") && e.contains("\"data\"") && e.contains("--fs"),
        "{e}"
    );
    // Truncated and non-MAT files: errors, no panic.
    let good = mat_file(&[param(0.0, None), int16("RF", &[3, 2, 2], &rf)]);
    for cut in [10, 130, 200, good.len() - 5] {
        std::fs::write(&p, &good[..cut]).unwrap();
        let e = import_mat(&p).unwrap_err().to_string();
        assert!(e.contains("x.mat"), "{e}");
    }
}

#[test]
fn real_mat_truncated_is_an_error() {
    let Some(path) = usray_testdata::data_file("real/PWI_disk.mat") else {
        return;
    };
    let bytes = std::fs::read(path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("cut.mat");
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let e = import_mat(&p).unwrap_err().to_string();
    assert!(e.contains("cut.mat"), "{e}");
    // The FMC files do not store the pitch (nor, for the pins, fc): refused, named.
    if let Some(fmc) = usray_testdata::data_file("real/ArraySteelPins.mat") {
        let e = import_mat(fmc).unwrap_err().to_string();
        assert!(
            e.contains("ArraySteelPins.mat") && e.contains("pitch"),
            "{e}"
        );
        let opts = usray_signal::ImportOptions {
            center_frequency_hz: Some(3.5e6),
            ..Default::default()
        };
        let e = usray_signal::import_mat_with(
            usray_testdata::data_file("real/ArraySteelPins.mat").unwrap(),
            &opts,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("pitch"), "{e}");
        // An option a full-matrix capture does not use is refused, not ignored.
        let opts = usray_signal::ImportOptions {
            pitch_m: Some(1e-3),
            angles_rad: Some(vec![0.1]),
            ..Default::default()
        };
        let e = usray_signal::import_mat_with(
            usray_testdata::data_file("real/ArraySteelPins.mat").unwrap(),
            &opts,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("--angles-deg") && e.contains("full-matrix"),
            "{e}"
        );
    }
}

#[test]
fn imaging_settings_from_contract_keys() {
    // CONTRACT §3 `[imaging]`, as the CLI would hand it over after parsing TOML.
    let v = serde_json::json!({
        "x_range_m": [-0.02, 0.02], "z_range_m": [0.001, 0.035], "pixel_m": 0.1e-3,
        "f_number": 1.5, "dynamic_range_db": 60.0, "sound_speed_m_s": 1540.0
    });
    let s: usray_signal::ImagingSettings = serde_json::from_value(v).unwrap();
    assert_eq!(s.demod, usray_signal::Demod::Iq);
    let (x, z) = s.grid().unwrap();
    assert_eq!((x.len(), z.len()), (401, 341));
    assert_eq!((x[0], x[400], z[0], z[340]), (-0.02, 0.02, 0.001, 0.035));
    let s: usray_signal::ImagingSettings =
        serde_json::from_value(serde_json::json!({"demod": "hilbert"})).unwrap();
    assert_eq!(s.demod, usray_signal::Demod::Hilbert);
    let mut bad = s.clone();
    bad.pixel_m = 0.0;
    assert!(bad.grid().unwrap_err().to_string().contains("pixel_m"));
    let mut bad = s;
    bad.dynamic_range_db = -1.0;
    let m = meta(4, 20e6, 5e6, &[0.0], &[0.0]);
    assert!(usray_signal::BMode::new(&bad, &m, 100)
        .unwrap_err()
        .to_string()
        .contains("dynamic_range_db"));
}
