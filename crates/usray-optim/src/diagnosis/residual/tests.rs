//! Unit tests of the residual analysis.

use super::*;

/// 121 × 181 pixels of 0.1 mm: x ∈ [−6, 6] mm, z ∈ [2, 20] mm; D = 60 dB;
/// 5 MHz, 3 cycles at 1540 m/s: b = 0.462 mm.
fn scene_with(objects: &str) -> Scene {
    scene_in(objects, &std::env::temp_dir())
}

fn scene_in(objects: &str, base: &std::path::Path) -> Scene {
    let text = format!(
        r#"
[medium]
sound_speed_m_s = 1540.0
impedance_mrayl = 1.54
[probe]
kind = "linear"
n_elements = 64
pitch_m = 0.3e-3
element_width_m = 0.27e-3
center_frequency_hz = 5.0e6
cycles = 3.0
main_lobe_deg = 5.0
cutoff_deg = 60.0
[acquisition]
angles_deg = [0.0]
sampling_frequency_hz = 40.0e6
max_depth_m = 0.03
rays_per_element = 10
max_bounces = 2
seed = 1
[imaging]
x_range_m = [-0.006, 0.006]
z_range_m = [0.002, 0.020]
pixel_m = 0.1e-3
f_number = 1.5
dynamic_range_db = 60.0
[materials.target]
impedance_mrayl = 1.99
sound_speed_m_s = 1570.0
{objects}
"#
    );
    Scene::from_toml_str(&text, "test.toml", base).unwrap()
}

const CYLINDER: &str = r#"
[[objects]]
name = "cylinder"
shape = "cylinder"
center_m = [0.0, 0.0, 0.010]
radius_m = 0.003
material = "target"
"#;

fn grid(scene: &Scene) -> (usize, usize, Vec<f64>, Vec<f64>) {
    let (x, z) = scene.imaging_settings().grid().unwrap();
    (z.len(), x.len(), x, z)
}

/// A bright ring of Gaussian profile (σ = 0.15 mm) on the cylinder's surface,
/// on a dark background.
fn ring_echo(scene: &Scene, level: f64) -> Vec<f64> {
    let (nz, nx, x, z) = grid(scene);
    let mut img = vec![0.0; nz * nx];
    for iz in 0..nz {
        for ix in 0..nx {
            let rho = x[ix].hypot(z[iz] - 0.010);
            img[iz * nx + ix] = level * (-((rho - 0.003) / 0.15e-3).powi(2)).exp();
        }
    }
    img
}

fn by_partition<'a>(r: &'a ResidualReport, p: &str) -> Vec<&'a RegionShare> {
    r.shares.iter().filter(|s| s.partition == p).collect()
}

fn share(r: &ResidualReport, region: &str) -> f64 {
    r.shares.iter().find(|s| s.region == region).unwrap().share
}

#[test]
fn residual_inside_a_disk_is_all_inside_the_cylinder() {
    let scene = scene_with(CYLINDER);
    let (nz, nx, x, z) = grid(&scene);
    let measured = vec![0.3; nz * nx];
    let mut simulated = measured.clone();
    for iz in 0..nz {
        for ix in 0..nx {
            if x[ix].hypot(z[iz] - 0.010) < 0.002 {
                simulated[iz * nx + ix] = 0.5;
            }
        }
    }
    let r = analyse_residual(&scene, &simulated, &measured, &ResidualOptions::default()).unwrap();
    assert!((r.band_m - 3.0 * 1540.0 / 1e7).abs() < 1e-15);
    let obj = by_partition(&r, "object");
    assert_eq!(obj[0].region, "inside objects.cylinder");
    assert!((obj[0].share - 1.0).abs() < 1e-12, "{obj:?}");
    assert_eq!(share(&r, "boundary of objects.cylinder"), 0.0);
    assert_eq!(share(&r, "outside all objects"), 0.0);
    let expected = L1L2::default().value(&simulated, &measured);
    assert!((r.loss - expected).abs() < 1e-12 * expected);
    // The disk spans depths 8–12 mm, laterally −2–2 mm.
    assert!((share(&r, "depth 5.0–10.0 mm") - 0.5).abs() < 0.05);
    assert!((share(&r, "depth 10.0–15.0 mm") - 0.5).abs() < 0.05);
    assert_eq!(share(&r, "depth 2.0–5.0 mm"), 0.0);
    assert!((share(&r, "lateral -5.0–0.0 mm") - 0.5).abs() < 0.05);
    assert_eq!(share(&r, "lateral -6.0–-5.0 mm"), 0.0);
    // Texture: the inside region holds the disk plus a flat margin.
    let t = &r.texture[0];
    assert_eq!(t.region, "inside objects.cylinder");
    let m = t.measured.as_ref().unwrap();
    assert!((m.mean_grey - 0.3).abs() < 1e-12 && m.std_grey < 1e-12);
    assert_eq!(m.speckle_snr, None);
    assert!(t.simulated.as_ref().unwrap().mean_grey > 0.3);
    assert_eq!(r.texture.last().unwrap().region, "outside all objects");
}

