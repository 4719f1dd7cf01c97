//! Locates the shared reference data that usray's tests read in place.
//!
//! Lookup order: `$USRAY_TEST_DATA`, then `../shared/data` next to the workspace
//! root. A user's fresh clone has neither: [`data_file`] then prints that the test
//! was skipped and returns `None`, so the test passes. Under CI (`CI=true`) missing
//! data is a failure, so a wrong path can never pass silently.
//!
//!
//! Tests that run a Python script (fixtures written or checked with h5py,
//! pyuff_ustb, …) get the interpreter from [`python`], which treats a missing
//! `python3` or module the same way: skipped locally, a failure under CI.
//!
//! ```
//! // In a test:
//! let Some(path) = usray_testdata::data_file("peers/points.json") else { return };
//! assert!(path.exists());
//! ```

use std::path::PathBuf;

/// The data root, if one exists: `$USRAY_TEST_DATA`, else `<workspace>/../shared/data`.
///
/// The workspace is found **at run time**: the nearest ancestor holding
/// `Cargo.lock` of the directory `cargo test` runs the test from
/// (`$CARGO_MANIFEST_DIR`, else the current directory). A compile-time
/// `env!("CARGO_MANIFEST_DIR")` would go stale when a build cache is reused from a
/// checkout at another path (cargo does not rebuild a path crate that moved).
pub fn data_root() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("USRAY_TEST_DATA") {
        let dir = PathBuf::from(dir);
        return dir.is_dir().then_some(dir);
    }
    let dir = workspace_root()?.join("../shared/data");
    dir.is_dir().then(|| dir.canonicalize().unwrap_or(dir))
}

/// The workspace root, found **at run time** as the nearest ancestor holding
/// `Cargo.lock` of `$CARGO_MANIFEST_DIR` (set by `cargo test` for the crate under
/// test), else of the current directory.
pub fn workspace_root() -> Option<PathBuf> {
    let start = std::env::var_os("CARGO_MANIFEST_DIR")
        .map(PathBuf::from)
        .or_else(|| std::env::current_dir().ok())?;
    start
        .ancestors()
        .find(|d| d.join("Cargo.lock").is_file())
        .map(PathBuf::from)
}

/// The path of a file the repository itself ships (e.g. `"scenes/cylinder.toml"`),
/// found at run time like [`workspace_root`], so a build cache reused from a
/// checkout at another path still reads this checkout's files.
///
/// ```
/// let scene = usray_testdata::workspace_file("scenes/cylinder.toml");
/// assert!(scene.is_file());
/// ```
///
/// # Panics
/// When no workspace root is found (the test runs outside the repository).
pub fn workspace_file(relative: &str) -> PathBuf {
    workspace_root()
        .unwrap_or_else(|| {
            panic!("no workspace (Cargo.lock) above $CARGO_MANIFEST_DIR or the current directory, looking for `{relative}`")
        })
        .join(relative)
}

/// True when running under CI (`CI` set to `true` or `1`).
pub fn under_ci() -> bool {
    matches!(std::env::var("CI").as_deref(), Ok("true") | Ok("1"))
}

/// The path of `relative` (e.g. `"real/PWI_disk.mat"`) inside the data root.
///
/// Returns `None` and prints a skip notice when the file is missing outside CI.
///
/// # Panics
/// Under CI (`CI=true`) a missing file panics, naming every place looked in.
pub fn data_file(relative: &str) -> Option<PathBuf> {
    let found = data_root()
        .map(|root| root.join(relative))
        .filter(|p| p.exists());
    if found.is_none() {
        let msg = format!(
            "test data `{relative}` not found (looked in $USRAY_TEST_DATA = {:?}, then ../shared/data beside the workspace)",
            std::env::var_os("USRAY_TEST_DATA")
        );
        if under_ci() {
            panic!("{msg}; CI=true, so missing data is a failure");
        }
        eprintln!("SKIPPED: {msg}");
    }
    found
}

/// Runs the repository's Python script `script` (a path from the workspace root,
/// e.g. `"tests/python/uff_check.py"`) with `args`, if `python3` runs and imports
/// every module of `modules` (e.g. `["h5py", "pyuff_ustb"]`; CI installs them from
/// `ci/requirements.txt`).
///
/// Returns `None` and prints a skip notice when either is missing outside CI.
///
/// # Panics
/// Under CI (`CI=true`) a missing interpreter or module panics, naming it; the
/// script exiting non-zero panics with its output.
pub fn run_python<A: AsRef<std::ffi::OsStr>>(
    modules: &[&str],
    script: &str,
    args: &[A],
) -> Option<()> {
    let probe = std::process::Command::new("python3")
        .arg("-c")
        .arg(format!("import {}", modules.join(", ")))
        .output();
    let missing = match probe {
        Err(e) => Some(format!("python3 cannot be run ({e})")),
        Ok(o) if !o.status.success() => Some(format!(
            "python3 lacks a module of {modules:?}: {}",
            String::from_utf8_lossy(&o.stderr).trim()
        )),
        Ok(_) => None,
    };
    if let Some(msg) = missing {
        if under_ci() {
            panic!("{msg}; CI=true, so a missing Python dependency is a failure (pip install -r ci/requirements.txt)");
        }
        eprintln!("SKIPPED: {msg} (pip install -r ci/requirements.txt)");
        return None;
    }
    let path = workspace_file(script);
    let out = std::process::Command::new("python3")
        .arg(&path)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run python3 {}: {e}", path.display()));
    assert!(
        out.status.success(),
        "python3 {} failed ({}):\n{}\n{}",
        path.display(),
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    Some(())
}
