//! The scene's `[imaging]` table as the beamformer's settings.

use super::Scene;
use usray_signal::ImagingSettings;

impl Scene {
    /// The image-formation settings of CONTRACT §3 `[imaging]`: grid, F-number,
    /// dynamic range and the sound speed the beamformer assumes (the medium's when
    /// `imaging.sound_speed_m_s` is absent, see [`Scene::imaging_sound_speed`]).
    /// Demodulation is IQ at the probe's centre frequency; the scanner's depth gain
    /// (`acquisition.depth_gain_db_per_cm`) is *not* compensated, as a scanner's
    /// B-mode would not be.
    pub fn imaging_settings(&self) -> ImagingSettings {
        let im = &self.imaging;
        ImagingSettings {
            f_number: im.f_number,
            dynamic_range_db: im.dynamic_range_db,
            sound_speed_m_s: Some(self.imaging_sound_speed()),
            reference_amplitude: im.reference_amplitude,
            ..ImagingSettings::new(im.x_range_m, im.z_range_m, im.pixel_m)
        }
    }
}
