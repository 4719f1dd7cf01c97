//! The same generic tracer with the reverse-mode `Var` (one recording on one
//! thread, paths traced directly): the gradient of a functional of the deposits
//! equals the forward dual's.

mod common;
use common::{keys, scene_path};
use usray_ad::reverse::Recording;
use usray_ad::{Dual, Real};
use usray_transport::{trace_path, Scene, TraceSettings};

const PARAMS: [&str; 3] = [
    "objects.cylinder.radius_m",
    "materials.target.impedance_mrayl",
    "materials.target.roughness",
];

fn functional<T: Real>(scene: &Scene, st: &usray_transport::SceneT<T>) -> T {
    let s = TraceSettings {
        seed: 3,
        max_bounces: scene.acquisition.max_bounces,
        rays_per_element: 1,
        receivers_per_event: 0,
        sampler: usray_transport::scene::Sampler::Independent,
    };
    let mut acc = T::zero();
    for el in (0..scene.probe.n_elements).step_by(8) {
        for ray in 0..6 {
            trace_path(st, &s, 2, el, ray, |d| {
                // L = Σ a_k · (1 + 1e6·τ_k): both amplitude and time derivatives count.
                acc += d.amplitude * (T::one() + d.time.scale(1e6));
            });
        }
    }
    acc
}

#[test]
fn reverse_mode_gradient_equals_forward_dual() {
    let scene = Scene::load(scene_path("cylinder.toml")).unwrap();
    let params = keys(&PARAMS);
    // Forward: one dual pass with three partials.
    let st = scene
        .lift::<Dual<3>>(|p, v| match params.iter().position(|q| q == p) {
            Some(i) => Dual::variable(v, i),
            None => Dual::from_f64(v),
        })
        .unwrap();
    let fwd = functional(&scene, &st);
    // Reverse: inputs in the order of PARAMS (the lift visits paths in a fixed
    // order, so create the inputs first and hand them out by path).
    let rec = Recording::start();
    let inputs: Vec<_> = params
        .iter()
        .map(|p| rec.input(scene.get(p).unwrap()))
        .collect();
    let st = scene
        .lift(|p, v| match params.iter().position(|q| q == p) {
            Some(i) => inputs[i],
            None => usray_ad::reverse::Var::from_f64(v),
        })
        .unwrap();
    let y = functional(&scene, &st);
    let mut g = vec![0.0; PARAMS.len()];
    rec.gradient(y, &mut g);
    eprintln!(
        "value {} / {}; forward {:?}; reverse {:?}",
        fwd.value(),
        y.value(),
        fwd.eps,
        g
    );
    assert_eq!(fwd.value(), y.value());
    assert!(fwd.eps.iter().any(|e| *e != 0.0));
    for i in 0..PARAMS.len() {
        let tol = 1e-9 * fwd.eps[i].abs().max(1e-12);
        assert!(
            (fwd.eps[i] - g[i]).abs() <= tol,
            "{}: {} vs {}",
            PARAMS[i],
            fwd.eps[i],
            g[i]
        );
    }
}
