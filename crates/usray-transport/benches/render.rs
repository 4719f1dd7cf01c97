//! Transport throughput (`harness = false`, own timing loop, median of repeats).
//!
//! (a) The cylinder demo scene at its default settings, in a rayon pool of 1
//!     thread and of all cores: seconds and rays per second.
//! (b) The valve mesh scene, single-threaded: whole-tracer rays per second
//!     against bare `obvhs` traversal (the geometry crate's f32 BVH,
//!     `MeshBvh::traverse_f32`) of **the same rays**: every ray the tracer casts
//!     (path segments and receiver connections, with their `t` ranges) is
//!     recorded with `integrator::trace_path_casts` and replayed through the
//!     bare traversal, in the tracer's order; also split by kind (primary,
//!     later path segments of every branch, connections).
//!
//! Run: `cargo bench -p usray-transport --bench render`

use std::time::Instant;
use usray_geometry::{MeshBvh, Shape};
use usray_transport::integrator::{element_stack, trace_path_casts};
use usray_transport::{render, RenderOptions, Scene};

const REPEATS: usize = 5;

include!("common/bench_util.rs");

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
    // `USRAY_BENCH_ONLY=b` skips part (a) (for profiling part (b) alone),
    // `USRAY_BENCH_ONLY=a` skips part (b).
    let only = std::env::var("USRAY_BENCH_ONLY").unwrap_or_default();
    let only_b = only == "b";
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

    if only == "a" {
        return;
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
    let st = valve.lift_const::<f64>().expect("lift");
    let opts1 = RenderOptions {
        threads: Some(1),
        ..Default::default()
    };
    let mut secs_t = Vec::new();
    let mut rays_t = 0;
    for _ in 0..REPEATS {
        let t = Instant::now();
        let (_, c, _) = usray_transport::trace_all(&valve, &st, &opts1);
        secs_t.push(t.elapsed().as_secs_f64());
        rays_t = c.rays;
    }
    let st_s = median(secs_t);
    let rps_t = rays_t as f64 / st_s;
    println!("tracer (trace only): {st_s:.3} s, {rays_t} rays, {rps_t:.3e} rays/s");
    // Every ray the tracer casts, in its order, as `f32` (what the bare
    // traversal takes; the tracer converts its `f64` rays itself).
    let Shape::Mesh(mesh) = &st.geometry.objects()[0] else {
        panic!("valve scene object 0 is not a mesh")
    };
    assert_eq!(st.geometry.len(), 1, "the valve scene is one mesh");
    let settings = render::settings(&valve, &opts1);
    let mut casts = Vec::new();
    // Kinds: 0 primary (first ray of a path), 1 later path segment, 2 connection
    // (finite `t_max`).
    let mut kind = Vec::new();
    for tx in 0..st.transmits.len() {
        for el in 0..st.n_elements {
            let stack = element_stack(&st, el);
            for r in 0..settings.rays_per_element {
                let first = casts.len();
                trace_path_casts(
                    &st,
                    &settings,
                    tx,
                    el,
                    r as u32,
                    stack,
                    |_| {},
                    |ray, t0, t1| {
                        let (o, d) = (ray.origin.value(), ray.dir.value());
                        kind.push(if casts.len() == first {
                            0u8
                        } else if t1.is_finite() {
                            2
                        } else {
                            1
                        });
                        casts.push(Cast {
                            o: o.map(|x| x as f32),
                            d: d.map(|x| x as f32),
                            t: [t0 as f32, t1 as f32],
                        });
                    },
                );
            }
        }
    }
    assert_eq!(casts.len() as u64, rays_t, "recorded rays = rays counted");
    let (sb, hits) = bench_bare(&mesh.bvh, &casts);
    let bare = casts.len() as f64 / sb;
    println!(
        "bare obvhs, the same {} rays in the tracer's order: {sb:.3} s ({hits} hit), {bare:.3e} rays/s",
        casts.len()
    );
    let mut bare_primary = 0.0;
    for (k, name) in ["primary", "secondary path segments", "connections"]
        .iter()
        .enumerate()
    {
        let sub: Vec<Cast> = casts
            .iter()
            .zip(&kind)
            .filter(|(_, &c)| c as usize == k)
            .map(|(c, _)| *c)
            .collect();
        let (s, hits) = bench_bare(&mesh.bvh, &sub);
        let rate = sub.len() as f64 / s;
        println!(
            "  bare obvhs, {name}: {} rays ({hits} hit), {s:.3} s, {rate:.3e} rays/s",
            sub.len()
        );
        if k == 0 {
            bare_primary = rate;
        }
    }
    println!(
        "ratio tracer/bare on the same rays = {:.3} (whole render), {:.3} (trace only)",
        rps / bare,
        rps_t / bare
    );
    println!(
        "(against bare primary rays only, the earlier comparison: {:.3} / {:.3})",
        rps / bare_primary,
        rps_t / bare_primary
    );
}

/// One recorded ray in `f32`: origin, unit direction, `[t_min, t_max]` metres.
#[derive(Clone, Copy)]
struct Cast {
    o: [f32; 3],
    d: [f32; 3],
    t: [f32; 2],
}

/// Seconds per pass of the bare traversal of `rays` (median of [`REPEATS`]
/// timings, each of enough passes for ≥ 2e6 rays), and the hits of one pass.
fn bench_bare(bvh: &MeshBvh, rays: &[Cast]) -> (f64, usize) {
    let inner = (2_000_000 / rays.len().max(1)).max(1);
    let mut secs = Vec::new();
    let mut hits = 0;
    for _ in 0..REPEATS {
        let t = Instant::now();
        for _ in 0..inner {
            hits = rays
                .iter()
                .filter(|c| {
                    std::hint::black_box(bvh.traverse_f32(c.o, c.d, c.t[0], c.t[1])).is_some()
                })
                .count();
        }
        secs.push(t.elapsed().as_secs_f64() / inner as f64);
    }
    (median(secs), hits)
}
