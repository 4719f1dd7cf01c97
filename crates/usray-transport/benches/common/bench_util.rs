/// Median of timings (the upper middle for an even count).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A shipped scene, `scenes/NAME` (the including bench imports `Scene`).
fn scene(name: &str) -> Scene {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    Scene::load(p).expect("scene")
}
