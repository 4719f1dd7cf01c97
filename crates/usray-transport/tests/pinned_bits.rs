//! The bits of small renders and gradients at a fixed seed, pinned by a hash
//! (FNV-1a over the `f64` bit patterns): a refactoring of the tracer, the
//! sample grid, the pulse or the down-shift that is meant to keep behaviour
//! must keep these hashes. A change of physics changes them on purpose: then
//! re-pin, saying why in the commit.
//!
//! Covered: a plain render (one record per channel), an attenuating render
//! (down-shift node records), the impulse-only render, and the gradient in
//! forward duals (with the pulse-shape and attenuation terms) and in per-path
//! reverse mode (12 parameters).

mod common;
use common::{header, keys, weights};
use usray_transport::scene::Owner;
use usray_transport::{channel_gradient, render, RenderOptions, Scene};

/// FNV-1a of the bit patterns.
fn hash(v: &[f64]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for x in v {
        for b in x.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// A rough cylinder under three steered plane waves, 24 elements, with the
/// given medium attenuation (dB/(cm·MHz)).
fn scene(attenuation: f64) -> Scene {
    let text = header(24, 0.27e-3, "[-5.0, 0.0, 5.0]", 6, 3).replace(
        "impedance_mrayl = 1.5\n",
        &format!("impedance_mrayl = 1.5\nattenuation_db_cm_mhz = {attenuation}\n"),
    ) + r#"
[materials.target]
impedance_mrayl = 1.99
sound_speed_m_s = 1570.0
roughness = 0.3
attenuation_db_cm_mhz = 0.7

[[objects]]
name = "cylinder"
shape = "cylinder"
center_m = [0.001, 0.0, 0.012]
radius_m = 0.004
material = "target"
"#;
    Scene::from_toml_str(&text, "<pinned>", ".").unwrap()
}

fn opts() -> RenderOptions {
    RenderOptions {
        threads: Some(2),
        ..Default::default()
    }
}

#[test]
fn renders_keep_their_bits() {
    let (plain, _) = render(&scene(0.0), &opts()).unwrap();
    let (att, _) = render(&scene(0.5), &opts()).unwrap();
    let impulse = RenderOptions {
        impulse_only: true,
        ..opts()
    };
    let (imp, _) = render(&scene(0.5), &impulse).unwrap();
    let got = [
        (plain.n_samples, hash(&plain.samples)),
        (att.n_samples, hash(&att.samples)),
        (imp.n_samples, hash(&imp.samples)),
    ];
    assert_eq!(got, PINNED_RENDERS);
}

#[test]
fn gradients_keep_their_bits() {
    let s = scene(0.5);
    let (data, _) = render(&s, &opts()).unwrap();
    let w = weights(data.samples.len(), 777);
    let dual = channel_gradient(
        &s,
        &keys(&[
            "objects.cylinder.radius_m",
            "materials.target.impedance_mrayl",
            "probe.center_frequency_hz",
            "probe.cycles",
            "medium.attenuation_db_cm_mhz",
        ]),
        &w,
        &opts(),
    )
    .unwrap();
    let reverse_params: Vec<_> = s
        .params()
        .into_iter()
        .map(|(p, _)| p)
        .filter(|p| p.owner != Owner::Imaging)
        .take(12)
        .collect();
    assert_eq!(reverse_params.len(), 12, "{reverse_params:?}");
    let reverse = channel_gradient(&s, &reverse_params, &w, &opts()).unwrap();
    assert_eq!([hash(&dual), hash(&reverse)], PINNED_GRADIENTS);
}

/// `(n_samples, hash)` of the plain, attenuating and impulse-only renders.
const PINNED_RENDERS: [(usize, u64); 3] = [
    (1625, 4454980342166785432),
    (1625, 6078499491342987169),
    (1625, 15914854763017201676),
];
/// Hashes of the dual-pass and reverse-pass gradients.
const PINNED_GRADIENTS: [u64; 2] = [12282403180781650760, 6316529346207027454];
