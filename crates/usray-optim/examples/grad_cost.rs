//! Gradient cost and memory of the calibration objective on `scenes/cylinder.toml`.
//!
//! `cargo run --release -p usray-optim --example grad_cost -- ratio` prints the
//! time of one value (render + B-mode + loss) and of value + gradient for 3 and 16
//! parameters; `… -- mem RAYS` runs one 3-parameter value + gradient at RAYS rays
//! per element and prints the peak resident memory (VmHWM).

use std::time::Instant;
use usray_optim::{Objective, ParamSpec};
use usray_transport::{RenderOptions, Scene};

const CYLINDER: &str = include_str!("../../../scenes/cylinder.toml");

const P16: [&str; 16] = [
    "objects.cylinder.radius_m",
    "materials.target.impedance_mrayl",
    "materials.target.roughness",
    "objects.cylinder.center_m.0",
    "objects.cylinder.center_m.2",
    "materials.target.sound_speed_m_s",
    "medium.sound_speed_m_s",
    "medium.impedance_mrayl",
    "probe.pitch_m",
    "probe.element_width_m",
    "probe.center_frequency_hz",
    "probe.cycles",
    "probe.main_lobe_deg",
    "probe.cutoff_deg",
    "probe.elevation_m",
    "imaging.sound_speed_m_s",
];

fn objective(n: usize, rays: Option<usize>) -> (Objective, Vec<f64>) {
    let truth = Scene::from_toml_str(CYLINDER, "cylinder.toml", ".").unwrap();
    let opts = RenderOptions {
        rays_per_element: rays,
        ..Default::default()
    };
    let (nz, nx) = usray_optim::grid_shape(&truth).unwrap();
    let helper = Objective::new(truth.clone(), vec![0.0; nz * nx], vec![], opts.clone()).unwrap();
    let reference = helper.value(&[]).unwrap().image.data;
    let mut start = truth.clone();
    start
        .set(&"objects.cylinder.radius_m".parse().unwrap(), 0.0055)
        .unwrap();
    let specs: Vec<ParamSpec> = P16[..n]
        .iter()
        .map(|p| ParamSpec::parse(p, &start).unwrap())
        .collect();
    let at = P16[..n]
        .iter()
        .map(|p| start.get(&p.parse().unwrap()).unwrap())
        .collect();
    (Objective::new(start, reference, specs, opts).unwrap(), at)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time(mut f: impl FnMut(), reps: usize) -> f64 {
    median(
        (0..reps)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    match args.get(1).map(String::as_str) {
        Some("mem") => {
            let rays: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(200);
            let (obj, at) = objective(3, Some(rays));
            let e = obj.value_and_gradient(&at).unwrap();
            let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
            let hwm = status
                .lines()
                .find(|l| l.starts_with("VmHWM"))
                .unwrap_or("VmHWM: ?");
            println!("rays_per_element {rays}: loss {:.4e}, {hwm}", e.loss);
        }
        _ => {
            let (o3, a3) = objective(3, None);
            let (o16, a16) = objective(16, None);
            let v = time(|| drop(o3.value(&a3).unwrap()), 5);
            let g3 = time(|| drop(o3.value_and_gradient(&a3).unwrap()), 3);
            let g16 = time(|| drop(o16.value_and_gradient(&a16).unwrap()), 3);
            println!("threads {}", rayon::current_num_threads());
            println!("value                 {v:.3} s");
            println!("value+grad  3 params  {g3:.3} s  ratio {:.2}", g3 / v);
            println!("value+grad 16 params  {g16:.3} s  ratio {:.2}", g16 / v);
        }
    }
}
