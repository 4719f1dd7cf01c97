//! Where and how commands write: only inside `--out DIR`, every file atomically and
//! the files of one run as a set ([`OutDir`]).

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::cli::Common;

/// The output directory of a command, written as a set.
///
/// Every file goes first into a staging folder inside `--out`
/// (`.usray-staging-PID/`); [`OutDir::finish`] moves them all in once the command
/// has succeeded, so a failed or killed run adds nothing to `--out` (a kill
/// leaves only the staging folder, which the next run there removes). A lock
/// file (`.usray.lock`, holding the process id and command line) makes a second
/// run into the same `--out` fail at once, naming the first, instead of mixing
/// their files. Creating the lock and the staging folder also proves `--out`
/// writable before any work starts.
pub struct OutDir {
    dir: PathBuf,
    staging: PathBuf,
    lock: PathBuf,
    /// The run's checkpoint, if it keeps one ([`OutDir::journal`]).
    checkpoint: Option<PathBuf>,
    finished: bool,
}

/// `--out` when none is given.
pub const DEFAULT_OUT: &str = "usray-out";

/// Name of the lock file inside an output directory.
const LOCK_NAME: &str = ".usray.lock";
/// Prefix of staging folders inside an output directory.
const STAGING_PREFIX: &str = ".usray-staging-";
/// Prefix of `usray_signal::write_atomic`'s temporary files.
const TEMP_PREFIX: &str = ".usray-tmp-";

impl OutDir {
    /// Creates `dir` (and parents) if needed, takes its lock, removes what
    /// earlier killed runs left there, and opens a staging folder.
    pub fn create(dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output directory {}", dir.display()))?;
        let lock = dir.join(LOCK_NAME);
        take_lock(&lock, dir)?;
        let pid = std::process::id();
        // From here on the lock is ours: build `Self` first so that an error
        // below releases it.
        let out = Self {
            dir: dir.to_path_buf(),
            staging: dir.join(format!("{STAGING_PREFIX}{pid}")),
            lock,
            checkpoint: None,
            finished: false,
        };
        remove_stale(dir)?;
        std::fs::create_dir(&out.staging)
            .with_context(|| format!("cannot write in output directory {}", dir.display()))?;
        Ok(out)
    }

    /// The path `name` is written to (inside the staging folder until
    /// [`OutDir::finish`]).
    pub fn path(&self, name: &str) -> PathBuf {
        self.staging.join(name)
    }

    /// The run's checkpoint `name`, kept in the output directory itself (not the
    /// staging folder) so that it outlives a killed run, and removed by
    /// [`OutDir::finish`]. It records a digest of `problem` — everything that
    /// determines the run's results (scene, data, options) — so that `resume`
    /// refuses the checkpoint of another problem.
    pub fn journal(
        &mut self,
        name: &str,
        problem: &[&dyn std::fmt::Debug],
        resume: bool,
    ) -> Result<usray_optim::Journal> {
        let path = self.dir.join(name);
        let journal = usray_optim::Journal::open(&path, &fingerprint(problem), resume)?;
        self.checkpoint = Some(path);
        Ok(journal)
    }

    /// Moves every staged file into the output directory, removes the checkpoint
    /// (if any) and releases the lock.
    pub fn finish(mut self) -> Result<()> {
        let entries = std::fs::read_dir(&self.staging)
            .with_context(|| format!("reading {}", self.staging.display()))?;
        for entry in entries {
            let entry = entry.with_context(|| format!("reading {}", self.staging.display()))?;
            let target = self.dir.join(entry.file_name());
            std::fs::rename(entry.path(), &target)
                .with_context(|| format!("moving the output into {}", target.display()))?;
        }
        self.finished = true;
        std::fs::remove_dir(&self.staging)
            .with_context(|| format!("removing {}", self.staging.display()))?;
        // The results are written: the checkpoint has done its work.
        if let Some(c) = &self.checkpoint {
            match std::fs::remove_file(c) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(e).with_context(|| format!("removing {}", c.display()))
                }
                _ => {}
            }
        }
        std::fs::remove_file(&self.lock)
            .with_context(|| format!("releasing {}", self.lock.display()))?;
        Ok(())
    }

    /// Writes `value` as pretty JSON to `name`, atomically.
    pub fn write_json(&self, name: &str, value: &serde_json::Value) -> Result<PathBuf> {
        let path = self.path(name);
        let text = serde_json::to_string_pretty(value)?;
        self.write_text_at(&path, &text)?;
        Ok(path)
    }

    /// Writes `text` to `name`, atomically.
    pub fn write_text(&self, name: &str, text: &str) -> Result<PathBuf> {
        let path = self.path(name);
        self.write_text_at(&path, text)?;
        Ok(path)
    }

    fn write_text_at(&self, path: &Path, text: &str) -> Result<()> {
        usray_signal::write_atomic(path, |w| w.write_all(text.as_bytes()))
            .with_context(|| format!("writing {}", path.display()))
    }
}

