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
/// the error names the flag to pass; with `--pitch 1e-3 --fc 3.5e6` (the values
/// `../shared/data/real/README.md` confirms) it imports, and the sidecar records
/// both values and that they came from the user.
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
    assert!(err.contains("--fc"), "{err}");

    let o = usray(&["import", f, "--fc", "3.5e6", "--out", o_s, "--quiet"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--pitch"), "{err}");

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
