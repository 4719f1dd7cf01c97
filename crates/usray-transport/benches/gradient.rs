//! Transport gradient cost (`harness = false`, median of repeats): value (f64
//! render) against value + `channel_gradient` of `L = Σ w·P` for 3 parameters
//! (one `Dual<3>` replay) and 16 parameters (per-path reverse mode), on
//! `scenes/cylinder.toml` at its default settings, all cores.
//!
//! Run: `cargo bench -p usray-transport --bench gradient`. Peak memory against
//! the ray count: `examples/gradient_cost.rs` under `/usr/bin/time -v`.

use std::time::Instant;
use usray_transport::{channel_gradient, render, RenderOptions, Scene};

const REPEATS: usize = 3;

include!("common/cylinder_params.rs");
include!("common/bench_util.rs");

fn main() {
    let scene = scene("cylinder.toml");
    let opts = RenderOptions::default();
    let (d, _) = render(&scene, &opts).expect("render");
    let w: Vec<f64> = d.samples.iter().map(|v| v.signum() * 1e-3).collect();
    let value = median(
        (0..REPEATS)
            .map(|_| {
                let t = Instant::now();
                render(&scene, &opts).expect("render");
                t.elapsed().as_secs_f64()
            })
            .collect(),
    );
    println!("value (render): {value:.3} s");
    let params = params();
    for n in [3, 16] {
        let g = median(
            (0..REPEATS)
                .map(|_| {
                    let t = Instant::now();
                    channel_gradient(&scene, &params[..n], &w, &opts).expect("gradient");
                    t.elapsed().as_secs_f64()
                })
                .collect(),
        );
        println!(
            "{n} parameters: gradient {g:.3} s; value+gradient / value = {:.2}",
            (value + g) / value
        );
    }
}