impl Drop for OutDir {
    /// A run that did not finish leaves nothing: the staging folder and the lock go.
    fn drop(&mut self) {
        if !self.finished {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
        let _ = std::fs::remove_file(&self.lock);
    }
}

/// Creates the lock file `lock` of `dir`, holding this process's id and command
/// line. A lock whose process is gone (a killed run) is taken over; one whose
/// process lives is an error naming it.
fn take_lock(lock: &Path, dir: &Path) -> Result<()> {
    use std::io::Write as _;
    let me = format!(
        "{}\n{}\n",
        std::process::id(),
        std::env::args().collect::<Vec<_>>().join(" ")
    );
    for _ in 0..2 {
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(lock)
        {
            Ok(mut f) => {
                f.write_all(me.as_bytes())
                    .with_context(|| format!("writing {}", lock.display()))?;
                return Ok(());
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let held = std::fs::read_to_string(lock).unwrap_or_default();
                let mut lines = held.lines();
                let pid = lines.next().and_then(|l| l.trim().parse::<u32>().ok());
                let command = lines.next().unwrap_or("?");
                if let Some(pid) = pid.filter(|&p| process_alive(p)) {
                    anyhow::bail!(
                        "output directory {} is in use by another usray run (process {pid}: `{command}`); wait for it to end or choose another --out",
                        dir.display()
                    );
                }
                // The run that held it is gone (or the file is unreadable): stale.
                std::fs::remove_file(lock)
                    .with_context(|| format!("removing the stale lock {}", lock.display()))?;
            }
            Err(e) => {
                return Err(e)
                    .with_context(|| format!("cannot write in output directory {}", dir.display()))
            }
        }
    }
    anyhow::bail!(
        "output directory {}: another usray run took the lock at the same moment",
        dir.display()
    )
}

/// Whether process `pid` is running. Where this cannot be told (no `/proc`), a
/// lock is assumed live: the error then says whose it is.
fn process_alive(pid: u32) -> bool {
    let proc = Path::new("/proc");
    !proc.is_dir() || proc.join(pid.to_string()).exists()
}

/// Removes the staging folders and temporary files killed runs left in `dir`
/// (called under the lock, so no live run owns them).
fn remove_stale(dir: &Path) -> Result<()> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))?;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        let path = entry.path();
        if name.starts_with(STAGING_PREFIX) {
            std::fs::remove_dir_all(&path)
                .with_context(|| format!("removing the stale {}", path.display()))?;
        } else if name.starts_with(TEMP_PREFIX) {
            std::fs::remove_file(&path)
                .with_context(|| format!("removing the stale {}", path.display()))?;
        }
    }
    Ok(())
}

/// `common` with `--out` set to the directory of `--resume DIR`, if given.
///
/// # Errors
/// When `--out` names another directory.
pub fn resumed(common: &Common, resume: Option<&Path>) -> Result<Common> {
    let Some(dir) = resume else {
        return Ok(common.clone());
    };
    anyhow::ensure!(
        common.out == Path::new(DEFAULT_OUT) || common.out == dir,
        "--resume {} continues the run in that directory; --out {} names another",
        dir.display(),
        common.out.display()
    );
    Ok(Common {
        out: dir.to_path_buf(),
        ..common.clone()
    })
}

