//! Step 5's spectral check of a centre-frequency refit: do the measured
//! echoes' spectra shift alike along every path, as a centre frequency
//! shifts them, or the more the longer the path, as an attenuation does
//! ([`super::VerdictRule::min_spectral_z`])?

use super::calibration::Stage;
use super::options::DiagnoseOptions;
use super::refits::Refitted;
use super::results::EffectResult;
use super::verdict::qualifies;
use usray_signal::{spectral_shift, SpectralShift, SpectralShiftOptions};
use usray_transport::Scene;

/// The path of the probe's centre frequency, the one candidate checked.
const CENTER_FREQUENCY: &str = "probe.center_frequency_hz";

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
    let measured = opts.measured_channels.as_ref()?;
    let k = refits.iter().map(|r| r.candidate).find(|&k| {
        effects[k].path == CENTER_FREQUENCY && qualifies(&effects[k], noise_passed, &opts.rule)
    })?;
    progress("checking the centre frequency against the echoes' spectra along their path");
    let model = match usray_transport::render(baseline_scene, &stage.render_s) {
        Ok((channels, _)) => channels,
        Err(e) => {
            progress(&format!(
                "spectral check not made: the model's render failed: {e}"
            ));
            return None;
        }
    };
    match spectral_shift(
        &measured.0,
        &model,
        baseline_scene.medium.sound_speed_m_s,
        baseline_scene.probe.center_frequency_hz,
        &SpectralShiftOptions::default(),
    ) {
        Ok(shift) => {
            effects[k].spectral_z = shift.attenuation_z();
            Some(shift)
        }
        Err(e) => {
            progress(&format!("spectral check not made: {e}"));
            None
        }
    }
}
