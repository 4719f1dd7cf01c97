//! `usray beamform` without a scene on phased and convex data (the PyMUST
//! fixtures of `usray-signal`): a scan-converted sector with mm axes, the point
//! targets where they are, black outside the sector.

use std::path::PathBuf;
use std::process::Command;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../usray-signal/tests/data/probes")
        .join(name)
}

#[test]
fn beamform_without_a_scene_images_the_sector() {
    for (name, deepest_target_m) in [("p4_diverging", 0.06), ("c5_diverging", 0.065)] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("bf");
        let o = Command::new(env!("CARGO_BIN_EXE_usray"))
            .args([
                "beamform",
                fixture(&format!("{name}.json")).to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--quiet",
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        for f in [
            "bmode.npy",
            "bmode.png",
            "bmode_figure.png",
            "bmode_figure.svg",
        ] {
            assert!(out.join(f).exists(), "{name}: {f} missing");
        }
        let img = usray_signal::io::read_npy(out.join("bmode.npy")).unwrap();
        let (nz, nx) = (img.shape[0], img.shape[1]);
        let ch = usray_signal::read_channels(fixture(&format!("{name}.json"))).unwrap();
        let s = usray_signal::ImagingSettings::for_channels(&ch.meta, ch.n_samples).unwrap();
        let (x, z) = s.grid().unwrap();
        assert_eq!((nz, nx), (z.len(), x.len()));
        assert!(
            *z.last().unwrap() > deepest_target_m,
            "{name}: depth {:?}",
            z.last()
        );
        // The top corners lie outside the sector: black.
        assert_eq!(img.data[0], 0.0, "{name}: top-left corner");
        assert_eq!(img.data[nx - 1], 0.0, "{name}: top-right corner");
        // The brightest pixel is one of the point targets or in the speckle disk
        // (all targets have the same reflection coefficient): in front of the
        // probe, within the sector.
        let k = usray_signal::post::argmax(&img.data);
        assert_eq!(img.data[k], 1.0);
        let (xb, zb) = (x[k % nx], z[k / nx]);
        assert!(
            zb > 0.015 && xb.abs() < 0.03,
            "{name}: brightest at ({xb}, {zb})"
        );
    }
}