#[test]
fn shares_sum_to_one_in_every_partition_with_overlapping_objects() {
    let objects = format!(
        "{CYLINDER}{}",
        r#"
[[objects]]
name = "deep"
shape = "plane"
center_m = [0.0, 0.0, 0.008]
material = "target"
[[objects]]
name = "layer"
shape = "slab"
z_top_m = 0.003
z_bottom_m = 0.005
material = "target"
[[objects]]
name = "ball"
shape = "sphere"
center_m = [0.004, 0.001, 0.016]
radius_m = 0.0015
material = "target"
"#
    );
    let scene = scene_with(&objects);
    let (nz, nx, _, _) = grid(&scene);
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let simulated: Vec<f64> = (0..nz * nx).map(|_| next()).collect();
    let measured: Vec<f64> = (0..nz * nx).map(|_| next()).collect();
    let r = analyse_residual(&scene, &simulated, &measured, &ResidualOptions::default()).unwrap();
    for p in ["object", "depth", "lateral"] {
        let s = by_partition(&r, p);
        let total: f64 = s.iter().map(|s| s.share).sum();
        assert!((total - 1.0).abs() < 1e-12, "{p}: {total}");
        assert_eq!(s.iter().map(|s| s.pixels).sum::<usize>(), nz * nx);
        assert!(s.windows(2).all(|w| w[0].share >= w[1].share), "{p} sorted");
    }
    assert_eq!(by_partition(&r, "object").len(), 9);
    let reg = scene_regions(&scene, &ResidualOptions::default()).unwrap();
    let obj = &reg.partitions[0];
    let at = |x: f64, z: f64| {
        let ix = ((x + 0.006) / 1e-4).round() as usize;
        let iz = ((z - 0.002) / 1e-4).round() as usize;
        obj.regions[obj.label[iz * nx + ix]].as_str()
    };
    // Inside both the cylinder and the half-space: the smaller one wins.
    assert_eq!(at(0.0, 0.010), "inside objects.cylinder");
    assert_eq!(at(-0.005, 0.015), "inside objects.deep");
    assert_eq!(at(0.0, 0.004), "inside objects.layer");
    assert_eq!(at(0.0, 0.0030), "boundary of objects.layer");
    assert_eq!(at(0.0, 0.0070), "boundary of objects.cylinder"); // top of the cylinder
    assert_eq!(at(-0.005, 0.0081), "boundary of objects.deep");
    assert_eq!(at(-0.005, 0.006), "outside all objects");
    // Sphere with c_y = 1 mm: section radius √(1.5² − 1²) mm ≈ 1.118 mm.
    assert_eq!(at(0.004, 0.016), "inside objects.ball");
    assert_eq!(at(0.004, 0.016 - 0.00112), "boundary of objects.ball");
}

#[test]
fn hollow_cylinder_has_bands_at_both_surfaces() {
    let scene = scene_with(
        r#"
[[objects]]
name = "tube"
shape = "cylinder"
center_m = [0.0, 0.0, 0.010]
radius_m = 0.003
thickness_m = 0.001
material = "target"
"#,
    );
    let reg = scene_regions(&scene, &ResidualOptions::default()).unwrap();
    let nx = reg.nx;
    let row = |z: f64| ((z - 0.002) / 1e-4).round() as usize * nx + nx / 2;
    let o = &reg.objects[0];
    assert!(o.band[row(0.007)] && o.band[row(0.008)]); // outer and inner surface
    assert!(!o.band[row(0.0075)] && o.inside[row(0.0075)]); // mid-wall
    assert!(!o.band[row(0.010)] && o.inside[row(0.010)]); // lumen
}

