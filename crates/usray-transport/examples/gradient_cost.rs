//! Cost of the transport gradient against the value (render), and its memory.
//!
//! `gradient_cost value SCENE RAYS` renders once; `gradient_cost grad SCENE RAYS P`
//! renders and takes the gradient of `L = Σ w·P` for the first `P` parameters of
//! [`PATHS`]. Prints seconds. Run under `/usr/bin/time -v` for the peak RSS:
//! ```text
//! /usr/bin/time -v target/release/examples/gradient_cost grad scenes/cylinder.toml 20 3
//! /usr/bin/time -v target/release/examples/gradient_cost grad scenes/cylinder.toml 200 3
//! ```
use std::time::Instant;
use usray_transport::{channel_gradient, render, RenderOptions, Scene};

include!("../benches/common/cylinder_params.rs");

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let needed = if a.first().is_some_and(|m| m.starts_with("grad")) {
        4
    } else {
        3
    };
    if a.len() < needed {
        eprintln!("usage: gradient_cost value|lift SCENE RAYS  |  gradient_cost grad|grad_fwd SCENE RAYS P");
        std::process::exit(2);
    }
    let scene = Scene::load(&a[1]).expect("scene");
    let opts = RenderOptions {
        rays_per_element: Some(a[2].parse().expect("rays")),
        ..Default::default()
    };
    let t = Instant::now();
    let (d, stats) = render(&scene, &opts).expect("render");
    let tv = t.elapsed().as_secs_f64();
    if a[0] == "lift" {
        lift_cost(&scene);
        return;
    }
    if a[0] == "value" {
        println!("value {tv:.3} s ({} rays)", stats.rays_traced);
        return;
    }
    let p: usize = a[3].parse().expect("P");
    let w: Vec<f64> = d.samples.iter().map(|v| v.signum() * 1e-3).collect();
    let t = Instant::now();
    // `grad_fwd`: the same parameters in forward passes of 8 (two calls below
    // the reverse-mode threshold) for the crossover measurement.
    let params = params();
    let g = if a[0] == "grad_fwd" {
        params[..p]
            .chunks(8)
            .flat_map(|c| channel_gradient(&scene, c, &w, &opts).expect("gradient"))
            .collect()
    } else {
        channel_gradient(&scene, &params[..p], &w, &opts).expect("gradient")
    };
    let tg = t.elapsed().as_secs_f64();
    println!(
        "value {tv:.3} s, gradient ({p} params) {tg:.3} s, value+gradient / value = {:.2}; g[0] = {:.3e}",
        (tv + tg) / tv,
        g[0]
    );
}

fn lift_cost(scene: &Scene) {
    let meshes = scene.mesh_instances().expect("meshes");
    let t = Instant::now();
    for _ in 0..1000 {
        let st = scene.lift_with(Some(&meshes), |_, v| v).expect("lift");
        std::hint::black_box(&st);
    }
    println!("lift_with: {:.1} µs", t.elapsed().as_secs_f64() * 1e3);
}
