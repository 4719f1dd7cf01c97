//! Hostile input to the channel-data and MAT readers: every case is refused with
//! an error naming the file and the field, within bounded memory and time, and
//! never a panic. Each case a sweep of bad files found is a regression test here;
//! property tests add generated sidecar values and corrupted MAT bytes.

mod common;
use common::{double, int16, mat_file, matrix, structure, tag};
use proptest::prelude::*;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use usray_signal::mat::{limits, parse_mat};
use usray_signal::{import_mat, read_channels, write_channels, ChannelData, ChannelMeta};

/// A valid sidecar (2 transmits, 4 elements) as JSON, to be spoiled one key at a time.
fn good_sidecar() -> serde_json::Value {
    serde_json::json!({
        "format": "usray-channels/1", "sampling_frequency_hz": 20e6, "t0_s": 0.0,
        "sound_speed_m_s": 1540.0, "center_frequency_hz": 5e6,
        "probe": {"kind": "linear", "n_elements": 4, "pitch_m": 0.3e-3, "element_width_m": 0.27e-3},
        "transmits": [{"kind": "plane_wave", "angle_rad": 0.0}, {"kind": "plane_wave", "angle_rad": 0.1}]
    })
}

/// Writes `sidecar` with a matching NPY (`n_samples` per record) into `dir` as `c.*`.
fn write_pair(dir: &Path, sidecar: &serde_json::Value, n_samples: usize) -> PathBuf {
    let good: ChannelMeta = serde_json::from_value(good_sidecar()).unwrap();
    let data = ChannelData {
        meta: good,
        n_samples: n_samples.max(1),
        samples: vec![0.5; 2 * 4 * n_samples.max(1)],
    };
    let json = dir.join("c.json");
    write_channels(&json, &data).unwrap();
    if n_samples == 0 {
        // An NPY of shape [2, 4, 0], written by hand (the writer refuses it).
        let header = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 4, 0), }";
        let mut h = header.to_string();
        while (10 + h.len() + 1) % 64 != 0 {
            h.push(' ');
        }
        h.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend((h.len() as u16).to_le_bytes());
        bytes.extend(h.as_bytes());
        std::fs::write(dir.join("c.npy"), bytes).unwrap();
    }
    std::fs::write(&json, serde_json::to_string(sidecar).unwrap()).unwrap();
    json
}

/// Sets `value` at the dotted `key` of a JSON object.
fn set(v: &mut serde_json::Value, key: &str, value: serde_json::Value) {
    let mut at = v;
    let parts: Vec<&str> = key.split('.').collect();
    for p in &parts[..parts.len() - 1] {
        at = match p.parse::<usize>() {
            Ok(i) => &mut at[i],
            Err(_) => &mut at[*p],
        };
    }
    at[parts[parts.len() - 1]] = value;
}

#[test]
fn sidecar_values_outside_their_physical_range_are_refused_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, serde_json::Value, &str)] = &[
        ("probe.kind", "sector".into(), "probe.kind"),
        ("probe.kind", "convex".into(), "probe.radius_m"),
        ("probe.radius_m", 1e-3.into(), "probe.radius_m"),
        ("probe.element_width_m", 0.0.into(), "element_width_m"),
        ("probe.element_width_m", (-1.0).into(), "element_width_m"),
        ("probe.element_width_m", 0.5e-3.into(), "element_width_m"),
        ("probe.pitch_m", 1e30.into(), "pitch_m"),
        ("transmits.1.angle_rad", 100.0.into(), "angle_rad"),
        (
            "transmits.1.kind",
            "diverging".into(),
            "transmits[1].virtual_source_m",
        ),
        ("transmits.1.kind", "synthetic".into(), "transmits[1].kind"),
        (
            "sampling_frequency_hz",
            1e300.into(),
            "sampling_frequency_hz",
        ),
        (
            "sampling_frequency_hz",
            1e24.into(),
            "sampling_frequency_hz",
        ),
        ("center_frequency_hz", 1e-300.into(), "center_frequency_hz"),
        ("sound_speed_m_s", 1.0.into(), "sound_speed_m_s"),
        ("t0_s", (-1e300).into(), "t0_s"),
        ("transmits.0.t0_s", 1e300.into(), "t0_s"),
        ("probe.n_elements", 4.7.into(), "n_elements"),
    ];
    for (key, value, named) in cases {
        let mut v = good_sidecar();
        set(&mut v, key, value.clone());
        let json = write_pair(dir.path(), &v, 8);
        let e = read_channels(&json).unwrap_err().to_string();
        assert!(
            e.contains("c.json") && e.contains(named),
            "{key} = {value}: {e}"
        );
    }
    // A record of no samples.
    let json = write_pair(dir.path(), &good_sidecar(), 0);
    let e = read_channels(&json).unwrap_err().to_string();
    assert!(e.contains("c.npy") && e.contains("no samples"), "{e}");
    // The untouched sidecar reads.
    let json = write_pair(dir.path(), &good_sidecar(), 8);
    assert_eq!(read_channels(&json).unwrap().shape(), (2, 4, 8));
}

