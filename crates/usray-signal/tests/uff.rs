//! UFF import and export: a file USTB's Python writer (pyuff_ustb) made imports to
//! the channel data the script states independently; usray → UFF → usray keeps
//! the channel data; what usray cannot map is refused naming it.

use std::path::Path;

use usray_signal::io::read_channels;
use usray_signal::{export_uff, import_mat, import_uff, ChannelData};

const MODULES: &[&str] = &["h5py", "numpy", "pyuff_ustb"];

/// The tests here take turns: HDF5 locks a file through its open file
/// description, which a Python child that another test thread spawns while the
/// file is open inherits, so a concurrent reopen can fail with EAGAIN.
static TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn turn() -> std::sync::MutexGuard<'static, ()> {
    TURN.lock().unwrap_or_else(|e| e.into_inner())
}

/// Channel data without the keys UFF does not carry (everything but `frame` in
/// the `extra` maps: the probe's name, the import's `source`, …).
fn carried(mut ch: ChannelData) -> ChannelData {
    ch.meta.extra.clear();
    ch.meta.probe.extra.clear();
    for t in &mut ch.meta.transmits {
        t.extra.retain(|k, _| k == "frame");
    }
    ch
}

/// pyuff_ustb writes 2 frames × 3 plane waves with different transmit delays;
/// usray imports the values, the angles, the frames and USTB's time origin
/// (t0 = initial_time + delay) exactly.
#[test]
fn a_file_written_by_pyuff_ustb_imports_to_the_stated_channel_data() {
    let _turn = turn();
    let dir = tempfile::tempdir().unwrap();
    let (uff, expected) = (dir.path().join("s.uff"), dir.path().join("expected.json"));
    let Some(()) = usray_testdata::run_python(
        MODULES,
        "tests/python/uff_write.py",
        &[uff.as_os_str(), expected.as_os_str()],
    ) else {
        return;
    };
    let imported = import_uff(&uff).unwrap();
    assert_eq!(imported.meta.extra["source"]["file"], "s.uff");
    assert_eq!(carried(imported), read_channels(&expected).unwrap());
}

/// A file pyuff_ustb wrote with two spherical waves (a virtual source behind
/// the array, a focus in front of it; `tests/data/uff/`, made by
/// `tests/python/uff_write_spherical.py`, committed so no Python runs here):
/// usray imports them as a diverging and a focused transmit at those points,
/// on USTB's clock, with the samples unchanged.
#[test]
fn spherical_waves_written_by_pyuff_ustb_import_as_diverging_and_focused() {
    let _turn = turn();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/uff");
    let (uff, expected) = (
        data.join("spherical.uff"),
        data.join("spherical_expected.json"),
    );
    let imported = import_uff(&uff).unwrap();
    let expected = read_channels(&expected).unwrap();
    assert_eq!(imported.samples, expected.samples);
    assert_eq!(carried(imported.clone()).meta.probe, expected.meta.probe);
    for (a, b) in imported.meta.transmits.iter().zip(&expected.meta.transmits) {
        assert_eq!((&a.kind, a.t0_s), (&b.kind, b.t0_s));
        let key = if a.kind == "diverging" {
            "virtual_source_m"
        } else {
            "focus_m"
        };
        for k in 0..2 {
            let (u, v) = (
                a.extra[key][k].as_f64().unwrap(),
                b.extra[key][k].as_f64().unwrap(),
            );
            assert!((u - v).abs() <= 1e-15, "{key}[{k}]: {u} vs {v}");
        }
    }
    assert_eq!(imported.meta.transmits.len(), 2);
}

/// usray writes PyMUST's point-target channel data (3 angles, a t0 per transmit);
/// pyuff_ustb reads back the rates, probe, angles, time origin and samples; usray
/// imports the file to the same channel data.
#[test]
fn points_round_trip_through_uff_and_read_in_pyuff_ustb() {
    let _turn = turn();
    let Some(points) = usray_testdata::data_file("peers/points.json") else {
        return;
    };
    let original = read_channels(&points).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let uff = dir.path().join("points.uff");
    export_uff(&uff, &original).unwrap();
    assert_eq!(carried(import_uff(&uff).unwrap()), carried(original));
    usray_testdata::run_python(
        MODULES,
        "tests/python/uff_check.py",
        &[uff.as_os_str(), points.as_os_str()],
    );
}

