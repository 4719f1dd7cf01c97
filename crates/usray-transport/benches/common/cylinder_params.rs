/// Sixteen parameters of `scenes/cylinder.toml` (the first three: radius, depth,
/// impedance), shared by the gradient-cost bench and the `gradient_cost` example so
/// that time and memory are measured on the same parameter set.
pub const PATHS: [&str; 16] = [
    "objects.cylinder.radius_m",
    "objects.cylinder.center_m.2",
    "materials.target.impedance_mrayl",
    "objects.cylinder.center_m.0",
    "materials.target.sound_speed_m_s",
    "materials.target.roughness",
    "materials.target.attenuation_db_cm_mhz",
    "medium.sound_speed_m_s",
    "medium.impedance_mrayl",
    "medium.attenuation_db_cm_mhz",
    "probe.pitch_m",
    "probe.element_width_m",
    "probe.center_frequency_hz",
    "probe.cycles",
    "probe.elevation_m",
    "acquisition.angles_deg.0",
];

/// [`PATHS`] as keys.
pub fn params() -> Vec<usray_transport::ParamKey> {
    PATHS.iter().map(|p| p.parse().expect("a parameter path")).collect()
}
