//! File I/O: CONTRACT §2 channel data (`NAME.npy` float32 C order + `NAME.json`),
//! B-mode images as float32 NPY and 8-bit grey PNG, and [`write_atomic`], which every
//! writer here (and the CLI) uses so that no partial file is ever left behind.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use crate::channels::{ChannelData, ChannelMeta};
use crate::error::{Result, SignalError};

/// Write `path` atomically: `write` fills a temporary file in the same directory,
/// which is flushed, synced and renamed onto `path` only if `write` succeeded. On
/// any error the temporary file is removed and `path` is untouched. The file gets
/// the mode any new file gets under the process's umask (0644 under umask 022).
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let p = dir.path().join("a.txt");
/// usray_signal::write_atomic(&p, |w| w.write_all(b"hello")).unwrap();
/// assert_eq!(std::fs::read(&p).unwrap(), b"hello");
/// // A failing writer leaves nothing behind.
/// let q = dir.path().join("b.txt");
/// let r = usray_signal::write_atomic(&q, |w| {
///     w.write_all(b"partial")?;
///     Err(std::io::Error::other("disk full"))
/// });
/// assert!(r.is_err() && !q.exists());
/// ```
pub fn write_atomic<F>(path: impl AsRef<Path>, write: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let path = path.as_ref();
    let tmp = temp_beside(path)?;
    {
        let mut w = BufWriter::new(tmp.as_file());
        write(&mut w).map_err(|e| SignalError::io(path, e))?;
        w.flush().map_err(|e| SignalError::io(path, e))?;
    }
    persist(tmp, path)
}

/// A new temporary file in the directory of `path` (`.usray-tmp-*`), removed when
/// dropped unless [`persist`]ed. A temporary file is private (0600) by default;
/// it is asked for 0666 so that the file renamed into place has the mode the
/// user's umask gives any new file.
pub(crate) fn temp_beside(path: &Path) -> Result<tempfile::NamedTempFile> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".usray-tmp-");
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    builder
        .tempfile_in(&dir)
        .map_err(|e| SignalError::io(path, e))
}

/// Syncs the finished temporary file `tmp` and renames it onto `path`.
pub(crate) fn persist(tmp: tempfile::NamedTempFile, path: &Path) -> Result<()> {
    tmp.as_file()
        .sync_all()
        .map_err(|e| SignalError::io(path, e))?;
    tmp.persist(path)
        .map_err(|e| SignalError::io(path, e.error))?;
    Ok(())
}

/// The `(json, npy)` pair of a channel-data path given as `NAME.json`, `NAME.npy`
/// or the bare stem `NAME`.
pub fn channel_paths(path: impl AsRef<Path>) -> (PathBuf, PathBuf) {
    let p = path.as_ref();
    let stem = match p.extension().and_then(|e| e.to_str()) {
        Some("json") | Some("npy") => p.with_extension(""),
        _ => p.to_path_buf(),
    };
    let mut j = stem.clone().into_os_string();
    j.push(".json");
    let mut n = stem.into_os_string();
    n.push(".npy");
    (PathBuf::from(j), PathBuf::from(n))
}

/// An n-d array read from NPY, as `f64`, C order.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    /// Shape, outermost axis first.
    pub shape: Vec<usize>,
    /// Values in C order.
    pub data: Vec<f64>,
}

