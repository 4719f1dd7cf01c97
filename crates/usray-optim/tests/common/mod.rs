//! Shared helpers of the crate's tests.
#![allow(dead_code)]

use usray_transport::Scene;

/// The cylinder scene cut down to 16 elements, one angle and a small grid at
/// 0.4 mm (the CLI tests' tiny scene), so that a diagnosis takes about a second
/// in a debug build.
pub fn tiny_scene() -> Scene {
    let text = std::fs::read_to_string("../../scenes/cylinder.toml")
        .unwrap()
        .replace("n_elements = 128", "n_elements = 16")
        .replace(
            "angles_deg = [-10.0, -5.0, 0.0, 5.0, 10.0]",
            "angles_deg = [0.0]",
        )
        .replace("x_range_m = [-0.015, 0.015]", "x_range_m = [-0.004, 0.004]")
        .replace("z_range_m = [0.002, 0.028]", "z_range_m = [0.008, 0.02]")
        .replace("pixel_m = 0.1e-3", "pixel_m = 0.4e-3");
    Scene::from_toml_str(&text, "tiny.toml", "../../scenes").unwrap()
}
