//! The impedance an envelope image cannot tell from a fitted one.
//!
//! At normal incidence a wall of impedance `Z` in a background of `Z₁` reflects
//! with `R = (Z − Z₁)/(Z + Z₁)` and passes both ways with `T₁₂T₂₁ = 1 − R²`
//! (Kinsler et al., *Fundamentals of Acoustics*, 4th ed., §6.2). Its *mirror*
//! `Z' = Z₁²/Z` gives `R' = −R` and the same `1 − R²`: every echo keeps its
//! amplitude and at most flips its sign, which the envelope of a B-mode does not
//! show. So an image loss has a second basin at `Z'` (oblique incidence, rough
//! facets and the sound speed break the symmetry only slightly): experiment 2
//! started on the wrong side of `Z₁` ended at 1.1926 MRayl for 1.99, the mirror
//! to 0.07% (`docs/performance.md`, "Samplers").

use usray_transport::scene::Owner;
use usray_transport::{Field, ParamKey, Scene};

/// The mirror `Z₁²/Z` (MRayl) of `value` when `key` is a material's impedance
/// (`materials.NAME.impedance_mrayl`), against the scene's background medium
/// `Z₁ = medium.impedance_mrayl`; `None` for any other parameter or a
/// non-positive value.
///
/// ```
/// # use usray_transport::Scene;
/// # let scene = Scene::from_toml_str(include_str!("../../../scenes/cylinder.toml"), "c.toml", ".").unwrap();
/// use usray_optim::impedance_mirror;
/// use usray_transport::{Field, ParamKey};
/// // Water's 1.54 MRayl around a 1.99 MRayl wall: R = +0.127; the mirror reflects −0.127.
/// let z = ParamKey::material("target", Field::Impedance);
/// let m = impedance_mirror(&scene, &z, 1.99).unwrap();
/// assert!((m - 1.54 * 1.54 / 1.99).abs() < 1e-12);
/// let r = |z: f64| (z - 1.54) / (z + 1.54);
/// assert!((r(m) + r(1.99)).abs() < 1e-12);
/// let radius = ParamKey::object("cylinder", Field::Radius);
/// assert!(impedance_mirror(&scene, &radius, 0.005).is_none());
/// ```
pub fn impedance_mirror(scene: &Scene, key: &ParamKey, value: f64) -> Option<f64> {
    let (Owner::Material(material), Field::Impedance) = (&key.owner, key.field) else {
        return None;
    };
    let background = scene.medium.impedance_mrayl;
    (scene.materials.contains_key(material.as_str()) && value > 0.0 && background > 0.0)
        .then(|| background * background / value)
}