/// Read a little-endian `float32` or `float64` NPY array (C order, or Fortran order
/// converted to C order), checking that
/// the file holds exactly as many values as its header announces and that none is
/// NaN or infinite.
pub fn read_npy(path: impl AsRef<Path>) -> Result<NpyArray> {
    let path = path.as_ref();
    let mut bytes = Vec::new();
    File::open(path)
        .and_then(|f| BufReader::new(f).read_to_end(&mut bytes))
        .map_err(|e| SignalError::io(path, e))?;
    let npy = npyz::NpyFile::new(&bytes[..])
        .map_err(|e| SignalError::format(path, format!("not a valid NPY file: {e}")))?;
    let fortran = npy.order() == npyz::Order::Fortran;
    let shape: Vec<usize> = npy.shape().iter().map(|&s| s as usize).collect();
    let n = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .filter(|&n| n.checked_mul(8).is_some())
        .ok_or_else(|| {
            SignalError::format(path, format!("NPY shape {shape:?} is too large to address"))
        })?;
    let dtype = npy.dtype();
    let descr = dtype.descr();
    let width = match descr.as_str() {
        "'<f4'" => 4,
        "'<f8'" => 8,
        other => {
            return Err(SignalError::format(
                path,
                format!("NPY dtype {other} is not supported; float32 ('<f4') is required"),
            ))
        }
    };
    // Data offset from the preamble: magic (6), version (2), header length
    // (u16 for v1, u32 for v2/v3), header.
    let offset = match bytes.get(6) {
        Some(1) if bytes.len() >= 10 => 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize,
        Some(2) | Some(3) if bytes.len() >= 12 => {
            12 + u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize
        }
        _ => return Err(SignalError::format(path, "unknown NPY version")),
    };
    let need = n * width;
    let have = bytes.len().saturating_sub(offset);
    if have != need {
        return Err(SignalError::format(
            path,
            format!(
                "NPY data size mismatch: header says shape {shape:?} of {descr} ({need} bytes of data) but the file holds {have} bytes of data ({})",
                if have < need { "truncated" } else { "extra bytes: mislabelled shape or dtype" }
            ),
        ));
    }
    let data: Vec<f64> = if width == 4 {
        npy.into_vec::<f32>()
            .map_err(|e| SignalError::format(path, format!("NPY data unreadable: {e}")))?
            .into_iter()
            .map(f64::from)
            .collect()
    } else {
        npy.into_vec::<f64>()
            .map_err(|e| SignalError::format(path, format!("NPY data unreadable: {e}")))?
    };
    if data.len() != n {
        return Err(SignalError::format(
            path,
            format!("NPY holds {} values, its header announces {n}", data.len()),
        ));
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(SignalError::format(
            path,
            format!(
                "NPY value at flat index {i} is {} (NaN or infinite samples are not accepted)",
                data[i]
            ),
        ));
    }
    let data = if fortran && shape.len() > 1 {
        // Column-major → row-major: C index of a Fortran-ordered element.
        let mut c = vec![0.0; n];
        let mut idx = vec![0usize; shape.len()];
        for &v in &data {
            let mut off = 0;
            for (k, &i) in idx.iter().enumerate() {
                off = off * shape[k] + i;
            }
            c[off] = v;
            for (k, i) in idx.iter_mut().enumerate() {
                *i += 1;
                if *i < shape[k] {
                    break;
                }
                *i = 0;
            }
        }
        c
    } else {
        data
    };
    Ok(NpyArray { shape, data })
}

/// Write `data` (C order, `shape`) as a float32 NPY file, atomically.
pub fn write_npy_f32(path: impl AsRef<Path>, shape: &[usize], data: &[f64]) -> Result<()> {
    let path = path.as_ref();
    let n: usize = shape.iter().product();
    if n != data.len() {
        return Err(SignalError::Invalid(format!(
            "writing {}: shape {shape:?} needs {n} values, got {}",
            path.display(),
            data.len()
        )));
    }
    let shape64: Vec<u64> = shape.iter().map(|&s| s as u64).collect();
    write_atomic(path, |w| {
        use npyz::WriterBuilder;
        let mut wr = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&shape64)
            .writer(w)
            .begin_nd()?;
        wr.extend(data.iter().map(|&v| v as f32))?;
        wr.finish()
    })
}

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path).map_err(|e| SignalError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| SignalError::format(path, format!("invalid JSON: {e}")))
}

/// Read CONTRACT §2 channel data from `NAME.json` + `NAME.npy` (either path, or the
/// stem). Validates the format tag, required keys, positive finite rates, the NPY
/// shape against the JSON (`[n_transmits, n_elements, n_samples]`), and rejects NaN
/// or infinite samples. Errors name the file and the problem.
pub fn read_channels(path: impl AsRef<Path>) -> Result<ChannelData> {
    let (jpath, npath) = channel_paths(path);
    let value = read_json(&jpath)?;
    let obj = value
        .as_object()
        .ok_or_else(|| SignalError::format(&jpath, "top level is not a JSON object"))?;
    for key in [
        "format",
        "sampling_frequency_hz",
        "t0_s",
        "sound_speed_m_s",
        "center_frequency_hz",
        "probe",
        "transmits",
    ] {
        if !obj.contains_key(key) {
            return Err(SignalError::format(&jpath, format!("missing key `{key}`")));
        }
    }
    let meta: ChannelMeta = serde_json::from_value(value.clone()).map_err(|e| {
        let at = bad_field(&value).map_or(String::new(), |k| format!(" at `{k}`"));
        SignalError::format(&jpath, format!("bad channel metadata{at}: {e}"))
    })?;
    meta.validate()
        .map_err(|w| SignalError::format(&jpath, w))?;
    let arr = read_npy(&npath)?;
    let want = [meta.transmits.len(), meta.probe.n_elements];
    if arr.shape.len() != 3 || arr.shape[0] != want[0] || arr.shape[1] != want[1] {
        return Err(SignalError::format(
            &npath,
            format!(
                "array shape {:?} disagrees with {}: expected [{}, {}, n_samples] (n_transmits = len(transmits), n_elements = probe.n_elements)",
                arr.shape,
                jpath.display(),
                want[0],
                want[1]
            ),
        ));
    }
    if arr.shape[2] == 0 {
        return Err(SignalError::format(
            &npath,
            "the records hold no samples (n_samples = 0)",
        ));
    }
    Ok(ChannelData {
        meta,
        n_samples: arr.shape[2],
        samples: arr.data,
    })
}

