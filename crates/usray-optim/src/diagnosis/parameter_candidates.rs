//! Candidates of the form "this modelled value is wrong": every continuous scene
//! parameter that the calibration does not fit and that a real acquisition can
//! get wrong, scored like the structural catalogue ([`crate::catalogue`]).
//!
//! A structural candidate switches an effect on from its null (no wall → a
//! wall); a parameter candidate moves a value the scene already has — a hollow
//! cylinder's wall thickness, an object's sound speed, the probe's centre
//! frequency or element width, an attenuation, scattering, depth gain or
//! roughness already switched on — either way from the scene's value, which is
//! its null.

use super::catalogue::{
    sound_speed_tolerance, wall_echo_width_m, wall_learning_rate, wall_onsets,
    wall_thickness_tolerance, Candidate, DEPTH_GAIN_MAX_DB_PER_CM, EFFECT_LEARNING_RATE,
};
use usray_transport::{Field, ParamKey, Scene};

/// Relative half-width of the range of a sound speed or centre frequency
/// candidate (±15%: beyond the spread of soft tissues' speeds, 1450–1640 m/s,
/// about a nominal 1540 m/s; a probe's actual centre frequency is within
/// ±15% of its nominal one for the arrays of PyMUST's `getparam`).
pub(crate) const RELATIVE_RANGE: f64 = 0.15;

