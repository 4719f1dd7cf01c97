//! Phased and convex probes, diverging and focused transmits in the sidecar
//! (CONTRACT §2): what is accepted, and bad values refused naming the key.

use usray_signal::ChannelMeta;

fn meta(probe: serde_json::Value, transmits: serde_json::Value) -> ChannelMeta {
    serde_json::from_value(serde_json::json!({
        "format": "usray-channels/1", "sampling_frequency_hz": 20e6, "t0_s": 0.0,
        "sound_speed_m_s": 1540.0, "center_frequency_hz": 3.5e6,
        "probe": probe, "transmits": transmits
    }))
    .unwrap()
}

fn convex(radius: serde_json::Value) -> serde_json::Value {
    serde_json::json!({"kind": "convex", "n_elements": 128, "pitch_m": 0.508e-3,
                       "element_width_m": 0.46e-3, "radius_m": radius})
}

fn phased() -> serde_json::Value {
    serde_json::json!({"kind": "phased", "n_elements": 64, "pitch_m": 0.3e-3, "element_width_m": 0.25e-3})
}

#[test]
fn phased_and_convex_with_every_transmit_kind_are_accepted() {
    let tx = serde_json::json!([
        {"kind": "plane_wave", "angle_rad": 0.1},
        {"kind": "diverging", "virtual_source_m": [0.002, -0.015], "t0_s": -6e-7},
        {"kind": "focused", "focus_m": [0.005, 0.04]}
    ]);
    meta(phased(), tx.clone()).validate().unwrap();
    meta(convex(0.04957.into()), tx).validate().unwrap();
}

#[test]
fn bad_probes_and_transmits_are_refused_naming_the_key() {
    let ok_tx = serde_json::json!([{"kind": "plane_wave", "angle_rad": 0.0}]);
    let cases = [
        // 127 × 0.508 mm / 2 = 32.3 mm is half the aperture.
        (
            meta(convex(0.03.into()), ok_tx.clone()),
            "probe.radius_m",
            "half the aperture",
        ),
        (
            meta(convex("big".into()), ok_tx.clone()),
            "probe.radius_m",
            "finite",
        ),
        (
            meta(
                serde_json::json!({"kind": "phased", "n_elements": 64, "pitch_m": 0.3e-3, "element_width_m": 0.31e-3}),
                ok_tx.clone(),
            ),
            "probe.element_width_m",
            "overlap",
        ),
        (
            meta(
                phased(),
                serde_json::json!([{"kind": "focused", "focus_m": [0.0, -0.01]}]),
            ),
            "transmits[0].focus_m",
            "in front of the array",
        ),
        (
            meta(
                phased(),
                serde_json::json!([{"kind": "diverging", "virtual_source_m": [0.0, 0.01]}]),
            ),
            "transmits[0].virtual_source_m",
            "behind the array",
        ),
        (
            meta(
                phased(),
                serde_json::json!([{"kind": "diverging", "virtual_source_m": [0.0]}]),
            ),
            "transmits[0].virtual_source_m",
            "two finite numbers",
        ),
        (
            meta(phased(), serde_json::json!([{"kind": "focused"}])),
            "transmits[0].focus_m",
            "required",
        ),
    ];
    for (m, key, what) in cases {
        let e = m.validate().unwrap_err();
        assert!(e.contains(key) && e.contains(what), "{key}: {e}");
    }
    // NaN cannot be written in JSON; a NaN that reached the struct is refused too.
    let mut m = meta(
        phased(),
        serde_json::json!([{"kind": "focused", "focus_m": [0.0, 0.04]}]),
    );
    m.transmits[0].extra["focus_m"] = serde_json::json!([f64::NAN, 0.04]);
    let e = m.validate().unwrap_err();
    assert!(e.contains("transmits[0].focus_m"), "{e}");
}

/// A plane-wave file keeps its JSON on a round trip; other kinds need no angle.
#[test]
fn transmit_json_round_trips() {
    let m = meta(
        phased(),
        serde_json::json!([{"kind": "focused", "focus_m": [0.005, 0.04], "t0_s": -1e-6}]),
    );
    assert_eq!(m.transmits[0].angle_rad, 0.0);
    let back: ChannelMeta = serde_json::from_value(serde_json::to_value(&m).unwrap()).unwrap();
    assert_eq!(back, m);
}