// ---- MAT v5 bytes ------------------------------------------------------------

/// A Verasonics-style `param` with two elements, `set` replacing field values.
fn param(set: &[(&str, f64)]) -> Vec<u8> {
    let mut f: Vec<(&str, f64)> = vec![
        ("fs", 20e6),
        ("fc", 5e6),
        ("c", 1540.0),
        ("t0", 2e-6),
        ("pitch", 0.3e-3),
        ("width", 0.25e-3),
        ("Nelements", 2.0),
    ];
    for (k, v) in set {
        f.iter_mut().find(|(n, _)| n == k).unwrap().1 = *v;
    }
    let mut fields: Vec<(&str, Vec<u8>)> = f
        .iter()
        .map(|(n, v)| (*n, double("", &[1, 1], &[*v])))
        .collect();
    fields.push(("TXdelay", double("", &[1, 2], &[0.0, 0.0])));
    structure("param", &fields)
}

fn import_bytes(bytes: &[u8]) -> Result<ChannelData, String> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.mat");
    std::fs::write(&p, bytes).unwrap();
    import_mat(&p).map_err(|e| e.to_string())
}

#[test]
fn mat_values_outside_their_range_are_refused_naming_the_field() {
    let rf: Vec<i16> = (0..12).collect();
    let ok = mat_file(&[param(&[]), int16("RF", &[3, 2, 2], &rf)]);
    assert_eq!(import_bytes(&ok).unwrap().shape(), (2, 2, 3));
    for (set, named) in [
        (("Nelements", 2.7), "Nelements"),
        (("width", -0.25e-3), "element_width_m"),
        (("width", 0.5e-3), "element_width_m"),
        (("pitch", 1e30), "pitch_m"),
    ] {
        let bytes = mat_file(&[param(&[set]), int16("RF", &[3, 2, 2], &rf)]);
        let e = import_bytes(&bytes).unwrap_err();
        assert!(e.contains("x.mat") && e.contains(named), "{set:?}: {e}");
    }
    // An RF of no samples.
    let bytes = mat_file(&[param(&[]), int16("RF", &[0, 2, 2], &[])]);
    let e = import_bytes(&bytes).unwrap_err();
    assert!(e.contains("x.mat") && e.contains("no samples"), "{e}");
}

/// `levels` 1×1 cells nested in one another around a scalar, built in one pass
/// (wrapping level by level would copy the whole buffer at every level).
fn nested_cells(levels: usize) -> Vec<u8> {
    let inner = double("", &[1, 1], &[1.0]);
    // Each level adds a 40-byte header (flags 16, dims 16, empty name 8) inside
    // its own 8-byte miMATRIX tag.
    let mut out = Vec::with_capacity(levels * 48 + inner.len());
    for k in (1..=levels).rev() {
        let body_len = 40 + (k - 1) * 48 + inner.len();
        out.extend(14u32.to_le_bytes());
        out.extend((body_len as u32).to_le_bytes());
        out.extend(tag(6, &[1, 0, 0, 0, 0, 0, 0, 0]));
        out.extend(tag(5, &[1, 0, 0, 0, 1, 0, 0, 0]));
        out.extend(tag(1, b""));
    }
    out.extend(inner);
    out
}

/// 100 000 cells nested in one another (a stack overflow before the depth limit).
#[test]
fn deeply_nested_cells_are_refused_not_a_stack_overflow() {
    assert_eq!(
        nested_cells(2),
        matrix(
            "",
            1,
            &[1, 1],
            matrix("", 1, &[1, 1], double("", &[1, 1], &[1.0]))
        )
    );
    let e = parse_mat(&mat_file(&[nested_cells(100_000)])).unwrap_err();
    assert!(
        e.contains("nested deeper than") && e.contains("MAX_NESTING"),
        "{e}"
    );
    // Nesting at the limit still reads.
    assert!(parse_mat(&mat_file(&[nested_cells(limits::MAX_NESTING)])).is_ok());
}

