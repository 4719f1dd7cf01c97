//! Scenes: the TOML file of CONTRACT §3, its validation, and its parameters.
//!
//! A [`Scene`] holds the parsed file (every number as `f64`) plus the directory
//! the file lives in (mesh paths are relative to it). It is the single source of
//! truth for parameter values: [`Scene::params`], [`Scene::get`] and
//! [`Scene::set`] address every continuous scalar by its [`ParamKey`] (printed
//! and parsed as its dotted path: [`key`], [`params`]), and [`Scene::lift`] builds the numeric state the tracer uses in
//! any `T: Real`, with chosen parameters seeded as AD variables.

mod acquisition;
mod imaging;
pub mod key;
mod lift;
pub mod params;
mod schema;
mod slots;

pub use key::{Field, ImagingRole, Owner, ParamGroup, ParamKey};
pub use lift::{LumenT, MaterialT, ObjectT, SceneT};
pub use schema::{
    limits, Acquisition, Dimensions, Emission, Imaging, Material, Medium, Object, Probe,
    ReceiveBaffle, ReceiveDirectivity, Sampler, ShapeKind, TransmitSpec,
};

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// An error in a scene: which file, which key, what was expected. Displayed as
/// ``FILE: key `KEY`: MESSAGE``, or `FILE: MESSAGE` when no key is involved
/// (an unreadable scene file).
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// The scene file (or `<memory>` for a scene built from a string).
    pub file: String,
    /// The dotted key (`probe.pitch_m`, `objects.cylinder.radius_m`, …); empty
    /// when the error is about the file as a whole.
    pub key: String,
    /// What was wrong and what was expected.
    pub message: String,
}

impl std::fmt::Display for SceneError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.key.is_empty() {
            write!(f, "{}: {}", self.file, self.message)
        } else {
            write!(f, "{}: key `{}`: {}", self.file, self.key, self.message)
        }
    }
}

impl std::error::Error for SceneError {}

impl SceneError {
    pub(crate) fn new(file: &str, key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            file: file.to_string(),
            key: key.into(),
            message: message.into(),
        }
    }
}

/// A parsed, validated scene (CONTRACT §3).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The background medium.
    pub medium: Medium,
    /// The transducer.
    pub probe: Probe,
    /// Transmits, sampling, ray budget.
    pub acquisition: Acquisition,
    /// Imaging grid and beamformer settings (optional in the file).
    #[serde(default)]
    pub imaging: Imaging,
    /// Materials by name.
    #[serde(default)]
    pub materials: BTreeMap<String, Material>,
    /// Objects, in file order.
    #[serde(default)]
    pub objects: Vec<Object>,
    /// Where the scene came from (file path, or `<memory>`); not a TOML key.
    #[serde(skip)]
    pub source: String,
    /// Directory mesh paths are relative to; not a TOML key.
    #[serde(skip)]
    pub base_dir: PathBuf,
}

impl Scene {
    /// Read, parse and validate a scene file. Errors name the file and the key.
    ///
    /// ```no_run
    /// let scene = usray_transport::Scene::load("scenes/cylinder.toml").unwrap();
    /// assert!(scene.key("objects.cylinder.radius_m").is_ok());
    /// ```
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| SceneError::new(&file, "", format!("cannot read the scene file: {e}")))?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Self::from_toml_str(&text, &file, base)
    }

    /// Parse and validate scene text; `file` names it in errors, `base_dir` is
    /// where relative mesh paths are resolved.
    pub fn from_toml_str(
        text: &str,
        file: &str,
        base_dir: impl Into<PathBuf>,
    ) -> Result<Self, SceneError> {
        let mut scene: Scene = toml::from_str(text).map_err(|e| toml_error(file, text, &e))?;
        scene.source = file.to_string();
        scene.base_dir = base_dir.into();
        scene.validate()?;
        Ok(scene)
    }

    /// The scene as TOML text (for `fitted.toml`).
    pub fn to_toml_string(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_default()
    }

    /// Check every value (finite, in range), every reference (materials, mesh files)
    /// and every shape's required keys. Called by [`Scene::load`] and [`Scene::set`].
    pub fn validate(&self) -> Result<(), SceneError> {
        schema::validate(self)
    }

    /// Sound speed the beamformer assumes: `imaging.sound_speed_m_s`, else the medium's.
    pub fn imaging_sound_speed(&self) -> f64 {
        self.imaging
            .sound_speed_m_s
            .unwrap_or(self.medium.sound_speed_m_s)
    }

    /// Index of an object by name.
    pub fn object_index(&self, name: &str) -> Option<usize> {
        self.objects.iter().position(|o| o.name == name)
    }
}

/// Turn a TOML/serde error into a [`SceneError`] naming the key: serde reports the
/// span; the key is read from the source line (`key = value`) and the table
/// header above it.
fn toml_error(file: &str, text: &str, e: &toml::de::Error) -> SceneError {
    let msg = e.message().trim().to_string();
    let Some(span) = e.span() else {
        return SceneError::new(file, "<document>", msg);
    };
    let start = span.start.min(text.len());
    let line_no = text[..start].matches('\n').count() + 1;
    let line_start = text[..start].rfind('\n').map(|i| i + 1).unwrap_or(0);
    let line_end = text[start..]
        .find('\n')
        .map(|i| start + i)
        .unwrap_or(text.len());
    let line = text[line_start..line_end].trim();
    // The enclosing table: the last header above the line. For an entry of an
    // array of tables (`[[objects]]`), name it by its `name = "…"` key when it has
    // one (`objects.cylinder`), else by its index (`objects.0`).
    let mut table = String::new();
    let mut header_end = 0;
    let mut is_array = false;
    for (pos, l) in line_offsets(&text[..line_start]).into_iter().rev() {
        let l = l.trim();
        if l.starts_with('[') {
            is_array = l.starts_with("[[");
            table = l
                .trim_start_matches('[')
                .trim_end_matches(']')
                .trim()
                .to_string();
            header_end = pos + l.len();
            break;
        }
    }
    if is_array {
        let header = format!("[[{table}]]");
        let index = text[..header_end]
            .matches(header.as_str())
            .count()
            .saturating_sub(1);
        let block_end = text[header_end..]
            .find("\n[")
            .map(|i| header_end + i)
            .unwrap_or(text.len());
        let name = text[header_end..block_end].lines().find_map(|l| {
            let (k, v) = l.split_once('=')?;
            (k.trim() == "name").then(|| v.trim().trim_matches('"').to_string())
        });
        table = match name {
            Some(n) if !n.is_empty() => format!("{table}.{n}"),
            _ => format!("{table}.{index}"),
        };
    }
    let key = if line.starts_with('[') {
        line.trim_start_matches('[')
            .trim_end_matches(']')
            .trim()
            .to_string()
    } else if let Some(eq) = line.find('=') {
        let k = line[..eq].trim();
        if table.is_empty() {
            k.to_string()
        } else {
            format!("{table}.{k}")
        }
    } else if table.is_empty() {
        "<document>".to_string()
    } else {
        table
    };
    SceneError::new(file, key, format!("{msg} (line {line_no})"))
}

/// `(byte offset, line)` of every line of `text`.
fn line_offsets(text: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut pos = 0;
    for l in text.split_inclusive('\n') {
        out.push((pos, l.trim_end_matches('\n')));
        pos += l.len();
    }
    out
}
