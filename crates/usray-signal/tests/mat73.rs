//! MAT v7.3 (HDF5) files read into the same values as their MAT v5 originals:
//! `tests/python/mat73_from_v5.py` (h5py, scipy) writes a v7.3 copy of a v5 file
//! in MATLAB's layout, and the v7.3 reader must give what the v5 reader gives.

use std::path::Path;

use usray_signal::mat::{read_mat, MatFile};
use usray_signal::{import_mat, import_mat_with, ImportOptions};

const SCRIPT: &str = "tests/python/mat73_from_v5.py";
const MODULES: &[&str] = &["h5py", "numpy", "scipy"];

/// The v7.3 copy of `v5` written as `out`; `None` when skipped.
fn v73_copy(v5: &Path, out: &Path) -> Option<()> {
    usray_testdata::run_python(MODULES, SCRIPT, &[v5.as_os_str(), out.as_os_str()])
}

/// Variables by name (v7.3 files list them alphabetically, v5 files in the
/// order they were saved).
fn sorted(mut vars: MatFile) -> MatFile {
    vars.sort_by(|a, b| a.0.cmp(&b.0));
    vars
}

/// Every class the v5 reader decodes (numeric classes, complex, char, empty,
/// nested cells, a 1×1 struct, a struct array) reads the same from v7.3.
#[test]
fn every_class_reads_as_from_v5() {
    let dir = tempfile::tempdir().unwrap();
    let (v5, v73) = (dir.path().join("s5.mat"), dir.path().join("s73.mat"));
    let Some(()) = usray_testdata::run_python(
        MODULES,
        SCRIPT,
        &[std::ffi::OsStr::new("--sample"), v5.as_os_str()],
    ) else {
        return;
    };
    v73_copy(&v5, &v73).unwrap();
    let (a, b) = (
        sorted(read_mat(&v5).unwrap()),
        sorted(read_mat(&v73).unwrap()),
    );
    let names: Vec<&str> = a.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        ["cells", "doubles", "empty", "ints", "points", "singles", "text", "z"]
    );
    for ((name, va), (_, vb)) in a.iter().zip(&b) {
        assert_eq!(va, vb, "variable `{name}`");
    }
}

/// `PWI_disk.mat` saved as v7.3 imports to exactly the channel data of the v5
/// original (same file name, so even the recorded source matches).
#[test]
fn pwi_disk_as_v73_imports_like_the_v5_original() {
    let Some(v5) = usray_testdata::data_file("real/PWI_disk.mat") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let v73 = dir.path().join("PWI_disk.mat");
    let Some(()) = v73_copy(&v5, &v73) else {
        return;
    };
    assert!(std::fs::read(&v73)
        .unwrap()
        .starts_with(b"MATLAB 7.3 MAT-file"));
    assert_eq!(import_mat(&v73).unwrap(), import_mat(&v5).unwrap());
    let options = ImportOptions {
        pitch_m: Some(0.35e-3),
        ..Default::default()
    };
    assert_eq!(
        import_mat_with(&v73, &options).unwrap(),
        import_mat_with(&v5, &options).unwrap()
    );
}

/// A v7.3 header over something that is not HDF5 is refused naming the file.
#[test]
fn a_v73_header_without_hdf5_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("fake.mat");
    let mut bytes = b"MATLAB 7.3 MAT-file, not really".to_vec();
    bytes.resize(2048, b' ');
    std::fs::write(&p, bytes).unwrap();
    let e = read_mat(&p).unwrap_err().to_string();
    assert!(e.contains("fake.mat") && e.contains("HDF5"), "{e}");
}

/// Hostile v7.3 files are refused by the v5 reader's limits before memory is
/// spent: an array past `MAX_VALUES` (declared, never written: a few bytes on
/// disk) and a cell that contains itself (stopped at `MAX_NESTING`).
#[test]
fn v73_files_past_the_limits_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let class = |loc: &hdf5::Location, name: &str| {
        let v: hdf5::types::VarLenUnicode = name.parse().unwrap();
        loc.new_attr::<hdf5::types::VarLenUnicode>()
            .create("MATLAB_class")
            .unwrap()
            .write_scalar(&v)
            .unwrap();
    };

    let huge = dir.path().join("huge.mat");
    {
        let f = hdf5::File::create(&huge).unwrap();
        let n = usray_signal::mat::limits::MAX_VALUES + 1;
        let ds = f
            .new_dataset::<f64>()
            .shape([n, 1])
            .chunk([1024, 1])
            .create("big")
            .unwrap();
        class(&ds, "double");
    }
    let e = read_mat(&huge).unwrap_err().to_string();
    assert!(e.contains("huge.mat") && e.contains("MAX_VALUES"), "{e}");

    let cyclic = dir.path().join("cyclic.mat");
    {
        let f = hdf5::File::create(&cyclic).unwrap();
        let ds = f
            .new_dataset::<hdf5::ObjectReference1>()
            .shape([1, 1])
            .create("c")
            .unwrap();
        class(&ds, "cell");
        let itself = f.reference::<hdf5::ObjectReference1>("c").unwrap();
        ds.write_raw(&[itself]).unwrap();
    }
    let e = read_mat(&cyclic).unwrap_err().to_string();
    assert!(e.contains("cyclic.mat") && e.contains("MAX_NESTING"), "{e}");
}
