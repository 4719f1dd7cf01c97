//! Step 5 and the echoes' spectra: do the measured echoes' spectra shift
//! alike along every path, as a centre frequency shifts them, or the more the
//! longer the path, as an attenuation does ([`super::VerdictRule::min_spectral_z`])?
//! Three uses: the centre-frequency candidate's range covers the centre they
//! show ([`widen_centre_frequency`]), a centre-frequency refit is checked
//! against them ([`check_centre_frequency`]), and where the image names
//! nothing they may name the medium's attenuation
//! ([`attenuation_from_spectra`]).

use super::calibration::Stage;
use super::catalogue::Candidate;
use super::held_out::held_out;
use super::options::DiagnoseOptions;
use super::parameter_candidates::RELATIVE_RANGE;
use super::refits::{image_on_fit_seed, record_held_out, Refitted};
use super::results::{EffectResult, SpectralAttenuation, SpectralCentre};
use super::spatial::{block_px, held_out_losses, HeldOutLosses};
use super::verdict::{qualifies, VerdictRule};
use crate::OptimError;
use usray_signal::{spectral_shift, SpectralShift, SpectralShiftOptions};
use usray_transport::{Field, ParamKey, Scene};

/// The path of the probe's centre frequency, the one candidate checked.
const CENTER_FREQUENCY: &str = "probe.center_frequency_hz";

/// The path of the medium's attenuation, the one candidate the spectra name:
/// the echoes' shift averages the attenuation over their whole path, most of
/// which lies in the medium.
const MEDIUM_ATTENUATION: &str = "medium.attenuation_db_cm_mhz";

/// Where a centre-frequency refit of `refits` would be named by every other
/// test of the verdict and the measured data are channels
/// ([`DiagnoseOptions::measured_channels`]): renders the channels of
/// `baseline_scene` (the null refit's, the control every excess is measured
/// against) at the stage's seed and rays, measures the spectral shift of the
/// measured channels against them, and records its attenuation in standard
/// errors in the refit's [`EffectResult::spectral_z`]. Returns the shift;
/// `None` where nothing was checked. A failed render or a shift that cannot
/// be measured (too few echoes) is reported through `progress` and leaves
/// the refit unchecked.
pub(crate) fn check_centre_frequency(
    refits: &[Refitted],
    effects: &mut [EffectResult],
    stage: &Stage,
    baseline_scene: &Scene,
    opts: &DiagnoseOptions,
    noise_passed: bool,
    progress: &mut dyn FnMut(&str),
) -> Option<SpectralShift> {
    opts.measured_channels.as_ref()?;
    let k = refits.iter().map(|r| r.candidate).find(|&k| {
        effects[k].path == CENTER_FREQUENCY && qualifies(&effects[k], noise_passed, &opts.rule)
    })?;
    progress("checking the centre frequency against the echoes' spectra along their path");
    let shift = measured_shift(baseline_scene, stage, opts, progress)?;
    effects[k].spectral_z = shift.attenuation_z();
    Some(shift)
}

