//! `usray params SCENE`: every continuous parameter and its value.

use crate::output::OutDir;
use anyhow::Result;
use std::path::Path;
use usray_transport::Scene;

/// Prints `path = value` per line and writes the same to `params.txt`.
pub fn run(scene: &Path, out: &Path) -> Result<()> {
    let scene = Scene::load(scene)?;
    let text: String = scene
        .params()
        .iter()
        .map(|(p, v)| format!("{p} = {v}\n"))
        .collect();
    let out = OutDir::create(out)?;
    out.write_text("params.txt", &text)?;
    out.finish()?;
    print!("{text}");
    Ok(())
}
