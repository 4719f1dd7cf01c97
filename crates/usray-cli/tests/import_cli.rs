//! `usray import` from the outside: the shipped real files import from the
//! command line, with flags supplying what a file does not store.

use std::process::Command;

fn usray(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_usray"))
        .args(args)
        .output()
        .unwrap()
}

fn sidecar(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// `ArraySteelPins.mat` stores neither pitch nor centre frequency: without flags
/// the error names `--pitch`; with `--pitch 1e-3` alone it imports with the centre
/// frequency estimated from the samples (and says so); with `--pitch 1e-3 --fc
/// 3.5e6` (the values `../shared/data/real/README.md` confirms) the sidecar
/// records both values and that they came from the user.
#[test]
fn full_matrix_file_imports_with_pitch_and_fc_flags() {
    let Some(file) = usray_testdata::data_file("real/ArraySteelPins.mat") else {
        return;
    };
    let f = file.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("pins");
    let o_s = out.to_str().unwrap();

    let o = usray(&["import", f, "--out", o_s, "--quiet"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--pitch"), "{err}");

    let est = dir.path().join("estimated");
    let o = usray(&[
        "import",
        f,
        "--pitch",
        "1e-3",
        "--out",
        est.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = sidecar(&est.join("ArraySteelPins.json"));
    assert!(
        v["source"]["fc_note"]
            .as_str()
            .unwrap()
            .contains("estimated"),
        "{v}"
    );

    let o = usray(&[
        "import", f, "--pitch", "1e-3", "--fc", "3.5e6", "--out", o_s, "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = sidecar(&out.join("ArraySteelPins.json"));
    assert_eq!(v["probe"]["pitch_m"], 1e-3, "{v}");
    assert_eq!(v["probe"]["n_elements"], 32, "{v}");
    assert_eq!(v["center_frequency_hz"], 3.5e6, "{v}");
    assert_eq!(v["source"]["overrides"]["pitch_m"], 1e-3, "{v}");
    assert!(out.join("ArraySteelPins.npy").is_file());
}

/// A flag overrides what a Verasonics file stores (a wrong `param.pitch`, say),
/// and a non-positive flag is refused naming it.
#[test]
fn flags_override_the_files_values_and_bad_flags_are_refused() {
    let Some(file) = usray_testdata::data_file("real/PWI_disk.mat") else {
        return;
    };
    let f = file.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("disk");
    let o_s = out.to_str().unwrap();

    let o = usray(&["import", f, "--pitch", "3e-4", "--out", o_s, "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = sidecar(&out.join("PWI_disk.json"));
    assert_eq!(v["probe"]["pitch_m"], 3e-4, "{v}");
    assert_eq!(v["center_frequency_hz"], 5e6, "file's fc kept: {v}");
    assert_eq!(v["source"]["overrides"]["pitch_m"], 3e-4, "{v}");

    for bad in ["0", "-1e-3", "nan", "inf"] {
        let o = usray(&[
            "import",
            f,
            &format!("--pitch={bad}"),
            "--out",
            o_s,
            "--quiet",
        ]);
        assert!(!o.status.success(), "--pitch={bad} accepted");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("--pitch"), "--pitch={bad}: {err}");
    }
}

/// `usray export --format uff` writes NAME.uff that `usray import` reads back to
/// the same channel data, and pyuff_ustb (USTB's reader) reads it as the sidecar
/// says; a .uff that is not HDF5 is refused naming the file.
#[test]
fn export_to_uff_and_import_it_back() {
    let Some(points) = usray_testdata::data_file("peers/points.json") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (uff_dir, back_dir) = (dir.path().join("uff"), dir.path().join("back"));
    let o = usray(&[
        "export",
        points.to_str().unwrap(),
        "--format",
        "uff",
        "--out",
        uff_dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let uff = uff_dir.join("points.uff");
    let o = usray(&[
        "import",
        uff.to_str().unwrap(),
        "--out",
        back_dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (sidecar(&points), sidecar(&back_dir.join("points.json")));
    for key in [
        "sampling_frequency_hz",
        "t0_s",
        "sound_speed_m_s",
        "center_frequency_hz",
    ] {
        assert_eq!(a[key], b[key], "{key}");
    }
    for (ta, tb) in a["transmits"]
        .as_array()
        .unwrap()
        .iter()
        .zip(b["transmits"].as_array().unwrap())
    {
        assert_eq!(
            (&ta["angle_rad"], &ta["t0_s"]),
            (&tb["angle_rad"], &tb["t0_s"])
        );
    }
    let samples = |p: &std::path::Path| usray_signal::read_channels(p).unwrap().samples;
    assert!(samples(&points) == samples(&back_dir.join("points.json")));
    usray_testdata::run_python(
        &["h5py", "numpy", "pyuff_ustb"],
        "tests/python/uff_check.py",
        &[uff.as_os_str(), points.as_os_str()],
    );

    let fake = dir.path().join("fake.uff");
    std::fs::write(&fake, b"not hdf5").unwrap();
    let o = usray(&[
        "import",
        fake.to_str().unwrap(),
        "--out",
        back_dir.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("fake.uff") && err.contains("HDF5"), "{err}");
}
