//! The structural candidate effects of a diagnosis (CONTRACT §3): what may be
//! missing from the scene, how to switch it on and which parameter carries its
//! strength. The candidates "this modelled value is wrong" are in
//! `parameter_candidates`.

use crate::OptimError;
use usray_transport::scene::{Material, Owner, ShapeKind};
use usray_transport::{Field, ParamKey, Scene};

/// Fixed density of the `volume_scattering` candidate, scatterers per mm³ (well
/// above the ≈ 10 per resolution cell of fully developed speckle at 5 MHz); its
/// strength is what is scored and fitted.
pub(crate) const SCATTERER_DENSITY_PER_MM3: f64 = 5.0;

/// Onsets of a `volume_scattering` candidate's strength (range
/// 0–[`SCATTERER_STRENGTH_MAX`] at [`SCATTERER_DENSITY_PER_MM3`]): a faint
/// speckle first, then ×3 and ×9. A
/// speckle much fainter than the measured one lies below the display's floor,
/// where the clip map's derivative is zero (paper eq. clip_grad) and the loss
/// is flat: k-Wave's lumen speckle at about −25 dB scored 0.001 from 0.035
/// alone. The best by loss is scored, as for the sound speed.
pub(crate) const SCATTERER_STRENGTH_ONSETS: [f64; 3] = [0.035, 0.1, 0.3];

/// Largest strength of a `volume_scattering` candidate. Power per volume goes
/// as ρ·strength² (`ScattererField`); what a B-mode shows is the speckle
/// against the scene's brightest echo, so the strength that matters depends on
/// the scene's reflectors. Behind the k-Wave ring's weak wall (R = 0.09,
/// `bench/kwave/g1.toml`) 0.7 makes a lumen speckle at about −30 dB, and its
/// refit to k-Wave's lumen speckle stopped at 0.7 when that was the bound;
/// 2 reaches a speckle as bright as such a wall's echo.
pub(crate) const SCATTERER_STRENGTH_MAX: f64 = 2.0;

/// Largest depth gain the `depth_gain` candidate may take, dB/cm: the two-way
/// attenuation `2αf_c` of 1 dB/(cm·MHz) at 5 MHz.
pub(crate) const DEPTH_GAIN_MAX_DB_PER_CM: f64 = 10.0;

/// Onsets of the `pulse_length` candidate, in multiples of the scene's cycles
/// (the null first; its range is 0.5–3 times).
pub(crate) const PULSE_LENGTH_ONSETS: [f64; 4] = [1.0, 0.7, 1.4, 2.0];

/// Learning rate of an effect's strength in a confirming refit, in fractions of
/// its range per step (the calibrated parameters keep their groups' rates).
pub(crate) const EFFECT_LEARNING_RATE: f64 = 0.05;

/// Interactions a path gains when a `wall_thickness` candidate hollows a solid
/// cylinder: one crossing of the near wall's inner surface and one of the far
/// wall's inner surface before the far outer surface is reached (a path that
/// met the solid cylinder twice meets the tube four times).
const WALL_EXTRA_BOUNCES: u32 = 2;

/// The bounce limit a diagnosis renders every model at: the scene's
/// `acquisition.max_bounces` raised by the most any candidate of its catalogue
/// needs ([`Candidate::extra_bounces`]), capped at the schema's largest. The
/// calibration, the null refit and every candidate use it alike, so they
/// compare on equal terms.
///
/// Why: a branch stops after `max_bounces` interactions, transmissions
/// included (`usray_transport::integrator`, step 6). At the limit that just
/// reaches a solid cylinder's far side, a hollowed one loses its far wall, and
/// the true wall renders worse than no wall: a 1 mm wall in a 3 mm rod under
/// a 2 mm layer (`bench/tier_a/a3_layered.toml`, 4 bounces) had a loss of
/// 0.0539 against the solid rod's 0.0501; at 6 bounces, 0.0332 against 0.0500.
///
/// ```
/// use usray_optim::diagnosis_bounces;
/// let mut s = usray_transport::Scene::load("../../scenes/cylinder.toml").unwrap();
/// s.acquisition.max_bounces = 4;
/// assert_eq!(diagnosis_bounces(&s), 6); // a solid cylinder: a wall candidate
/// s.objects[0].thickness_m = Some(1e-3);
/// assert_eq!(diagnosis_bounces(&s), 4); // already a tube: none
/// ```
pub fn diagnosis_bounces(scene: &Scene) -> u32 {
    let extra = catalogue(scene)
        .iter()
        .map(Candidate::extra_bounces)
        .max()
        .unwrap_or(0);
    (scene.acquisition.max_bounces + extra).min(usray_transport::scene::limits::MAX_BOUNCES)
}