/// The spectral shift of the measured channels against `scene`'s, rendered at
/// the stage's seed and rays; `None`, reported through `progress`, where the
/// data are not channels, the render fails or the shift cannot be measured
/// (too few echoes).
pub(crate) fn measured_shift(
    scene: &Scene,
    stage: &Stage,
    opts: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Option<SpectralShift> {
    let measured = opts.measured_channels.as_ref()?;
    let model = match usray_transport::render(scene, &stage.render_s) {
        Ok((channels, _)) => channels,
        Err(e) => {
            progress(&format!(
                "spectral shift not measured: the model's render failed: {e}"
            ));
            return None;
        }
    };
    spectral_shift(
        &measured.0,
        &model,
        scene.medium.sound_speed_m_s,
        scene.probe.center_frequency_hz,
        &SpectralShiftOptions::default(),
    )
    .map_err(|e| progress(&format!("spectral shift not measured: {e}")))
    .ok()
}

/// Where the echoes' spectra against the round's scene as given, `shift`,
/// show a centre frequency other than the scene's `f_c`
/// ([`VerdictRule::spectra_show_centre`]), widens the centre-frequency
/// candidate among `candidates` (if any) to cover ±15% about that centre,
/// `f_c` plus the shift's offset, as well as about `f_c`, and adds that
/// centre to its onsets: the range bounds the search about a plausible value,
/// the screening starts it from the best of its onsets by loss, and the
/// echoes' spectra measure one. It is scored from the scene's value alone as
/// well, keeping the better score ([`Candidate::also_scored_from_null`]): the
/// spectra's centre, which k-Wave's grid alone puts a few percent low, must
/// not push the candidate below the others it outscores from the scene's
/// value. Returns what it did; `None` where the
/// spectra show no other centre or no centre frequency is a candidate.
///
/// The range only widens, and the null stays the scene's value: the image
/// still decides whether the centre frequency is named.
pub(crate) fn widen_centre_frequency(
    candidates: &mut [Candidate],
    shift: Option<&SpectralShift>,
    f_c: f64,
    rule: &VerdictRule,
) -> Option<SpectralCentre> {
    let shift = shift.filter(|s| rule.spectra_show_centre(s))?;
    let key = ParamKey::probe(Field::CenterFrequency);
    let c = candidates.iter_mut().find(|c| c.key == key)?;
    let centre_hz = f_c + shift.offset_hz;
    if centre_hz <= 0.0 {
        return None;
    }
    c.range = (
        c.range.0.min((1.0 - RELATIVE_RANGE) * centre_hz),
        c.range.1.max((1.0 + RELATIVE_RANGE) * centre_hz),
    );
    if !c.onsets.contains(&centre_hz) {
        c.onsets.push(centre_hz);
        c.also_scored_from_null = true;
    }
    Some(SpectralCentre {
        centre_hz,
        centre_std_hz: shift.offset_std.unwrap_or(f64::NAN),
        offset_hz: shift.offset_hz,
        range_hz: [c.range.0, c.range.1],
    })
}

/// An attenuation the echoes' spectra named: its candidate, and the control's
/// scene with it switched on and that scene's image on the stage's seed.
pub(crate) struct NamedFromSpectra {
    /// Index of the medium's attenuation among the candidates.
    pub candidate: usize,
    /// The image of `scene` on the calibration's seed.
    pub image_s: Vec<f64>,
    /// The control's scene with the attenuation switched on.
    pub scene: Scene,
}

/// Verdict test 10, where the image names no effect and the measured data are
/// channels: `shift`, the spectral shift of the measured echoes against
/// `scene`, the round's scene as given (before its calibration, whose
/// parameters, fitted to the image, may stand in for an attenuation's
/// darkening and change the echoes' spectra with it), rendered at the
/// stage's seed and rays ([`measured_shift`]). Where it
/// shows an attenuation beyond the scene's
/// ([`super::VerdictRule::spectra_show_attenuation`]) and the medium's
/// attenuation is a candidate, that attenuation is named at the scene's
/// value plus the estimate (within the candidate's range), and its
/// candidate's held-out numbers are filled from the control's scene
/// (`baseline_scene`, whose held-out losses are `baseline`) with it switched
/// on: what the image says of the value the spectra found, reported, not
/// tested. Returns the shift (absent where none was measured) and what it
/// named; a failed render of the named model is reported through `progress`
/// and names nothing.
#[allow(clippy::too_many_arguments)]
pub(crate) fn attenuation_from_spectra(
    scene: &Scene,
    shift: Option<&SpectralShift>,
    candidates: &[Candidate],
    effects: &mut [EffectResult],
    stage: &Stage,
    baseline_scene: &Scene,
    baseline: &HeldOutLosses,
    measured: &[f64],
    held_data: &[f64],
    opts: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> (Option<SpectralAttenuation>, Option<NamedFromSpectra>) {
    let Some(k) = effects
        .iter()
        .position(|e| e.path == MEDIUM_ATTENUATION && e.failed.is_none())
    else {
        return (None, None);
    };
    let Some(shift) = shift else {
        return (None, None);
    };
    let shows = opts.rule.spectra_show_attenuation(shift);
    let record = |named: bool| {
        Some(SpectralAttenuation {
            shift: shift.clone(),
            named,
        })
    };
    if !shows {
        return (record(false), None);
    }
    let c = &candidates[k];
    let value = (scene.medium.attenuation_db_cm_mhz + shift.attenuation_db_cm_mhz)
        .clamp(c.range.0, c.range.1);
    match switched_on_held_out(c, value, baseline_scene, stage, measured, held_data) {
        Ok((after, image_s, on)) => {
            let e = &mut effects[k];
            record_held_out(e, &after, stage, baseline);
            e.params = [(e.path.clone(), value)].into();
            e.params_std.clear();
            (
                record(true),
                Some(NamedFromSpectra {
                    candidate: k,
                    image_s,
                    scene: on,
                }),
            )
        }
        Err(err) => {
            progress(&format!(
                "the attenuation the spectra show was not named: its model failed: {err}"
            ));
            (record(false), None)
        }
    }
}

/// `c` switched on at `value` in `scene`: its held-out losses, its image on
/// the stage's seed, and the scene.
fn switched_on_held_out(
    c: &Candidate,
    value: f64,
    scene: &Scene,
    stage: &Stage,
    measured: &[f64],
    held_data: &[f64],
) -> Result<(HeldOutLosses, Vec<f64>, Scene), OptimError> {
    let on = c.switched_on(scene, value)?;
    let evals = held_out(&on, held_data, &stage.renders_held, &stage.setup)?;
    let after = held_out_losses(&stage.setup, held_data, &evals, block_px(&stage.scene));
    let image_s = image_on_fit_seed(&on, measured, stage)?;
    Ok((after, image_s, on))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parameter_candidates;

    /// A shift of `offset_hz` (± 10 kHz) whose attenuation is `alpha_z` of its
    /// standard errors.
    fn shift(offset_hz: f64, alpha_z: f64) -> SpectralShift {
        SpectralShift {
            echoes: vec![],
            offset_hz,
            offset_std: Some(0.01e6),
            slope_hz_per_m: 0.0,
            slope_std: None,
            spectral_variance_hz2: 1e12,
            attenuation_db_cm_mhz: 0.01 * alpha_z,
            attenuation_std: Some(0.01),
        }
    }

    #[test]
    fn the_centre_frequency_s_range_covers_the_centre_the_spectra_show() {
        let scene = Scene::load("../../scenes/ring.toml").unwrap();
        let f_c = scene.probe.center_frequency_hz;
        let rule = VerdictRule::default();
        let cf = |c: &[Candidate]| {
            c.iter()
                .find(|c| c.key == ParamKey::probe(Field::CenterFrequency))
                .unwrap()
                .clone()
        };
        let nominal = cf(&parameter_candidates(&scene, &[]));
        assert_eq!(nominal.range, (0.85 * f_c, 1.15 * f_c));

        // Echoes 1 MHz low alike along the path: the range reaches ±15%
        // about the centre shown, which joins the onsets; the null and the
        // upper bound stay the scene's.
        let mut c = parameter_candidates(&scene, &[]);
        let shown = widen_centre_frequency(&mut c, Some(&shift(-1e6, 0.0)), f_c, &rule).unwrap();
        let widened = cf(&c);
        assert_eq!(shown.centre_hz, f_c - 1e6);
        assert_eq!(widened.range, (0.85 * (f_c - 1e6), 1.15 * f_c));
        assert_eq!(shown.range_hz, [widened.range.0, widened.range.1]);
        assert_eq!(widened.onsets, [f_c, f_c - 1e6]);
        assert_eq!(widened.null, Some(f_c));
        assert!(widened.also_scored_from_null && !nominal.also_scored_from_null);

        // Not where the shift grows with the path (an attenuation's), nor
        // where the offset is within 3 standard errors, nor without a shift:
        // the candidate is untouched.
        for s in [Some(shift(-1e6, 5.0)), Some(shift(-0.02e6, 0.0)), None] {
            let mut c = parameter_candidates(&scene, &[]);
            assert!(widen_centre_frequency(&mut c, s.as_ref(), f_c, &rule).is_none());
            assert_eq!(cf(&c).range, nominal.range);
            assert_eq!(cf(&c).onsets, nominal.onsets);
        }
    }
}