/// The parameter candidates of `scene` whose paths are not in `calibrated`
/// (module docs). Each has the scene's value as its null and as its first
/// onset, so that switched on at the null it renders the scene bit for bit.
///
/// ```
/// use usray_optim::parameter_candidates;
/// let scene = usray_transport::Scene::load("../../scenes/ring.toml").unwrap();
/// let c = parameter_candidates(&scene, &[]);
/// let wall = c.iter().find(|c| c.effect == "wall_thickness").unwrap();
/// let tube_wall = usray_transport::ParamKey::object("tube", usray_transport::Field::Thickness);
/// assert_eq!(wall.key, tube_wall);
/// assert_eq!(wall.null, Some(0.001));
/// assert!(wall.two_sided && wall.range.0 < 0.001 && wall.range.1 > 0.001);
/// // A calibrated parameter is not a candidate.
/// let c = parameter_candidates(&scene, &[tube_wall.clone()]);
/// assert!(c.iter().all(|c| c.key != tube_wall));
/// ```
pub fn parameter_candidates(scene: &Scene, calibrated: &[ParamKey]) -> Vec<Candidate> {
    let mut out = Vec::new();
    let free = |key: &ParamKey| !calibrated.contains(key);
    let f_c = scene.probe.center_frequency_hz;
    let lambda = scene.medium.sound_speed_m_s / f_c;
    let two_sided = |effect: &str, key: ParamKey, v: f64, range: (f64, f64), extra: &[f64]| {
        let mut onsets = vec![v];
        onsets.extend(
            extra
                .iter()
                .copied()
                .filter(|x| *x > range.0 && *x < range.1),
        );
        Candidate {
            effect: effect.into(),
            key,
            onsets,
            range,
            two_sided: true,
            null: Some(v),
            fixed: vec![],
            learning_rate: EFFECT_LEARNING_RATE,
            tolerance: None,
            refit_always: false,
            also_scored_from_null: false,
        }
    };
    for o in &scene.objects {
        let (Some(r), Some(t)) = (o.radius_m, o.thickness_m) else {
            continue;
        };
        let path = ParamKey::object(&o.name, Field::Thickness);
        let Some(m) = scene.materials.get(&o.material) else {
            continue;
        };
        if !free(&path) {
            continue;
        }
        // As the structural wall (`catalogue`): the loss's basin is about one
        // echo width `Δt = c_wall·cycles/(2 f_c)` wide, so the onsets are the
        // scene's wall and walls one echo width apart across the radius.
        let dt = wall_echo_width_m(scene, m);
        let range = ((0.25 * lambda).min(0.5 * t), 0.95 * r);
        let mut across = wall_onsets(dt, range.1);
        across.retain(|x| (x - t).abs() > 0.5 * dt);
        let mut c = two_sided("wall_thickness", path, t, range, &across);
        c.learning_rate = wall_learning_rate(dt, range);
        c.tolerance = Some(wall_thickness_tolerance(scene, m.sound_speed_m_s));
        out.push(c);
    }
    // Lumen scatterers already switched on, as a material's below.
    for o in &scene.objects {
        let path = ParamKey::object(&o.name, Field::ScattererStrength);
        if let (Some(v), Some(rho)) = (
            o.lumen_scatterer_strength,
            o.lumen_scatterer_density_per_mm3,
        ) {
            if v > 0.0 && rho > 0.0 && free(&path) {
                out.push(two_sided("volume_scattering", path, v, (0.0, 4.0 * v), &[]));
            }
        }
    }
    let mut materials: Vec<&str> = scene.objects.iter().map(|o| o.material.as_str()).collect();
    materials.sort_unstable();
    materials.dedup();
    for name in materials {
        let Some(m) = scene.materials.get(name) else {
            continue;
        };
        let path = ParamKey::material(name, Field::SoundSpeed);
        if free(&path) {
            let v = m.sound_speed_m_s;
            out.push(two_sided(
                "material_sound_speed",
                path,
                v,
                ((1.0 - RELATIVE_RANGE) * v, (1.0 + RELATIVE_RANGE) * v),
                &[0.95 * v, 1.05 * v],
            ));
        }
        let on = |x: f64| x > 0.0;
        let path = ParamKey::material(name, Field::Attenuation);
        if on(m.attenuation_db_cm_mhz) && free(&path) {
            let v = m.attenuation_db_cm_mhz;
            out.push(two_sided(
                "attenuation",
                path,
                v,
                (0.0, (2.0f64).max(2.0 * v)),
                &[],
            ));
        }
        let path = ParamKey::material(name, Field::ScattererStrength);
        if on(m.scatterer_strength) && on(m.scatterer_density_per_mm3) && free(&path) {
            let v = m.scatterer_strength;
            out.push(two_sided("volume_scattering", path, v, (0.0, 4.0 * v), &[]));
        }
        let path = ParamKey::material(name, Field::Roughness);
        if on(m.roughness) && free(&path) {
            let v = m.roughness;
            out.push(two_sided("roughness", path, v, (0.0, 1.0), &[]));
        }
    }
    let path = ParamKey::medium(Field::Attenuation);
    let v = scene.medium.attenuation_db_cm_mhz;
    if v > 0.0 && free(&path) {
        out.push(two_sided(
            "attenuation",
            path,
            v,
            (0.0, (2.0f64).max(2.0 * v)),
            &[],
        ));
    }
    let c_img = scene.imaging.sound_speed_m_s;
    let path = ParamKey::medium(Field::SoundSpeed);
    let v = scene.medium.sound_speed_m_s;
    if c_img.is_some_and(|c| c != v) && free(&path) {
        // The medium's speed already differs from the beamformer's: the
        // structural candidate is off, this one asks whether the difference is
        // the right one (the structural candidate's range and onsets).
        let mut c = two_sided(
            "sound_speed",
            path,
            v,
            (0.93 * v, 1.07 * v),
            &[0.975 * v, 1.025 * v],
        );
        c.tolerance = Some(sound_speed_tolerance(scene, v));
        c.refit_always = true;
        out.push(c);
    }
    let path = ParamKey::probe(Field::CenterFrequency);
    if free(&path) {
        out.push(two_sided(
            "center_frequency",
            path,
            f_c,
            ((1.0 - RELATIVE_RANGE) * f_c, (1.0 + RELATIVE_RANGE) * f_c),
            &[],
        ));
    }
    let path = ParamKey::probe(Field::ElementWidth);
    let w = scene.probe.element_width_m;
    if scene.probe.n_elements > 1 && free(&path) {
        // Between a third of the pitch and the pitch (kerfless).
        let pitch = scene.probe.pitch_m;
        out.push(two_sided(
            "element_width",
            path,
            w,
            ((pitch / 3.0).min(w), pitch.max(w)),
            &[],
        ));
    }
    let path = ParamKey::acquisition(Field::DepthGain);
    let g = scene.acquisition.depth_gain_db_per_cm;
    if g != 0.0 && free(&path) {
        let span = DEPTH_GAIN_MAX_DB_PER_CM.max(2.0 * g.abs());
        out.push(two_sided("depth_gain", path, g, (-span, span), &[]));
    }
    out
}