/// A compressed element of a few hundred kB that inflates past the limit.
#[test]
fn a_decompression_bomb_is_refused_at_the_limit() {
    let mut enc = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    // An miMATRIX tag claiming the whole inflated size, then zeros.
    let n = limits::MAX_INFLATED_BYTES + (1 << 20);
    enc.write_all(&14u32.to_le_bytes()).unwrap();
    enc.write_all(&((n - 8) as u32).to_le_bytes()).unwrap();
    std::io::copy(&mut std::io::repeat(0).take(n - 8), &mut enc).unwrap();
    let z = enc.finish().unwrap();
    assert!(z.len() < 1 << 20, "the bomb is small: {} bytes", z.len());
    let e = parse_mat(&mat_file(&[tag(15, &z)])).unwrap_err();
    assert!(
        e.contains("inflates past") && e.contains("MAX_INFLATED_BYTES"),
        "{e}"
    );
}

use std::io::Read as _;

/// Numbers past the value budget are refused before they are converted.
#[test]
fn arrays_past_the_value_budget_are_refused() {
    // A header claiming more values than the budget, over enough bytes to pass the
    // dimension-against-bytes check (1 byte per value: int8).
    let n = limits::MAX_VALUES + 8;
    let body = tag(1, &vec![0u8; n]);
    let big = matrix("big", 8, &[n as i32, 1], body);
    let e = parse_mat(&mat_file(&[big])).unwrap_err();
    assert!(e.contains("big") && e.contains("MAX_VALUES"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any sidecar number, however huge, tiny or non-finite, reads or is refused:
    /// never a panic, and a value that reads is in its physical range.
    #[test]
    fn any_sidecar_number_reads_or_is_refused(
        key in prop::sample::select(vec![
            "sampling_frequency_hz", "t0_s", "sound_speed_m_s", "center_frequency_hz",
            "probe.pitch_m", "probe.element_width_m", "transmits.0.angle_rad", "transmits.1.t0_s",
        ]),
        value in prop_oneof![
            any::<f64>(),
            prop::sample::select(vec![0.0, -0.0, 1e-300, -1e300, 1e300, f64::MAX, f64::MIN_POSITIVE]),
        ],
    ) {
        let dir = tempfile::tempdir().unwrap();
        let mut v = good_sidecar();
        // serde_json writes non-finite numbers as null, which is refused too.
        set(&mut v, key, serde_json::json!(value));
        let json = write_pair(dir.path(), &v, 8);
        match read_channels(&json) {
            Ok(ch) => prop_assert!(ch.meta.validate().is_ok()),
            Err(e) => prop_assert!(e.to_string().contains("c.json"), "{}", e),
        }
    }

    /// A valid MAT file with bytes overwritten anywhere imports or is refused,
    /// never a panic.
    #[test]
    fn corrupted_mat_bytes_import_or_are_refused(
        edits in prop::collection::vec((0usize..1000, any::<u8>()), 1..8),
    ) {
        let rf: Vec<i16> = (0..12).collect();
        let mut bytes = mat_file(&[param(&[]), int16("RF", &[3, 2, 2], &rf)]);
        for (at, b) in edits {
            let i = at % bytes.len();
            bytes[i] = b;
        }
        if let Err(e) = import_bytes(&bytes) {
            prop_assert!(e.contains("x.mat"), "{}", e);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// A valid NPY file with bytes of its header (or the first data) overwritten
    /// reads or is refused naming the file: never a panic, and an array that
    /// reads holds as many values as its shape says.
    #[test]
    fn corrupted_npy_headers_read_or_are_refused(
        edits in prop::collection::vec((0usize..140, any::<u8>()), 1..6),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let json = write_pair(dir.path(), &good_sidecar(), 8);
        let npy = json.with_extension("npy");
        let mut bytes = std::fs::read(&npy).unwrap();
        for (at, b) in edits {
            let i = at % bytes.len();
            bytes[i] = b;
        }
        std::fs::write(&npy, &bytes).unwrap();
        match usray_signal::io::read_npy(&npy) {
            Ok(a) => prop_assert_eq!(a.data.len(), a.shape.iter().product::<usize>()),
            Err(e) => prop_assert!(e.to_string().contains("c.npy"), "{}", e),
        }
    }
}