/// The 32 frames of `PWI_disk.mat` become UFF's frame dimension and come back
/// tagged `frame` 0…31.
#[test]
fn frames_round_trip_through_uff() {
    let _turn = turn();
    let Some(mat) = usray_testdata::data_file("real/PWI_disk.mat") else {
        return;
    };
    let original = import_mat(&mat).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let uff = dir.path().join("disk.uff");
    export_uff(&uff, &original).unwrap();
    let back = import_uff(&uff).unwrap();
    assert_eq!(back.n_transmits(), 32);
    assert_eq!(carried(back), carried(original));
}

/// A small plane-wave data set (one transmit, 8 elements).
fn small() -> ChannelData {
    let meta = serde_json::from_value(serde_json::json!({
        "format": "usray-channels/1", "sampling_frequency_hz": 20e6, "t0_s": 1e-6,
        "sound_speed_m_s": 1540.0, "center_frequency_hz": 5e6,
        "probe": {"kind": "linear", "n_elements": 8, "pitch_m": 0.3e-3, "element_width_m": 0.27e-3},
        "transmits": [{"kind": "plane_wave", "angle_rad": 0.05}]
    }))
    .unwrap();
    ChannelData {
        meta,
        n_samples: 16,
        samples: (0..128).map(|i| i as f64).collect(),
    }
}

/// `small()` written to `dir/NAME.uff`, then changed by `edit`.
fn edited(dir: &Path, name: &str, edit: impl FnOnce(&hdf5::File)) -> std::path::PathBuf {
    let p = dir.join(format!("{name}.uff"));
    export_uff(&p, &small()).unwrap();
    edit(&hdf5::File::open_rw(&p).unwrap());
    p
}

fn set_number(file: &hdf5::File, path: &str, v: f64) {
    file.dataset(path).unwrap().write_raw(&[v]).unwrap();
}

/// IQ data, spherical waves without a source, elevated plane waves, a
/// curvilinear probe without a radius, shifted elements and missing fields are
/// each refused with an error naming the file and the field.
#[test]
fn what_usray_cannot_map_is_refused_naming_it() {
    let _turn = turn();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert_eq!(
        carried(import_uff(edited(d, "plain", |_| {})).unwrap()),
        small()
    );
    let cases: Vec<(std::path::PathBuf, &str)> = vec![
        (
            edited(d, "iq", |f| {
                set_number(f, "channel_data/modulation_frequency", 5e6)
            }),
            "IQ",
        ),
        (
            edited(d, "spherical", |f| {
                f.dataset("channel_data/sequence/wavefront")
                    .unwrap()
                    .write_raw(&[1i32])
                    .unwrap()
            }),
            "not a plane wave",
        ),
        (
            edited(d, "elevated", |f| {
                set_number(f, "channel_data/sequence/source/elevation", 0.1)
            }),
            "source/elevation",
        ),
        (
            edited(d, "convex", |f| {
                let p = f.group("channel_data/probe").unwrap();
                p.delete_attr("class").unwrap();
                let v: hdf5::types::VarLenUnicode = "uff.curvilinear_array".parse().unwrap();
                p.new_attr::<hdf5::types::VarLenUnicode>()
                    .create("class")
                    .unwrap()
                    .write_scalar(&v)
                    .unwrap();
            }),
            "probe/radius` is missing",
        ),
        (
            edited(d, "shifted", |f| {
                let g = f.dataset("channel_data/probe/geometry").unwrap();
                let mut v = g.read_raw::<f64>().unwrap();
                v[0] += 0.1e-3;
                g.write_raw(&v).unwrap();
            }),
            "geometry",
        ),
        (
            edited(d, "no_fs", |f| {
                f.unlink("channel_data/sampling_frequency").unwrap()
            }),
            "sampling_frequency` is missing",
        ),
        (
            edited(d, "no_pulse", |f| f.unlink("channel_data/pulse").unwrap()),
            "--fc",
        ),
    ];
    for (path, needle) in cases {
        let e = import_uff(&path).unwrap_err().to_string();
        assert!(
            e.contains(path.file_name().unwrap().to_str().unwrap()) && e.contains(needle),
            "{}: {e}",
            path.display()
        );
    }
    let e = import_uff(d.join("missing.uff")).unwrap_err().to_string();
    assert!(e.contains("missing.uff"), "{e}");
}