#[test]
fn axial_shift_of_a_boundary_echo_is_recovered() {
    let scene = scene_with(CYLINDER);
    let (nz, nx, _, _) = grid(&scene);
    let simulated = ring_echo(&scene, 0.8);
    for k in [3isize, -2] {
        let mut measured = vec![0.0; nz * nx];
        for iz in 0..nz as isize {
            let src = iz - k;
            if (0..nz as isize).contains(&src) {
                let (d, s) = (iz as usize * nx, src as usize * nx);
                measured[d..d + nx].copy_from_slice(&simulated[s..s + nx]);
            }
        }
        let r =
            analyse_residual(&scene, &simulated, &measured, &ResidualOptions::default()).unwrap();
        let want = k as f64 * 1e-4;
        for e in &r.echo_position {
            let got = e.shift_m.unwrap();
            assert!((got - want).abs() < 0.5e-4, "{e:?} vs {want}");
            assert!(e.correlation.unwrap() > 0.9 && !e.at_search_limit);
        }
    }
    let flat = vec![0.5; nz * nx];
    let r = analyse_residual(&scene, &flat, &flat, &ResidualOptions::default()).unwrap();
    assert_eq!(r.echo_position[0].shift_m, None);
    assert_eq!(r.loss, 0.0);
    assert!(r.shares.iter().all(|s| s.share == 0.0));
}

#[test]
fn amplitude_offset_gives_its_db_difference() {
    let scene = scene_with(CYLINDER);
    let simulated: Vec<f64> = ring_echo(&scene, 0.3).iter().map(|g| 0.5 + g).collect();
    let measured: Vec<f64> = simulated.iter().map(|g| g - 0.1).collect();
    let r = analyse_residual(&scene, &simulated, &measured, &ResidualOptions::default()).unwrap();
    let a = &r.echo_amplitude[0];
    assert_eq!(a.region, "boundary of objects.cylinder");
    assert!(a.pixels > 500);
    assert!((a.mean_db_difference.unwrap() - 6.0).abs() < 1e-9, "{a:?}");
    assert!(
        (a.energy_db_difference.unwrap() - 6.0).abs() < 1e-9,
        "{a:?}"
    );
    // Texture: the same offset in the grey means, SNR unchanged (E scales).
    let t = &r.texture[0];
    let (s, m) = (t.simulated.as_ref().unwrap(), t.measured.as_ref().unwrap());
    assert!((s.mean_grey - m.mean_grey - 0.1).abs() < 1e-12);
}

#[test]
fn boundary_width_is_the_fwhm_of_the_echo() {
    let scene = scene_with(
        r#"
[[objects]]
name = "layer"
shape = "slab"
z_top_m = 0.008
z_bottom_m = 0.018
material = "target"
"#,
    );
    let (nz, nx, _, z) = grid(&scene);
    // Envelope exp(−(z − 8 mm)²/2σ²) as grey: g = 1 + 20 log10(E) / 60, clipped.
    let echo = |sigma: f64| -> Vec<f64> {
        let mut img = vec![0.0; nz * nx];
        for iz in 0..nz {
            let e: f64 = (-(z[iz] - 0.008).powi(2) / (2.0 * sigma * sigma)).exp();
            let g = (1.0 + 20.0 * e.max(1e-300).log10() / 60.0).clamp(0.0, 1.0);
            img[iz * nx..(iz + 1) * nx].fill(g);
        }
        img
    };
    let (ss, sm) = (0.2e-3, 0.3e-3);
    let r = analyse_residual(&scene, &echo(ss), &echo(sm), &ResidualOptions::default()).unwrap();
    let w = &r.boundary_width[0];
    let k = 2.0 * (2.0 * 2f64.ln()).sqrt();
    assert!(
        (w.simulated_fwhm_m.unwrap() - k * ss).abs() < 0.3e-4,
        "{w:?}"
    );
    assert!(
        (w.measured_fwhm_m.unwrap() - k * sm).abs() < 0.3e-4,
        "{w:?}"
    );
    assert_eq!((w.simulated_columns, w.measured_columns), (nx, nx));
}