/// How many spatial dimensions the simulation that made a channel file had,
/// as the file declares it, and where it says so.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeclaredDimensions {
    /// 2 or 3.
    pub dimensions: u8,
    /// The key and text that declare it (for a report).
    pub evidence: String,
}

/// The spatial dimensions the channel data at `path` (its `.json` sidecar)
/// declare: an optional top-level `"dimensions": 2 | 3` (CONTRACT §2), else a
/// provenance text that names a 2-D simulation, `2-D` or `2D` as a word in
/// `simulation` or in `generator.tool` (what k-Wave's generator in
/// `tools/kwave` and the PyMUST reference data write: `"k-wave-python 0.6.2,
/// 2-D (x, z); …"`, `"PyMUST SIMUS (2-D)"`). `None` when the file says
/// nothing of it, as a scanner's data do.
///
/// ```
/// use usray_signal::io::declared_dimensions_of;
/// let v = serde_json::json!({"simulation": "k-wave-python 0.6.2, 2-D (x, z); scattered field"});
/// assert_eq!(declared_dimensions_of(&v).unwrap().unwrap().dimensions, 2);
/// let v = serde_json::json!({"generator": {"tool": "PyMUST SIMUS (2-D)"}});
/// assert_eq!(declared_dimensions_of(&v).unwrap().unwrap().dimensions, 2);
/// let v = serde_json::json!({"dimensions": 3, "simulation": "2-D"});
/// assert_eq!(declared_dimensions_of(&v).unwrap().unwrap().dimensions, 3);
/// assert!(declared_dimensions_of(&serde_json::json!({"source": "Verasonics"})).unwrap().is_none());
/// assert!(declared_dimensions_of(&serde_json::json!({"simulation": "a 2-Dimensional grid? no: 12-D"})).unwrap().is_none());
/// assert!(declared_dimensions_of(&serde_json::json!({"dimensions": 4})).is_err());
/// ```
///
/// # Errors
/// A `dimensions` key that is not 2 or 3 (a message naming it).
pub fn declared_dimensions_of(
    v: &serde_json::Value,
) -> std::result::Result<Option<DeclaredDimensions>, String> {
    if let Some(d) = v.get("dimensions") {
        return match d.as_u64() {
            Some(n @ (2 | 3)) => Ok(Some(DeclaredDimensions {
                dimensions: n as u8,
                evidence: format!("`dimensions` = {n}"),
            })),
            _ => Err(format!("`dimensions` = {d}: expected 2 or 3")),
        };
    }
    let names_2d = |text: &str| {
        let bytes = text.as_bytes();
        ["2-D", "2D"].iter().any(|w| {
            text.match_indices(w).any(|(i, _)| {
                let before = i.checked_sub(1).map(|k| bytes[k]);
                let after = bytes.get(i + w.len()).copied();
                let word = |b: Option<u8>| b.is_none_or(|b| !b.is_ascii_alphanumeric());
                word(before) && word(after)
            })
        })
    };
    for (key, text) in [
        ("simulation", v.get("simulation")),
        (
            "generator.tool",
            v.get("generator").and_then(|g| g.get("tool")),
        ),
    ] {
        if let Some(text) = text.and_then(|t| t.as_str()).filter(|t| names_2d(t)) {
            return Ok(Some(DeclaredDimensions {
                dimensions: 2,
                evidence: format!("`{key}` = \"{text}\""),
            }));
        }
    }
    Ok(None)
}