/// One candidate unmodelled effect: how to switch it on and which parameter
/// carries its strength.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// Effect name (CONTRACT §5): `wall_thickness`, `attenuation`, …
    pub effect: String,
    /// The strength parameter once switched on.
    pub key: ParamKey,
    /// Values at which it may be scored: the null where the model is smooth
    /// there; else a few values across the range (the best by loss is scored).
    pub onsets: Vec<f64>,
    /// Admissible range of the parameter in a refit.
    pub range: (f64, f64),
    /// Whether the parameter may move either way from its null (sound speed,
    /// pulse length) or only up (thickness, attenuation, scattering, depth
    /// gain).
    pub two_sided: bool,
    /// The parameter's *null*: the value at which the effect is off and the
    /// scene renders as the base model, bit for bit (checked in
    /// `tests/diagnosis.rs`). `None` for a wall, whose null — a solid
    /// cylinder — is a change of structure, not a thickness.
    pub null: Option<f64>,
    /// Other scene values set with the switch (e.g. the scatterer density).
    pub fixed: Vec<(ParamKey, f64)>,
    /// Learning rate of the strength in a confirming refit, in fractions of
    /// [`Candidate::range`] per step (0.05 unless the loss's
    /// basin is narrower than the range, as for a wall).
    pub learning_rate: f64,
    /// The smallest departure of the parameter from its null that matters to
    /// the image, in the parameter's unit (`None`: any departure the data
    /// resolve matters). A refit within it is not named, however significant
    /// its gain ([`crate::EffectResult::within_tolerance`]). Set for the
    /// medium's sound speed ([`sound_speed_tolerance`]) and a modelled wall's
    /// thickness ([`wall_thickness_tolerance`]).
    pub tolerance: Option<f64>,
    /// Refitted whatever its score, beside the best-scoring candidates
    /// ([`crate::DiagnoseOptions::confirm_top`]), from its best onset away
    /// from the null when the null scored best. Set for the medium's sound
    /// speed: a speed error rescales every depth, the calibration can take it
    /// up in the geometry (a radius that puts the brighter wall where the
    /// wrong speed shows it), and at the calibrated point no speed alone then
    /// lowers the loss; refitted jointly with the base parameters from a
    /// departure, it is found (docs/diagnosis.md, "Known limits").
    pub refit_always: bool,
    /// Scored from its null alone as well as from the best of its onsets,
    /// keeping the better score ([`crate::score_candidate`]): set where an
    /// onset comes from outside the image (the centre the echoes' spectra
    /// show, `widen_centre_frequency`), which may add to the score the
    /// one-gradient screen at the modelled value gives but not take from it.
    pub also_scored_from_null: bool,
}

impl Candidate {
    /// Interactions a path may gain once this effect is switched on, which the
    /// bounce limit must allow for ([`diagnosis_bounces`]): two for a wall
    /// that hollows a solid cylinder (a thickness without a null), none for an
    /// effect that changes values rather than structure.
    pub fn extra_bounces(&self) -> u32 {
        if self.key.field == Field::Thickness && self.null.is_none() {
            WALL_EXTRA_BOUNCES
        } else {
            0
        }
    }

    /// `scene` with this effect switched on at `value` (and its fixed settings).
    ///
    /// # Errors
    /// A parameter the scene does not have.
    pub fn switched_on(&self, scene: &Scene, value: f64) -> Result<Scene, OptimError> {
        let mut s = scene.clone();
        switch_on(&mut s, &self.key, value)?;
        for (k, v) in &self.fixed {
            switch_on(&mut s, k, *v)?;
        }
        Ok(s)
    }
}

