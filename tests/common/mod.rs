//! Pieces shared by the root package's integration tests.

use usray::transport::Scene;

const CYLINDER: &str = include_str!("../../scenes/cylinder.toml");

/// `scenes/cylinder.toml` reduced for CI: 32 elements, 3 angles (−5°, 0°, 5°), a
/// 16 × 16 mm grid of `pixel_m` pixels around the cylinder.
pub fn ci_cylinder(pixel_m: f64) -> Scene {
    let mut s = Scene::from_toml_str(CYLINDER, "cylinder.toml", ".").unwrap();
    s.probe.n_elements = 32;
    s.acquisition.angles_deg = vec![-5.0, 0.0, 5.0];
    s.acquisition.max_depth_m = 0.025;
    s.imaging.x_range_m = [-0.008, 0.008];
    s.imaging.z_range_m = [0.007, 0.023];
    s.imaging.pixel_m = pixel_m;
    s.validate().unwrap();
    s
}