/// A digest of everything that determines a run's results (scene, data,
/// options, and this build's version), as its checkpoint records it: a
/// checkpoint of another problem is refused on `--resume`. `Debug` prints
/// `f64` in its shortest exact form, so equal inputs give equal digests.
fn fingerprint(parts: &[&dyn std::fmt::Debug]) -> String {
    use std::hash::Hasher as _;
    struct Digest(std::collections::hash_map::DefaultHasher);
    impl std::fmt::Write for Digest {
        fn write_str(&mut self, s: &str) -> std::fmt::Result {
            self.0.write(s.as_bytes());
            Ok(())
        }
    }
    let mut d = Digest(std::collections::hash_map::DefaultHasher::new());
    let _ = std::fmt::Write::write_fmt(&mut d, format_args!("usray {}", env!("CARGO_PKG_VERSION")));
    for p in parts {
        let _ = std::fmt::Write::write_fmt(&mut d, format_args!("\u{1f}{p:?}"));
    }
    format!("{:016x}", d.0.finish())
}

/// A spinner on stderr for long work (hidden with `--quiet` or when stderr is not
/// a terminal).
pub fn spinner(quiet: bool, message: &str) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new_spinner()
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} {msg} [{elapsed}]")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_message(message.to_string());
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

/// Runs `f` in a rayon pool of `threads` workers (0 = every core).
pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> Result<R> {
    if threads == 0 {
        return Ok(f());
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start the worker threads")?;
    Ok(pool.install(f))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_finished_run_moves_its_files_in_and_releases_the_lock() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        let out = OutDir::create(&dir).unwrap();
        out.write_text("a.txt", "a").unwrap();
        out.write_json("b.json", &serde_json::json!({"b": 1}))
            .unwrap();
        assert!(!dir.join("a.txt").exists(), "visible before finish");
        out.finish().unwrap();
        assert_eq!(names(&dir), ["a.txt", "b.json"]);
    }

    #[test]
    fn an_unfinished_run_leaves_nothing() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        std::fs::create_dir(&dir).unwrap();
        std::fs::write(dir.join("earlier.txt"), "kept").unwrap();
        {
            let out = OutDir::create(&dir).unwrap();
            out.write_text("a.txt", "a").unwrap();
        } // dropped, as on an error
        assert_eq!(names(&dir), ["earlier.txt"]);
    }

    #[test]
    fn a_live_lock_is_refused_naming_its_process_and_a_dead_one_is_taken_over() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        std::fs::create_dir(&dir).unwrap();
        // This test's own process is alive.
        std::fs::write(
            dir.join(LOCK_NAME),
            format!("{}\nusray fit other.toml\n", std::process::id()),
        )
        .unwrap();
        let err = OutDir::create(&dir).err().unwrap().to_string();
        assert!(
            err.contains("in use") && err.contains("usray fit other.toml"),
            "{err}"
        );
        // A killed run: its process is gone; its staging folder and temporary
        // file are removed by the next run.
        std::fs::write(dir.join(LOCK_NAME), "999999999\nusray render x.toml\n").unwrap();
        std::fs::create_dir(dir.join(".usray-staging-999999999")).unwrap();
        std::fs::write(dir.join(".usray-staging-999999999/channels.npy"), "x").unwrap();
        std::fs::write(dir.join(".usray-tmp-abc"), "x").unwrap();
        let out = OutDir::create(&dir).unwrap();
        out.write_text("a.txt", "a").unwrap();
        out.finish().unwrap();
        assert_eq!(names(&dir), ["a.txt"]);
    }

    #[cfg(unix)]
    #[test]
    fn files_get_the_umask_mode_not_a_private_one() {
        use std::os::unix::fs::PermissionsExt;
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        let out = OutDir::create(&dir).unwrap();
        out.write_text("a.txt", "a").unwrap();
        out.finish().unwrap();
        // What the umask gives a plainly created file in the same place.
        let probe = dir.join("probe");
        std::fs::write(&probe, "p").unwrap();
        let want = std::fs::metadata(&probe).unwrap().permissions().mode() & 0o777;
        let got = std::fs::metadata(dir.join("a.txt"))
            .unwrap()
            .permissions()
            .mode()
            & 0o777;
        assert_eq!(got, want, "mode {got:o}, umask gives {want:o}");
    }
}