/// Frame-tagged transmits that do not repeat one sequence cannot be written, and
/// nothing is left behind.
#[test]
fn irregular_frames_are_not_written() {
    let _turn = turn();
    let mut ch = small();
    let mut second = ch.meta.transmits[0].clone();
    second.angle_rad = 0.2;
    ch.meta.transmits.push(second);
    ch.samples.extend_from_slice(&ch.samples.clone());
    for (i, f) in [0, 1].iter().enumerate() {
        ch.meta.transmits[i]
            .extra
            .insert("frame".into(), (*f).into());
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("frames.uff");
    let e = export_uff(&p, &ch).unwrap_err().to_string();
    assert!(e.contains("frame 1") && e.contains("frames.uff"), "{e}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// Convex probes and non-plane transmits are refused by the writer (it would
/// otherwise write a linear array or a plane wave at angle 0), naming the key.
/// `ch` written to UFF and imported back: the same channel data, the points
/// of the diverging and focused waves to 1e-15 m and the times of sample 0 to
/// 1e-20 s (a convex array's waves pass through USTB's frame and back,
/// `usray_signal::uff`).
fn round_trip(ch: &ChannelData, uff: &Path) {
    export_uff(uff, ch).unwrap();
    let back = import_uff(uff).unwrap();
    assert_eq!(back.samples, ch.samples);
    assert_eq!(back.n_samples, ch.n_samples);
    let (p, q) = (&back.meta.probe, &ch.meta.probe);
    assert_eq!(
        (&p.kind, p.n_elements, p.pitch_m, p.element_width_m),
        (&q.kind, q.n_elements, q.pitch_m, q.element_width_m)
    );
    assert_eq!(p.extra.get("radius_m"), q.extra.get("radius_m"));
    for (i, (a, b)) in back
        .meta
        .transmits
        .iter()
        .zip(&ch.meta.transmits)
        .enumerate()
    {
        assert_eq!(a.kind, b.kind, "transmit {i}");
        let (ta, tb) = (back.meta.t0_for(i), ch.meta.t0_for(i));
        assert!((ta - tb).abs() <= 1e-20, "transmit {i}: t0 {ta} vs {tb}");
        for key in ["virtual_source_m", "focus_m"] {
            if let Some(v) = b.extra.get(key) {
                for k in 0..2 {
                    let (u, w) = (a.extra[key][k].as_f64().unwrap(), v[k].as_f64().unwrap());
                    assert!(
                        (u - w).abs() <= 1e-15,
                        "transmit {i} {key}[{k}]: {u} vs {w}"
                    );
                }
            }
        }
    }
    assert_eq!(back.n_transmits(), ch.n_transmits());
}

/// PyMUST's convex (C5-2v) diverging and phased (P4-2v) focused channel data
/// (`tests/data/probes/`) go through UFF and back; pyuff_ustb reads the convex
/// file as USTB's `CurvilinearArray` with the elements and the virtual sources
/// where USTB's frame (apex at the origin) puts them.
#[test]
fn convex_and_circular_waves_round_trip_through_uff() {
    let _turn = turn();
    let probes = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/probes");
    let dir = tempfile::tempdir().unwrap();
    let c5 = read_channels(probes.join("c5_diverging.json")).unwrap();
    let uff = dir.path().join("c5.uff");
    round_trip(&c5, &uff);
    // P4-2v's pitch, 0.30 mm = 0.53 wavelength at 2.72 MHz, makes it phased again.
    let p4 = read_channels(probes.join("p4_focused.json")).unwrap();
    round_trip(&p4, &dir.path().join("p4.uff"));
    usray_testdata::run_python(
        MODULES,
        "tests/python/uff_check.py",
        &[
            uff.as_os_str(),
            probes.join("c5_diverging.json").as_os_str(),
        ],
    );
}

/// An option a UFF file's import does not use (the file states the clock,
/// angles and layout) is refused naming the flag, not silently ignored.
#[test]
fn options_a_uff_import_does_not_use_are_refused() {
    let _turn = turn();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.uff");
    export_uff(&p, &small()).unwrap();
    let with = |o: usray_signal::ImportOptions| usray_signal::import_uff_with(&p, &o);
    assert!(with(usray_signal::ImportOptions {
        center_frequency_hz: Some(4e6),
        ..Default::default()
    })
    .is_ok());
    let e = with(usray_signal::ImportOptions {
        t0_s: Some(0.0),
        axes: Some(vec![usray_signal::import::Axis::Samples]),
        ..Default::default()
    })
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("--axes") && e.contains("--t0") && e.contains("UFF"),
        "{e}"
    );
}