/// Sets `key` to `value`, creating the optional keys an effect switches on
/// (`objects.NAME.thickness_m`, `objects.NAME.lumen_scatterer_*`,
/// `imaging.sound_speed_m_s`).
fn switch_on(s: &mut Scene, key: &ParamKey, value: f64) -> Result<(), OptimError> {
    match (&key.owner, key.field) {
        (
            Owner::Object(name),
            field @ (Field::Thickness | Field::ScattererStrength | Field::ScattererDensity),
        ) => {
            let o = s
                .objects
                .iter_mut()
                .find(|o| o.name == *name)
                .ok_or_else(|| OptimError::Diagnosis(format!("no object `{name}` for {key}")))?;
            let slot = match field {
                Field::Thickness => &mut o.thickness_m,
                Field::ScattererStrength => &mut o.lumen_scatterer_strength,
                _ => &mut o.lumen_scatterer_density_per_mm3,
            };
            *slot = Some(value);
        }
        (Owner::Imaging, Field::SoundSpeed) => s.imaging.sound_speed_m_s = Some(value),
        _ => s.set(key, value)?,
    }
    s.validate()?;
    Ok(())
}

/// The smallest error of the medium's sound speed `c` that matters to the
/// image of `scene`, m/s. Beamformed at the wrong speed, an echo at depth `z`
/// is misplaced by `z·Δc/c`, a two-way path error of `2z·Δc/c`; by Rayleigh's
/// quarter-wavelength rule (Born & Wolf, *Principles of Optics*, §9.3) a path
/// error under `λ/4` leaves an image essentially as it was. At the image's
/// deepest row `z_max` that gives `Δc = c·λ/(8 z_max) = c²/(8 f_c z_max)`.
/// It keeps a speed a fraction of a degree of water temperature off (about 3
/// m/s per °C near 20 °C) from being named: k-Wave's time step delays the
/// echoes of the shared ring by 0.08% of their travel time, which reads as
/// water 2.3 m/s slow.
///
/// ```
/// use usray_optim::sound_speed_tolerance;
/// let scene = usray_transport::Scene::load("../../scenes/diagnose/kwave_ring_thin.toml").unwrap();
/// // 1480 m/s, 2.5 MHz, the image down to 28 mm: 1480² / (8 · 2.5 MHz · 28 mm).
/// let tol = sound_speed_tolerance(&scene, 1480.0);
/// assert!((tol - 1480.0f64.powi(2) / (8.0 * 2.5e6 * 0.028)).abs() < 1e-12);
/// assert!((tol - 3.911).abs() < 1e-3);
/// // The catalogue's sound speed carries it, and is refitted whatever its
/// // score; no other candidate has either.
/// for c in usray_optim::catalogue(&scene) {
///     let speed = c.effect == "sound_speed";
///     assert_eq!(c.tolerance, speed.then_some(tol), "{}", c.effect);
///     assert_eq!(c.refit_always, speed, "{}", c.effect);
/// }
/// ```
pub fn sound_speed_tolerance(scene: &Scene, c: f64) -> f64 {
    c * c / (8.0 * scene.probe.center_frequency_hz * scene.imaging.z_range_m[1])
}

/// The smallest change of a modelled wall's thickness that a diagnosis names,
/// metres: the same quarter-wavelength rule (Rayleigh's) as
/// [`sound_speed_tolerance`], applied to the path inside the wall. Thickening a
/// wall by `Δd` moves the echo of its inner surface by a two-way path `2Δd` in
/// the wall; under `λ_wall/4` that echo stays where it was, so
/// `Δd_tol = λ_wall/8 = c_wall/(8 f_c)`. What such a change does alter is the
/// unresolved wall echo's brightness (a thin layer's reflection grows with
/// its thickness), which the wall's impedance sets as well: the image does
/// not tell the two apart, and a thickness named from it would be the
/// impedance's proxy (on a k-Wave ring, 0.21 mm for a 0.15 mm wall imaged
/// with attenuation; docs/diagnosis.md).
///
/// ```
/// use usray_optim::wall_thickness_tolerance;
/// let scene = usray_transport::Scene::load("../../bench/kwave/g1.toml").unwrap();
/// // The k-Wave ring's wall, 1600 m/s at 2.5 MHz: 1600 / (8 · 2.5 MHz) = 80 µm.
/// let tol = wall_thickness_tolerance(&scene, 1600.0);
/// assert!((tol - 80e-6).abs() < 1e-12);
/// let wall = usray_optim::parameter_candidates(&scene, &[])
///     .into_iter()
///     .find(|c| c.effect == "wall_thickness")
///     .unwrap();
/// assert_eq!(wall.tolerance, Some(tol));
/// ```
pub fn wall_thickness_tolerance(scene: &Scene, c_wall: f64) -> f64 {
    c_wall / (8.0 * scene.probe.center_frequency_hz)
}

