//! Checkpoints of long runs: a [`Journal`] keeps the results of a run's
//! expensive, deterministic steps (each fit, each fit's iterations so far) and
//! the decisions it took on the wall clock, in a JSON file rewritten atomically
//! after every entry. A run killed midway and started again on the same journal
//! takes every kept result instead of recomputing it and every kept decision
//! instead of re-deciding, so it ends with the same bits as a run that was never
//! interrupted: the steps are deterministic (random numbers keyed by seed), and
//! `f64` values round-trip exactly through the file (shortest representation
//! written, correctly rounded parsing).
//!
//! ```
//! use usray_optim::Journal;
//! let path = std::env::temp_dir().join(format!("usray-journal-doc-{}.json", std::process::id()));
//! let journal = Journal::open(&path, "problem 1", false).unwrap();
//! let mut calls = 0;
//! let x: f64 = journal.remember("step", || { calls += 1; Ok(0.1 + 0.2) }).unwrap();
//! // Resumed: the kept value comes back, bit for bit, without the work.
//! let resumed = Journal::open(&path, "problem 1", true).unwrap();
//! let y: f64 = resumed.remember("step", || { calls += 1; Ok(0.0) }).unwrap();
//! assert_eq!((x.to_bits(), calls), (y.to_bits(), 1));
//! // A journal of another problem is refused.
//! assert!(Journal::open(&path, "problem 2", true).is_err());
//! std::fs::remove_file(&path).unwrap();
//! ```

use crate::OptimError;
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// The format tag of a journal file.
const JOURNAL_FORMAT: &str = "usray-journal/1";

/// The file and its entries, shared by every handle of one run.
#[derive(Debug)]
struct Store {
    path: PathBuf,
    fingerprint: String,
    entries: Mutex<serde_json::Map<String, serde_json::Value>>,
}

/// A handle on a run's journal (or on none: [`Journal::default`] computes
/// everything and keeps nothing). Handles are cheap to clone; [`Journal::scoped`]
/// gives a handle whose keys carry a prefix (one per diagnosis round).
#[derive(Clone, Debug, Default)]
pub struct Journal {
    store: Option<Arc<Store>>,
    prefix: String,
}

impl Journal {
    /// The journal at `path` for the problem `fingerprint` (any text that
    /// changes when the scene, the data or the options do). With `resume`, the
    /// file must exist and hold that fingerprint, and its entries are reused;
    /// without, the run starts empty and replaces any file there.
    ///
    /// # Errors
    /// With `resume`: a missing or unreadable file, or one of another problem.
    pub fn open(path: &Path, fingerprint: &str, resume: bool) -> Result<Self, OptimError> {
        let entries = if resume {
            let text = std::fs::read_to_string(path).map_err(|e| {
                OptimError::Checkpoint(format!(
                    "cannot resume: no checkpoint at {} ({e})",
                    path.display()
                ))
            })?;
            let bad = |why: &str| {
                OptimError::Checkpoint(format!("cannot resume from {}: {why}", path.display()))
            };
            let v: serde_json::Value =
                serde_json::from_str(&text).map_err(|e| bad(&format!("not JSON ({e})")))?;
            if v["format"] != JOURNAL_FORMAT {
                return Err(bad(&format!("not a {JOURNAL_FORMAT} file")));
            }
            if v["fingerprint"] != fingerprint {
                return Err(bad(
                    "it was written by a run with another scene, data or options; run without --resume to start afresh",
                ));
            }
            v["entries"]
                .as_object()
                .cloned()
                .ok_or_else(|| bad("no entries"))?
        } else {
            serde_json::Map::new()
        };
        Ok(Self {
            store: Some(Arc::new(Store {
                path: path.to_path_buf(),
                fingerprint: fingerprint.to_string(),
                entries: Mutex::new(entries),
            })),
            prefix: String::new(),
        })
    }

    /// A handle whose keys are prefixed by `scope/`.
    pub fn scoped(&self, scope: &str) -> Self {
        Self {
            store: self.store.clone(),
            prefix: format!("{}{scope}/", self.prefix),
        }
    }

    /// Whether entries are kept in a file (not [`Journal::default`]).
    pub fn is_active(&self) -> bool {
        self.store.is_some()
    }

    /// Number of entries kept (0 without a file).
    pub fn len(&self) -> usize {
        self.store
            .as_ref()
            .map_or(0, |s| s.entries.lock().map_or(0, |e| e.len()))
    }

    /// Whether no entry is kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The kept value of `key`, if any.
    pub fn get<T: DeserializeOwned>(&self, key: &str) -> Result<Option<T>, OptimError> {
        let Some(store) = &self.store else {
            return Ok(None);
        };
        let key = format!("{}{key}", self.prefix);
        let entries = store.entries.lock().map_err(|_| poisoned())?;
        entries
            .get(&key)
            .map(|v| {
                serde_json::from_value(v.clone()).map_err(|e| {
                    OptimError::Checkpoint(format!(
                        "{}: entry `{key}` cannot be read back ({e})",
                        store.path.display()
                    ))
                })
            })
            .transpose()
    }

    /// Keeps `value` under `key` and rewrites the file.
    pub fn put<T: Serialize>(&self, key: &str, value: &T) -> Result<(), OptimError> {
        let Some(store) = &self.store else {
            return Ok(());
        };
        let key = format!("{}{key}", self.prefix);
        let v = serde_json::to_value(value)
            .map_err(|e| OptimError::Checkpoint(format!("entry `{key}`: {e}")))?;
        let mut entries = store.entries.lock().map_err(|_| poisoned())?;
        entries.insert(key, v);
        store.write(&entries)
    }

    /// Removes `key` (and rewrites the file) if it is kept.
    pub fn forget(&self, key: &str) -> Result<(), OptimError> {
        let Some(store) = &self.store else {
            return Ok(());
        };
        let mut entries = store.entries.lock().map_err(|_| poisoned())?;
        if entries.remove(&format!("{}{key}", self.prefix)).is_some() {
            store.write(&entries)?;
        }
        Ok(())
    }

    /// The kept result of `key`, or `compute()`'s, kept.
    pub fn remember<T: Serialize + DeserializeOwned>(
        &self,
        key: &str,
        compute: impl FnOnce() -> Result<T, OptimError>,
    ) -> Result<T, OptimError> {
        if let Some(v) = self.get(key)? {
            return Ok(v);
        }
        let v = compute()?;
        self.put(key, &v)?;
        Ok(v)
    }
}

impl Store {
    /// Rewrites the file with `entries`, atomically (a kill while writing
    /// leaves the previous file).
    fn write(
        &self,
        entries: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<(), OptimError> {
        let text = serde_json::to_string(&serde_json::json!({
            "format": JOURNAL_FORMAT,
            "fingerprint": self.fingerprint,
            "entries": entries,
        }))
        .map_err(|e| OptimError::Checkpoint(e.to_string()))?;
        usray_signal::write_atomic(&self.path, |w| w.write_all(text.as_bytes()))?;
        Ok(())
    }
}

fn poisoned() -> OptimError {
    OptimError::Checkpoint("a thread panicked while writing the journal".into())
}
