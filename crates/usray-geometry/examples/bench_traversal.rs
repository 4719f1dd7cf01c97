//! Rays per second of the geometry layer on one thread, for comparison with the
//! whole tracer: bare `obvhs` traversal ([`MeshBvh::traverse_f32`]), the
//! closest-hit query ([`MeshBvh::closest_hit`]), [`Geometry::intersect`] in `f64`
//! and in `Dual<4>` (mesh and analytic tube); for the meshes also rays leaving
//! the surface (like the tracer's secondary rays).
//!
//! `cargo run --release -p usray-geometry --example bench_traversal`

use std::hint::black_box;
use std::sync::Arc;
use std::time::Instant;

use usray_ad::Dual;
use usray_geometry::shapes::hollow_cylinder::HollowCylinder;
use usray_geometry::valve::{valve_leaflets, ValveParams};
use usray_geometry::{Geometry, MeshInstance, Ray, Transform, TriangleMesh, Vec3};

fn rays(n: usize) -> Vec<([f64; 3], [f64; 3])> {
    let mut s = 1u64;
    let mut next = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let o = [0.04 * next() - 0.02, 0.0, 0.0];
            let t = [
                0.04 * next() - 0.02,
                0.01 * next() - 0.005,
                0.02 + 0.03 * next(),
            ];
            let d = [t[0] - o[0], t[1] - o[1], t[2] - o[2]];
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            (o, [d[0] / l, d[1] / l, d[2] / l])
        })
        .collect()
}

fn rate(name: &str, n: usize, f: impl FnOnce() -> usize) {
    let t0 = Instant::now();
    let hits = f();
    let s = t0.elapsed().as_secs_f64();
    println!(
        "{name:<48} {:>8.2} Mrays/s  ({hits} hits / {n})",
        n as f64 / s / 1e6
    );
}

fn main() {
    let n = 1_000_000;
    let rs = rays(n);
    for (label, mesh) in [
        (
            "valve (half closed)",
            valve_leaflets(0.5, &ValveParams::default()),
        ),
        (
            "icosphere r=8mm, 20480 tris",
            TriangleMesh::icosphere(0.008, 5),
        ),
    ] {
        let w = Transform::from_translation(Vec3::new(0.0, 0.0, 0.035));
        let inst = MeshInstance::new(Arc::new(mesh), w).unwrap();
        println!("-- {label}: {} triangles", inst.bvh.len());
        rate("MeshBvh::traverse_f32 (bare obvhs)", n, || {
            rs.iter()
                .filter(|(o, d)| {
                    black_box(inst.bvh.traverse_f32(
                        o.map(|x| x as f32),
                        d.map(|x| x as f32),
                        1e-9,
                        1.0,
                    ))
                    .is_some()
                })
                .count()
        });
        rate("MeshBvh::closest_hit (f32 BVH, f64 tests)", n, || {
            rs.iter()
                .filter(|(o, d)| black_box(inst.bvh.closest_hit(*o, *d, 1e-9, 1.0)).is_some())
                .count()
        });
        // Rays leaving the surface (the tracer's secondary and connection rays):
        // from the hit points of the primary rays, in a scrambled direction.
        let sec: Vec<([f64; 3], [f64; 3])> = rs
            .iter()
            .filter_map(|(o, d)| {
                let h = inst.bvh.closest_hit(*o, *d, 1e-9, 1.0)?;
                let p = [0, 1, 2].map(|k| o[k] + h.t * d[k]);
                let q = [d[1] - 0.3 * d[0], d[2] + 0.2, -d[0] + 0.5 * d[1]];
                let l = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                Some((p, q.map(|x| x / l)))
            })
            .collect();
        let m = sec.len();
        rate("secondary: MeshBvh::traverse_f32 (bare obvhs)", m, || {
            sec.iter()
                .filter(|(o, d)| {
                    black_box(inst.bvh.traverse_f32(
                        o.map(|x| x as f32),
                        d.map(|x| x as f32),
                        1e-9,
                        1.0,
                    ))
                    .is_some()
                })
                .count()
        });
        rate("secondary: MeshBvh::closest_hit", m, || {
            sec.iter()
                .filter(|(o, d)| black_box(inst.bvh.closest_hit(*o, *d, 1e-9, 1.0)).is_some())
                .count()
        });
        let mut g = Geometry::<f64>::new();
        g.add(inst.clone()).unwrap();
        rate("Geometry<f64>::intersect", n, || {
            rs.iter()
                .filter(|(o, d)| {
                    black_box(g.intersect(&Ray::new(Vec3::from(*o), Vec3::from(*d)), 1e-9, 1.0))
                        .is_some()
                })
                .count()
        });
        let gd = {
            let mut g = Geometry::<Dual<4>>::new();
            let wd = Transform::from_translation(Vec3::new(
                Dual::variable(0.0, 0),
                Dual::variable(0.0, 1),
                Dual::variable(0.035, 2),
            ));
            g.add(inst.with_transform(wd)).unwrap();
            g
        };
        rate("Geometry<Dual<4>>::intersect", n, || {
            rs.iter()
                .filter(|(o, d)| {
                    black_box(gd.intersect(&Ray::from_f64s(*o, *d), 1e-9, 1.0)).is_some()
                })
                .count()
        });
    }
    println!("-- analytic tube (R 20 mm, wall 3 mm)");
    let mut g = Geometry::<f64>::new();
    g.add(HollowCylinder::new(Vec3::new(0.0, 0.0, 0.04), 0.02, 0.003))
        .unwrap();
    rate("Geometry<f64>::intersect", n, || {
        rs.iter()
            .filter(|(o, d)| {
                black_box(g.intersect(&Ray::new(Vec3::from(*o), Vec3::from(*d)), 1e-9, 1.0))
                    .is_some()
            })
            .count()
    });
    let mut gd = Geometry::<Dual<4>>::new();
    gd.add(HollowCylinder::new(
        Vec3::new(
            Dual::variable(0.0, 0),
            Dual::constant(0.0),
            Dual::variable(0.04, 1),
        ),
        Dual::variable(0.02, 2),
        Dual::variable(0.003, 3),
    ))
    .unwrap();
    rate("Geometry<Dual<4>>::intersect", n, || {
        rs.iter()
            .filter(|(o, d)| black_box(gd.intersect(&Ray::from_f64s(*o, *d), 1e-9, 1.0)).is_some())
            .count()
    });
}
