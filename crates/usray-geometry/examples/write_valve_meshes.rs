//! Writes the procedural valve meshes used by scenes:
//! `scenes/meshes/valve_{open,half,closed}.obj` (closure 0, 0.5, 1).
//!
//! Run from the workspace root:
//! `cargo run -p usray-geometry --example write_valve_meshes`

use usray_geometry::valve::{valve_leaflets, ValveParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/meshes");
    std::fs::create_dir_all(&dir)?;
    for (name, closure) in usray_geometry::valve::SCENE_VALVES {
        let mesh = valve_leaflets(closure, &ValveParams::default());
        mesh.assert_well_formed();
        let path = dir.join(format!("{name}.obj"));
        mesh.write_obj(&path, &usray_geometry::valve::scene_valve_comment(closure))?;
        println!(
            "wrote {} ({} triangles)",
            path.display(),
            mesh.triangles.len()
        );
    }
    Ok(())
}