/// The candidate effects for `scene` (CONTRACT §3): a wall for each solid
/// cylinder, attenuation of the medium, scatterers in each object's material
/// and in each hollow cylinder's lumen, a
/// medium sound speed different from the beamformer's, a pulse length different
/// from the scene's (beyond CONTRACT §3's five), and a depth gain up with depth
/// (a gain down with depth images as attenuation).
/// Effects the scene already has switched on are not candidates.
///
/// ```
/// use usray_optim::catalogue;
/// let mut scene = usray_transport::Scene::load("../../scenes/cylinder.toml").unwrap();
/// let wall = |s: &usray_transport::Scene| {
///     catalogue(s).into_iter().find(|c| c.effect == "wall_thickness").unwrap()
/// };
/// // Onsets one echo width c_wall·cycles/(2 f_c) = 0.471 mm apart across the radius.
/// let w = wall(&scene);
/// assert_eq!(w.onsets.len(), 10);
/// assert!((w.onsets[1] - w.onsets[0] - 1570.0 * 3.0 / (2.0 * 5.0e6)).abs() < 1e-12);
/// // Every onset lies inside the refit's range, even for a wire-thin cylinder.
/// scene.set(&usray_transport::ParamKey::object("cylinder", usray_transport::Field::Radius), 0.1e-3).unwrap();
/// let w = wall(&scene);
/// assert!(!w.onsets.is_empty());
/// assert!(w.onsets.iter().all(|t| *t > w.range.0 && *t < w.range.1));
/// ```
pub fn catalogue(scene: &Scene) -> Vec<Candidate> {
    let mut out = Vec::new();
    let f_c = scene.probe.center_frequency_hz;
    let lambda = scene.medium.sound_speed_m_s / f_c;
    for o in &scene.objects {
        if o.shape == ShapeKind::Cylinder && o.thickness_m.is_none() {
            if let (Some(r), Some(m)) = (o.radius_m, scene.materials.get(&o.material)) {
                // The null (a solid cylinder) is a change of structure, and a wall
                // of zero thickness is invisible: scored at the best of several
                // walls across the radius. A wall `t` thick puts its inner echo
                // `2t/c_wall` after the outer one; the loss has a basin about one
                // echo width wide around the true `t` (pulse envelope FWHM
                // `cycles/f_c`, `usray_signal::pulse`), so the onsets lie one echo
                // width `Δt = c_wall·cycles/(2 f_c)` apart, at `(k + ½)Δt`, and a
                // refit steps a quarter of it. Thinnest wall in a refit: a quarter
                // wavelength (or an eighth of the radius).
                let dt = wall_echo_width_m(scene, m);
                let range = (0.25 * lambda.min(0.5 * r), 0.95 * r);
                let mut onsets = wall_onsets(dt, range.1);
                if onsets.is_empty() {
                    // A cylinder thinner than half an echo width: one onset.
                    onsets.push(0.5 * (range.0 + range.1));
                }
                out.push(Candidate {
                    effect: "wall_thickness".into(),
                    key: ParamKey::object(&o.name, Field::Thickness),
                    onsets,
                    range,
                    two_sided: false,
                    null: None,
                    fixed: vec![],
                    learning_rate: wall_learning_rate(dt, range),
                    tolerance: None,
                    refit_always: false,
                    also_scored_from_null: false,
                });
            }
        }
    }
    if scene.medium.attenuation_db_cm_mhz == 0.0 {
        out.push(Candidate {
            effect: "attenuation".into(),
            key: ParamKey::medium(Field::Attenuation),
            onsets: vec![0.0],
            range: (0.0, 2.0),
            two_sided: false,
            null: Some(0.0),
            fixed: vec![],
            learning_rate: EFFECT_LEARNING_RATE,
            tolerance: None,
            refit_always: false,
            also_scored_from_null: false,
        });
    }
    let mut materials: Vec<&str> = scene.objects.iter().map(|o| o.material.as_str()).collect();
    materials.sort_unstable();
    materials.dedup();
    // Attenuation inside each object's material: after the B-mode's normalisation
    // to its maximum, attenuation of the background alone changes little when
    // every echo crosses the same background path (a cylinder's near and far
    // walls); attenuation inside an object darkens what lies behind it.
    for m in &materials {
        if scene
            .materials
            .get(*m)
            .is_some_and(|mat| mat.attenuation_db_cm_mhz == 0.0)
        {
            out.push(Candidate {
                effect: "attenuation".into(),
                key: ParamKey::material(m, Field::Attenuation),
                onsets: vec![0.0],
                range: (0.0, 2.0),
                two_sided: false,
                null: Some(0.0),
                fixed: vec![],
                learning_rate: EFFECT_LEARNING_RATE,
                tolerance: None,
                refit_always: false,
                also_scored_from_null: false,
            });
        }
    }
    for m in materials {
        if scene.materials.get(m).is_some_and(|mat| {
            mat.scatterer_density_per_mm3 == 0.0 || mat.scatterer_strength == 0.0
        }) {
            out.push(volume_scattering(
                ParamKey::material(m, Field::ScattererStrength),
                ParamKey::material(m, Field::ScattererDensity),
            ));
        }
    }
    // Scatterers in each hollow cylinder's lumen (blood in a vessel, a cyst's
    // contents): the lumen is the surrounding medium, so the material's
    // candidate above does not reach it.
    for o in &scene.objects {
        let hollow = o.shape == ShapeKind::Cylinder && o.thickness_m.is_some();
        if hollow && o.lumen_scatterer_strength.unwrap_or(0.0) == 0.0 {
            out.push(volume_scattering(
                ParamKey::object(&o.name, Field::ScattererStrength),
                ParamKey::object(&o.name, Field::ScattererDensity),
            ));
        }
    }
    let c_img = scene
        .imaging
        .sound_speed_m_s
        .unwrap_or(scene.medium.sound_speed_m_s);
    if (c_img - scene.medium.sound_speed_m_s).abs() < 1e-9 {
        // Switched on by giving the beamformer its own speed, so that the medium's
        // speed is free to differ from it. A speed error of a few percent moves
        // an echo at depth `d` by `d·Δc/c`, more than the pulse length (3 cycles
        // at 5 MHz ≈ 0.9 mm, i.e. 3% of 15 mm of two-way path at the depth) for
        // errors past ≈ 3%: the loss is not quadratic that far from the null, so
        // the speed is scored from the best of five onsets 2.5% apart (four more
        // renders), each within the basin of its neighbours.
        out.push(Candidate {
            effect: "sound_speed".into(),
            key: ParamKey::medium(Field::SoundSpeed),
            onsets: [1.0, 0.975, 1.025, 0.95, 1.05]
                .iter()
                .map(|f| f * c_img)
                .collect(),
            range: (0.93 * c_img, 1.07 * c_img),
            two_sided: true,
            null: Some(c_img),
            fixed: vec![(ParamKey::imaging(Field::SoundSpeed), c_img)],
            learning_rate: EFFECT_LEARNING_RATE,
            tolerance: Some(sound_speed_tolerance(scene, c_img)),
            refit_always: true,
            also_scored_from_null: false,
        });
    }
    // Pulse length (bandwidth): the transmitted pulse's envelope FWHM in cycles
    // differs from the scene's; null = the scene's value, either way. A longer
    // pulse widens every echo by `Δcycles/f_c`; once that passes about half
    // the echo's own width, an echo of the model no longer overlaps the
    // measured one where it matters, the loss is flat at the null and its
    // gradient there says nothing (a 5-cycle burst against a 3-cycle model
    // scored 0.004 at the null and was never refitted, docs/diagnosis.md).
    // So it is scored from the best of onsets across its range — 0.7, 1.4 and
    // 2 times the scene's as well as the null, each within the basin of its
    // neighbours — like the sound speed.
    let cycles = scene.probe.cycles;
    out.push(Candidate {
        effect: "pulse_length".into(),
        key: ParamKey::probe(Field::Cycles),
        onsets: PULSE_LENGTH_ONSETS.iter().map(|f| f * cycles).collect(),
        range: (0.5 * cycles, 3.0 * cycles),
        two_sided: true,
        null: Some(cycles),
        fixed: vec![],
        learning_rate: EFFECT_LEARNING_RATE,
        tolerance: None,
        refit_always: false,
        also_scored_from_null: false,
    });
    if scene.acquisition.depth_gain_db_per_cm == 0.0 {
        out.push(Candidate {
            effect: "depth_gain".into(),
            key: ParamKey::acquisition(Field::DepthGain),
            onsets: vec![0.0],
            // Only up, as a scanner's time-gain boosts deep echoes.
            // A gain *down* with depth is not a separate effect in a B-mode: it
            // is what attenuation does (`2αf_c` dB/cm along every path, the
            // spectral down-shift aside; `tests/diagnosis.rs`), so with both
            // signs the two refits would tie on attenuated data.
            range: (0.0, DEPTH_GAIN_MAX_DB_PER_CM),
            two_sided: false,
            null: Some(0.0),
            fixed: vec![],
            // Steps of 0.3 dB/cm, the other effects' 5% of a ±3 dB/cm range:
            // the step the gain was tuned with, kept when its range grew.
            learning_rate: 0.3 / DEPTH_GAIN_MAX_DB_PER_CM,
            tolerance: None,
            refit_always: false,
            also_scored_from_null: false,
        });
    }
    out
}

