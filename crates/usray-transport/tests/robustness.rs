//! No NaN anywhere: grazing rays, total internal reflection, rays starting on a
//! surface, degenerate triangles.

mod common;
use common::header;
use usray_geometry::Vec3;
use usray_transport::ggx::Interface;
use usray_transport::{render, RenderOptions, Scene};

fn all_finite(scene: &Scene) {
    let opts = RenderOptions {
        rays_per_element: Some(300),
        ..Default::default()
    };
    let (d, stats) = render(scene, &opts).unwrap();
    assert!(d.samples.iter().all(|v| v.is_finite()), "non-finite sample");
    assert!(stats.rays_traced > 0);
}

#[test]
fn tir_scene_is_finite() {
    // A fast sphere (3000 m/s) in water: rays inside beyond 30° are totally reflected.
    let text = format!(
        "{}\n[materials.fast]\nimpedance_mrayl = 6.0\nsound_speed_m_s = 3000.0\nroughness = 0.2\n\n\
         [[objects]]\nname = \"ball\"\nshape = \"sphere\"\ncenter_m = [0.0, 0.0, 0.012]\nradius_m = 0.004\nmaterial = \"fast\"\n",
        header(32, 0.27e-3, "[-10.0, 0.0]", 300, 12)
    );
    all_finite(&Scene::from_toml_str(&text, "<tir>", ".").unwrap());
}

#[test]
fn surface_through_the_array_plane_is_finite() {
    // A slab whose top is the array plane (rays start on a surface), and a plane
    // containing the element centres' line at grazing angle.
    let text = format!(
        "{}\n[materials.gel]\nimpedance_mrayl = 1.6\nsound_speed_m_s = 1600.0\nroughness = 0.1\n\n\
         [[objects]]\nname = \"gel\"\nshape = \"slab\"\nz_top_m = 0.0\nz_bottom_m = 0.005\nmaterial = \"gel\"\n\n\
         [[objects]]\nname = \"tilted\"\nshape = \"plane\"\ncenter_m = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, -1e-9]\nmaterial = \"gel\"\n",
        header(16, 0.27e-3, "[0.0]", 300, 6)
    );
    all_finite(&Scene::from_toml_str(&text, "<surface>", ".").unwrap());
}

#[test]
fn degenerate_triangles_are_finite() {
    let dir = usray_testdata::workspace_file("crates/usray-transport/tests");
    let text = format!(
        "{}\n[materials.m]\nimpedance_mrayl = 1.9\nsound_speed_m_s = 1600.0\nroughness = 0.2\n\n\
         [[objects]]\nname = \"tet\"\nshape = \"mesh\"\npath = \"data/degenerate.obj\"\nmaterial = \"m\"\n",
        header(16, 0.27e-3, "[0.0]", 300, 6)
    );
    match Scene::from_toml_str(&text, "<mesh>", &dir) {
        Ok(scene) => all_finite(&scene),
        // Rejecting a degenerate mesh with an error is also acceptable: no panic.
        Err(e) => {
            eprintln!("degenerate mesh rejected: {e}");
            assert!(e.key.contains("objects.tet"), "{e}")
        }
    }
}

#[test]
fn grazing_incidence_samples_and_evaluations_are_finite() {
    let n = Vec3::new(0.0, 0.0, 1.0);
    for &alpha in &[0.0, 1e-4, 0.3, 1.0] {
        let iface = Interface {
            c1: 1540.0,
            c2: 3000.0,
            z1: 1.5,
            z2: 4.0,
            alpha,
            planar: false,
        };
        for &c in &[0.0, 1e-300, 1e-12, 1e-6, 0.5, 1.0] {
            let s = (1.0f64 - c * c).sqrt();
            let wi = Vec3::new(s, 0.0, c);
            for k in 0..64 {
                let u = |j: u64| ((k * 7 + j * 13) % 64) as f64 / 64.0;
                if let Some(x) = iface.scatter(wi, n, u(1), u(2)) {
                    for l in [x.reflected, x.transmitted].iter().flatten() {
                        assert!(
                            l.weight.is_finite() && l.wo.is_finite(),
                            "α {alpha} cos {c}"
                        );
                    }
                }
                let wo = Vec3::new((u(4) - 0.5) * 2.0, u(5) - 0.5, u(6) - 0.5).normalize();
                assert!(iface.eval(wi, wo, n).is_finite());
                assert!(iface.pdf(wi, wo, n).is_finite());
            }
            // Tangent outgoing direction.
            assert!(iface.eval(wi, Vec3::new(1.0, 0.0, 0.0), n).is_finite());
        }
    }
}
