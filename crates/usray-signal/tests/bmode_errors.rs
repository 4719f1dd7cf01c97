//! Bad input to `BMode` is an error, never a panic: channel data of another shape,
//! cotangents of the wrong length, a VJP before any forward pass, a workspace of
//! another operator, and malformed `frame` keys.

mod common;
use common::*;
use usray_signal::{read_channels, write_channels, BMode, ChannelData, ImagingSettings};

fn data(nt: usize, ne: usize, ns: usize) -> ChannelData {
    let angles = vec![0.0; nt];
    let t0s = vec![0.0; nt];
    let mut r = Rng(1);
    ChannelData {
        meta: meta(ne, 20e6, 5e6, &angles, &t0s),
        n_samples: ns,
        samples: r.vec(nt * ne * ns),
    }
}

fn settings() -> ImagingSettings {
    ImagingSettings::new([-1e-3, 1e-3], [2e-3, 4e-3], 0.25e-3)
}

#[test]
fn forward_with_other_shape_is_an_error_naming_both_shapes() {
    let ch = data(2, 8, 100);
    let b = BMode::new(&settings(), &ch.meta, ch.n_samples).unwrap();
    let mut ws = b.workspace();
    for other in [data(2, 8, 120), data(3, 8, 100), data(2, 6, 100)] {
        let e = b.forward(&other, &mut ws).unwrap_err().to_string();
        let (t, el, s) = other.shape();
        assert!(
            e.contains("expected [2, 8, 100]") && e.contains(&format!("[{t}, {el}, {s}]")),
            "{e}"
        );
    }
    // Samples vector inconsistent with the shape the metadata declares.
    let mut short = ch.clone();
    short.samples.pop();
    let e = b.forward(&short, &mut ws).unwrap_err().to_string();
    assert!(
        e.contains("1599 samples") && e.contains("1600 samples"),
        "{e}"
    );
    // No forward succeeded on `ws`: the VJP refuses.
    let e = b.vjp(&mut ws, &vec![0.0; 9 * 9]).unwrap_err().to_string();
    assert!(e.contains("forward"), "{e}");
}

#[test]
fn vjp_lengths_and_foreign_workspace_are_errors() {
    let ch = data(1, 8, 100);
    let b = BMode::new(&settings(), &ch.meta, ch.n_samples).unwrap();
    let mut ws = b.workspace();
    let img = b.forward(&ch, &mut ws).unwrap();
    let n = img.data.len();
    let e = b.vjp(&mut ws, &vec![1.0; n + 1]).unwrap_err().to_string();
    assert!(
        e.contains(&format!("{}", n + 1)) && e.contains(&format!("{n}")),
        "{e}"
    );
    let e = b.calibration_vjp(&mut ws, &[1.0]).unwrap_err().to_string();
    assert!(e.contains("d_image has 1 values"), "{e}");
    let mut short = vec![0.0; ch.samples.len() - 1];
    let e = b
        .vjp_into(&mut ws, &vec![1.0; n], &mut short)
        .unwrap_err()
        .to_string();
    assert!(e.contains("d_channels"), "{e}");
    assert!(b.vjp(&mut ws, &vec![1.0; n]).is_ok());
    assert!(b.calibration_vjp(&mut ws, &vec![1.0; n]).is_ok());
    // A workspace from an operator on another grid.
    let b2 = BMode::new(
        &ImagingSettings::new([-1e-3, 1e-3], [2e-3, 5e-3], 0.25e-3),
        &ch.meta,
        ch.n_samples,
    )
    .unwrap();
    let mut ws2 = b2.workspace();
    let e = b.forward(&ch, &mut ws2).unwrap_err().to_string();
    assert!(e.contains("workspace"), "{e}");
}

#[test]
fn degenerate_shapes_are_errors_at_construction() {
    let ch = data(1, 8, 100);
    assert!(BMode::new(&settings(), &ch.meta, 0).is_err());
    let mut m = ch.meta.clone();
    m.transmits.clear();
    assert!(BMode::new(&settings(), &m, 100).is_err());
    let mut m = ch.meta.clone();
    m.probe.n_elements = 0;
    assert!(BMode::new(&settings(), &m, 100).is_err());
    let mut m = ch.meta.clone();
    m.sampling_frequency_hz = f64::NAN;
    assert!(BMode::new(&settings(), &m, 100).is_err());
    let huge = ImagingSettings::new([-1.0, 1.0], [0.0, 1.0], 1e-4);
    let e = BMode::new(&huge, &ch.meta, 100).unwrap_err().to_string();
    assert!(e.contains("too large"), "{e}");
}

#[test]
fn frame_keys_are_validated_and_round_trip() {
    let mut ch = data(3, 8, 50);
    for (t, f) in ch.meta.transmits.iter_mut().zip([0u64, 1, 1]) {
        t.extra.insert("frame".into(), f.into());
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c");
    write_channels(&p, &ch).unwrap();
    let back = read_channels(&p).unwrap();
    assert_eq!(back.meta.frames().unwrap(), vec![vec![0], vec![1, 2]]);
    assert_eq!(
        BMode::new(&settings(), &back.meta, 50).unwrap().n_frames(),
        2
    );
    // Mixed: some transmits tagged, some not.
    let mut mixed = ch.clone();
    mixed.meta.transmits[1].extra.remove("frame");
    let e = BMode::new(&settings(), &mixed.meta, 50)
        .unwrap_err()
        .to_string();
    assert!(e.contains("transmits[1]") && e.contains("frame"), "{e}");
    assert!(write_channels(dir.path().join("m"), &mixed).is_err());
    // Not a non-negative integer: refused by the reader, naming the file.
    let json = std::fs::read_to_string(p.with_extension("json")).unwrap();
    for bad in ["-1", "1.5", "\"a\""] {
        let j = json.replacen("\"frame\": 1", &format!("\"frame\": {bad}"), 1);
        assert_ne!(j, json);
        std::fs::write(p.with_extension("json"), j).unwrap();
        let e = read_channels(&p).unwrap_err().to_string();
        assert!(
            e.contains("c.json") && e.contains("non-negative integer"),
            "{e}"
        );
    }
}

/// A sidecar's huge sampling frequency or time origin puts every delay past the
/// record: the image is formed (all dark), not a panic (issue 23: `das.rs`
/// indexed past the data when `as usize` saturated).
#[test]
fn huge_sampling_frequency_or_time_origin_does_not_panic() {
    for (fs, t0) in [(1e300, 0.0), (1e24, 0.0), (20e6, -1e300), (20e6, 1e300)] {
        let mut ch = data(1, 8, 100);
        ch.meta.sampling_frequency_hz = fs;
        ch.meta.t0_s = t0;
        let Ok(b) = BMode::new(&settings(), &ch.meta, ch.n_samples) else {
            continue; // refused up front: as good
        };
        let mut ws = b.workspace();
        if let Ok(img) = b.forward(&ch, &mut ws) {
            assert!(img.data.iter().all(|v| v.is_finite()), "fs {fs}, t0 {t0}");
        }
    }
}