/// The `volume_scattering` candidate of the field whose strength and density
/// are `strength` and `density`: switched on at [`SCATTERER_DENSITY_PER_MM3`],
/// its strength scored from [`SCATTERER_STRENGTH_ONSETS`] and refitted in
/// 0–[`SCATTERER_STRENGTH_MAX`].
fn volume_scattering(strength: ParamKey, density: ParamKey) -> Candidate {
    Candidate {
        effect: "volume_scattering".into(),
        key: strength,
        onsets: SCATTERER_STRENGTH_ONSETS.to_vec(),
        range: (0.0, SCATTERER_STRENGTH_MAX),
        two_sided: false,
        null: Some(0.0),
        fixed: vec![(density, SCATTERER_DENSITY_PER_MM3)],
        learning_rate: EFFECT_LEARNING_RATE,
        tolerance: None,
        refit_always: false,
        also_scored_from_null: false,
    }
}

/// A wall's echo width `Δt = c_wall·cycles/(2 f_c)`, m: the wall thickness
/// that puts its inner echo one pulse envelope FWHM (`cycles/f_c`,
/// `usray_signal::pulse`) after its outer one. The loss has a basin about this
/// wide around the true wall.
pub(crate) fn wall_echo_width_m(scene: &Scene, wall: &Material) -> f64 {
    wall.sound_speed_m_s * scene.probe.cycles / (2.0 * scene.probe.center_frequency_hz)
}

/// Walls one echo width `dt` apart, at `(k + ½)·dt`, below `max_m`: the onsets
/// at which a wall is scored.
pub(crate) fn wall_onsets(dt: f64, max_m: f64) -> Vec<f64> {
    (0..)
        .map(|k| (k as f64 + 0.5) * dt)
        .take_while(|t| *t < max_m)
        .collect()
}

/// A wall refit's step: a quarter of the echo width `dt`, as a fraction of
/// `range` (at most [`EFFECT_LEARNING_RATE`]).
pub(crate) fn wall_learning_rate(dt: f64, range: (f64, f64)) -> f64 {
    (0.25 * dt / (range.1 - range.0)).min(EFFECT_LEARNING_RATE)
}