/// [`declared_dimensions_of`] the `.json` sidecar of the channel data at
/// `path` (either file, or the stem).
///
/// # Errors
/// A sidecar that cannot be read or parsed, or a bad `dimensions` key
/// (errors name the file).
pub fn declared_dimensions(path: impl AsRef<Path>) -> Result<Option<DeclaredDimensions>> {
    let (jpath, _) = channel_paths(path);
    let value = read_json(&jpath)?;
    declared_dimensions_of(&value).map_err(|e| SignalError::format(&jpath, e))
}

/// The first sidecar key whose value does not have its type (serde_json's
/// message names the type, not the key).
fn bad_field(v: &serde_json::Value) -> Option<String> {
    use serde_json::from_value as de;
    let number = |v: &serde_json::Value| de::<f64>(v.clone()).is_err();
    for k in [
        "sampling_frequency_hz",
        "t0_s",
        "sound_speed_m_s",
        "center_frequency_hz",
    ] {
        if number(&v[k]) {
            return Some(k.into());
        }
    }
    let probe = &v["probe"];
    if de::<usize>(probe["n_elements"].clone()).is_err() {
        return Some("probe.n_elements".into());
    }
    for k in ["pitch_m", "element_width_m"] {
        if number(&probe[k]) {
            return Some(format!("probe.{k}"));
        }
    }
    if de::<String>(probe["kind"].clone()).is_err() {
        return Some("probe.kind".into());
    }
    let transmits = v["transmits"].as_array()?;
    transmits.iter().enumerate().find_map(|(i, t)| {
        if de::<String>(t["kind"].clone()).is_err() {
            Some(format!("transmits[{i}].kind"))
        } else if !t["angle_rad"].is_null() && number(&t["angle_rad"]) {
            Some(format!("transmits[{i}].angle_rad"))
        } else if !t["t0_s"].is_null() && number(&t["t0_s"]) {
            Some(format!("transmits[{i}].t0_s"))
        } else {
            None
        }
    })
}

/// Write channel data as `NAME.json` + `NAME.npy` (float32), each atomically.
/// `path` may be either file or the stem.
pub fn write_channels(path: impl AsRef<Path>, ch: &ChannelData) -> Result<()> {
    let (jpath, npath) = channel_paths(path);
    ch.validate().map_err(SignalError::Invalid)?;
    write_npy_f32(
        &npath,
        &[ch.n_transmits(), ch.n_elements(), ch.n_samples],
        &ch.samples,
    )?;
    let text = serde_json::to_string_pretty(&ch.meta)
        .map_err(|e| SignalError::Invalid(format!("serialising metadata: {e}")))?;
    write_atomic(&jpath, |w| w.write_all(text.as_bytes()))
}

/// Write a B-mode image (`[nz, nx]`, values in `[0, 1]`) as float32 NPY, atomically.
pub fn write_bmode_npy(path: impl AsRef<Path>, nz: usize, nx: usize, data: &[f64]) -> Result<()> {
    write_npy_f32(path, &[nz, nx], data)
}

/// Write a B-mode image (`[nz, nx]`, values in `[0, 1]`, clamped) as an 8-bit grey
/// PNG (row = depth), atomically. Grey level = round(255·v).
pub fn write_bmode_png(path: impl AsRef<Path>, nz: usize, nx: usize, data: &[f64]) -> Result<()> {
    let path = path.as_ref();
    if nz * nx != data.len() || nz == 0 || nx == 0 {
        return Err(SignalError::Invalid(format!(
            "writing {}: image [{nz}, {nx}] needs {} values, got {}",
            path.display(),
            nz * nx,
            data.len()
        )));
    }
    let pixels: Vec<u8> = data
        .iter()
        .map(|&v| {
            let v = if v.is_finite() {
                v.clamp(0.0, 1.0)
            } else {
                0.0
            };
            (v * 255.0).round() as u8
        })
        .collect();
    let img = image::GrayImage::from_raw(nx as u32, nz as u32, pixels)
        .ok_or_else(|| SignalError::Invalid("image buffer size".into()))?;
    let mut buf = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut buf), image::ImageFormat::Png)
        .map_err(|e| SignalError::Invalid(format!("encoding {}: {e}", path.display())))?;
    write_atomic(path, |w| w.write_all(&buf))
}
