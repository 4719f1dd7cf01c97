//! AD vs central FD of L = Σ w·P for a scene and parameters (diagnostics):
//! `cargo run --release -p usray-transport --example grad_check -- SCENE RAYS REL_H PATH...`
use usray_transport::{channel_gradient, render, RenderOptions, Scene};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scene = Scene::load(&args[0]).unwrap();
    let rays: usize = args[1].parse().unwrap();
    let rel: f64 = args[2].parse().unwrap();
    let params: Vec<_> = args[3..].iter().map(|p| scene.key(p).unwrap()).collect();
    let opts = RenderOptions {
        rays_per_element: Some(rays),
        ..Default::default()
    };
    let (d, _) = render(&scene, &opts).unwrap();
    let mut x = 12345u64;
    let w: Vec<f64> = d
        .samples
        .iter()
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect();
    let loss = |s: &Scene| -> f64 {
        let (d, _) = render(s, &opts).unwrap();
        d.samples.iter().zip(&w).map(|(p, w)| p * w).sum()
    };
    let t = std::time::Instant::now();
    let g = channel_gradient(&scene, &params, &w, &opts).unwrap();
    eprintln!("gradient in {:.2} s", t.elapsed().as_secs_f64());
    for (j, p) in params.iter().enumerate() {
        let st = scene.lift_dual::<1>(std::slice::from_ref(p)).unwrap();
        let (pd, _, _) = usray_transport::render_lifted(&scene, &st, &opts);
        let via_render: f64 = pd.iter().zip(&w).map(|(p, w)| p.eps[0] * w).sum();
        println!("{p}: dual render {via_render:.6e}");
        let v = scene.get(p).unwrap();
        let h = rel * v.abs().max(1e-3);
        let mut sp = scene.clone();
        sp.set(p, v + h).unwrap();
        let mut sm = scene.clone();
        sm.set(p, v - h).unwrap();
        let fd = (loss(&sp) - loss(&sm)) / (2.0 * h);
        println!(
            "{p}: AD {:.6e} FD {:.6e} rel {:.2e}",
            g[j],
            fd,
            (g[j] - fd).abs() / fd.abs().max(1e-300)
        );
    }
}