#[test]
fn mesh_objects_use_their_inside_mask() {
    // A 4 mm cube centred at 10 mm depth.
    let dir = std::env::temp_dir().join(format!("usray-residual-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut obj = String::new();
    for i in 0..8 {
        let c = |b: usize| if i >> b & 1 == 1 { 0.002 } else { -0.002 };
        obj += &format!("v {} {} {}\n", c(0), c(1), c(2));
    }
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        obj += &format!(
            "f {} {} {}\nf {} {} {}\n",
            f[0], f[1], f[2], f[0], f[2], f[3]
        );
    }
    std::fs::write(dir.join("cube.obj"), obj).unwrap();
    let scene = scene_in(
        r#"
[[objects]]
name = "cube"
shape = "mesh"
path = "cube.obj"
center_m = [0.0, 0.0, 0.010]
material = "target"
"#,
        &dir,
    );
    let reg = scene_regions(&scene, &ResidualOptions::default());
    std::fs::remove_dir_all(&dir).ok();
    let reg = reg.unwrap();
    let nx = reg.nx;
    let at = |x: f64, z: f64| {
        let u = ((z - 0.002) / 1e-4).round() as usize * nx + ((x + 0.006) / 1e-4).round() as usize;
        reg.partitions[0].regions[reg.partitions[0].label[u]].as_str()
    };
    assert!(reg.objects[0].approximate);
    assert_eq!(at(0.0, 0.010), "inside objects.cube");
    assert_eq!(at(0.0, 0.0081), "boundary of objects.cube");
    assert_eq!(at(0.0019, 0.010), "boundary of objects.cube");
    assert_eq!(at(0.0, 0.0070), "outside all objects");
}

#[test]
fn bad_inputs_are_reported() {
    let scene = scene_with(CYLINDER);
    let (nz, nx, _, _) = grid(&scene);
    let good = vec![0.5; nz * nx];
    let o = ResidualOptions::default();
    let msg = |e: OptimError| e.to_string();
    let e = msg(analyse_residual(&scene, &good[1..], &good, &o).unwrap_err());
    assert!(
        e.contains("simulated") && e.contains(&format!("[{nz}, {nx}]")),
        "{e}"
    );
    let mut nan = good.clone();
    nan[nx + 2] = f64::NAN;
    let e = msg(analyse_residual(&scene, &good, &nan, &o).unwrap_err());
    assert!(
        e.contains("measured") && e.contains("NaN") && e.contains("(1, 2)"),
        "{e}"
    );
    let mut big = good.clone();
    big[0] = 1.5;
    assert!(analyse_residual(&scene, &big, &good, &o).is_err());
    let bad = ResidualOptions {
        band_m: Some(-1.0),
        ..o
    };
    let e = msg(analyse_residual(&scene, &good, &good, &bad).unwrap_err());
    assert!(e.contains("band_m"), "{e}");
    assert!(signed_residual_rgb(&good, &good, nz, nx, Some(0.0)).is_err());
    assert!(signed_residual_rgb(&good, &good, nz + 1, nx, None).is_err());
}

#[test]
fn signed_map_is_diverging_around_white() {
    let sim = [0.5, 0.5, 0.5, 0.4];
    let meas = [0.5, 0.3, 0.6, 0.5];
    let m = signed_residual_rgb(&sim, &meas, 2, 2, None).unwrap();
    assert!((m.scale - 0.2).abs() < 1e-12); // 99th percentile of |d| = max here
    assert_eq!((m.width, m.height), (2, 2));
    assert_eq!(&m.rgb[0..3], &[255, 255, 255]);
    assert_eq!(&m.rgb[3..6], &[255, 0, 0]);
    assert_eq!(&m.rgb[6..9], &[128, 128, 255]);
    let z = signed_residual_rgb(&sim, &sim, 2, 2, None).unwrap();
    assert_eq!(z.scale, 1.0);
    assert!(z.rgb.iter().all(|&b| b == 255));
}
