//! Transport throughput (`harness = false`, own timing loop, median of repeats).
//!
//! (a) The cylinder demo scene at its default settings, in a rayon pool of 1
//!     thread and of all cores: seconds and rays per second.
//! (b) The valve mesh scene: whole-tracer rays per second against bare `obvhs`
//!     traversal (the geometry crate's f32 BVH, `MeshBvh::traverse_f32`) of the
//!     same primary rays, side by side, single-threaded.
//!
//! Run: `cargo bench -p usray-transport --bench render`

use std::time::Instant;
use usray_geometry::Shape;
use usray_transport::probe::{cosine_hemisphere, element_x};
use usray_transport::rng::{dim, PathSampler};
use usray_transport::scene::Emission;
use usray_transport::{render, RenderOptions, Scene};

const REPEATS: usize = 5;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn scene(name: &str) -> Scene {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    Scene::load(p).expect("scene")
}

fn bench_render(scene: &Scene, threads: usize) -> (f64, f64, u64) {
    let opts = RenderOptions {
        threads: Some(threads),
        ..Default::default()
    };
    let mut secs = Vec::new();
    let mut rays = 0;
    for _ in 0..REPEATS {
        let t = Instant::now();
        let (_, stats) = render(scene, &opts).expect("render");
        secs.push(t.elapsed().as_secs_f64());
        rays = stats.rays_traced;
    }
    let s = median(secs);
    (s, rays as f64 / s, rays)
}

fn main() {
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    // `USRAY_BENCH_ONLY=b` skips part (a) (for profiling part (b) alone).
    let only_b = std::env::var("USRAY_BENCH_ONLY").is_ok_and(|v| v == "b");
    let cyl = scene("cylinder.toml");
    if !only_b {
        println!("## (a) cylinder.toml at default settings (median of {REPEATS})");
        let paths = cyl.probe.n_elements
            * cyl.acquisition.angles_deg.len()
            * cyl.acquisition.rays_per_element;
        for threads in [1, cores] {
            let (s, rps, rays) = bench_render(&cyl, threads);
            println!(
            "threads {threads}: {s:.3} s, {rays} rays ({paths} paths), {rps:.3e} rays/s, {:.3e} paths/s",
            paths as f64 / s
        );
        }
    }

    println!(
        "## (b) valve.toml: whole tracer vs bare obvhs traversal, 1 thread (median of {REPEATS})"
    );
    let mut valve = scene("valve.toml");
    // `USRAY_BENCH_VALVE_RAYS` overrides the valve's rays per element.
    if let Some(r) = std::env::var("USRAY_BENCH_VALVE_RAYS")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        valve.acquisition.rays_per_element = r;
    }
    let (s, rps, rays) = bench_render(&valve, 1);
    println!("tracer (whole render: trace + splat + pulse convolution): {s:.3} s, {rays} rays, {rps:.3e} rays/s");
    // Tracing alone (paths, connections, deposits; no splat/convolution).
    let st1 = valve.lift_const::<f64>().expect("lift");
    let opts1 = RenderOptions {
        threads: Some(1),
        ..Default::default()
    };
    let mut secs_t = Vec::new();
    let mut rays_t = 0;
    for _ in 0..REPEATS {
        let t = Instant::now();
        let (_, c, _) = usray_transport::trace_all(&valve, &st1, &opts1);
        secs_t.push(t.elapsed().as_secs_f64());
        rays_t = c.rays;
    }
    let st_s = median(secs_t);
    let rps_t = rays_t as f64 / st_s;
    println!("tracer (trace only): {st_s:.3} s, {rays_t} rays, {rps_t:.3e} rays/s");
    // The same primary rays (emission points and directions of every path),
    // world frame, traversed by the mesh's f32 BVH.
    let st = valve.lift_const::<f64>().expect("lift");
    let Shape::Mesh(mesh) = &st.geometry.objects()[0] else {
        panic!("valve scene object 0 is not a mesh")
    };
    let n_el = st.n_elements;
    let mut rays_v = Vec::new();
    for tx in 0..st.angles.len() {
        for el in 0..n_el {
            for r in 0..valve.acquisition.rays_per_element {
                let smp = PathSampler::new(valve.acquisition.seed, tx as u32, el as u32, r as u32);
                let x = element_x(st.pitch, n_el, el)
                    + st.element_width * (smp.uniform(0, dim::EMIT_X) - 0.5);
                let y = st.elevation * (smp.uniform(0, dim::EMIT_Y) - 0.5);
                let d = match valve.acquisition.emission {
                    Emission::Cosine => cosine_hemisphere(
                        smp.uniform(0, dim::EMIT_U1),
                        smp.uniform(0, dim::EMIT_U2),
                    ),
                    Emission::PlaneWave => {
                        let a = st.angles[tx];
                        [a.sin(), 0.0, a.cos()]
                    }
                };
                rays_v.push((
                    [x as f32, y as f32, 0.0f32],
                    [d[0] as f32, d[1] as f32, d[2] as f32],
                ));
            }
        }
    }
    // Repeat the traversal of all rays `inner` times per timing (≥ 0.1 s).
    let inner = (2_000_000 / rays_v.len().max(1)).max(1);
    let mut secs = Vec::new();
    let mut hits = 0;
    for _ in 0..REPEATS {
        let t = Instant::now();
        for _ in 0..inner {
            hits = 0;
            for (o, d) in &rays_v {
                if mesh.bvh.traverse_f32(*o, *d, f32::INFINITY).is_some() {
                    hits += 1;
                }
            }
        }
        secs.push(t.elapsed().as_secs_f64() / inner as f64);
    }
    let sb = median(secs);
    let bare = rays_v.len() as f64 / sb;
    println!(
        "bare obvhs: {sb:.3} s, {} primary rays ({hits} hit), {bare:.3e} rays/s",
        rays_v.len()
    );
    println!(
        "ratio tracer/bare = {:.3} (whole render), {:.3} (trace only)",
        rps / bare,
        rps_t / bare
    );
}
