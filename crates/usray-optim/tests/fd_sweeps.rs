//! The finite-difference sweeps of `usray grad --fd-sweep` and `usray demo`
//! (`usray_optim::fd_sweeps`) on a tiny scene: their steps, their agreement
//! with the AD gradient of the fixed-seed loss, and their errors.

use usray_optim::{best_fd, fd_sweeps, grid_shape, sweep_steps, Objective, ParamSpec};
mod common;
use common::tiny_scene;
use usray_transport::RenderOptions;

/// `scene`'s objective for `specs` against its own image at a smaller radius.
fn objective(specs: Vec<ParamSpec>) -> Objective {
    let scene = tiny_scene();
    let render = RenderOptions {
        rays_per_element: Some(10),
        ..Default::default()
    };
    let (nz, nx) = grid_shape(&scene).unwrap();
    let mut truth = scene.clone();
    truth
        .set(&"objects.cylinder.radius_m".parse().unwrap(), 4.6e-3)
        .unwrap();
    let reference = Objective::new(truth, vec![0.0; nz * nx], vec![], render.clone())
        .unwrap()
        .value(&[])
        .unwrap()
        .image
        .data;
    Objective::new(scene, reference, specs, render).unwrap()
}

/// One sweep per parameter over `sweep_steps` (two renders per step), and with
/// common random numbers the best step agrees with the AD gradient of the
/// impedance — which moves no ray across an edge — to 1e-6.
#[test]
fn sweeps_take_their_steps_and_agree_with_ad() {
    let spec = ParamSpec {
        key: "materials.target.impedance_mrayl".parse().unwrap(),
        min: 1.7,
        max: 2.5,
    };
    let obj = objective(vec![spec.clone()]);
    let at = obj.initial_physical();
    let mut renders = 0;
    let sweeps = fd_sweeps(&obj, &at, || renders += 1).unwrap();
    assert_eq!(sweeps.len(), 1);
    let eps: Vec<f64> = sweeps[0].iter().map(|p| p.eps).collect();
    assert_eq!(eps, sweep_steps(&spec));
    assert_eq!(renders, 2 * eps.len());
    let ad = obj.value_and_gradient(&at).unwrap().gradient[0];
    assert!(ad != 0.0);
    let (best, rel) = best_fd(&sweeps[0], ad).unwrap();
    assert!(
        rel < 1e-6,
        "FD {} at ε = {} vs AD {ad}: {rel:e}",
        best.fd,
        best.eps
    );
}

/// A step that leaves the scene's valid region (a negative radius) fails the
/// sweep with an error naming the parameter and the cause.
#[test]
fn a_failing_step_names_the_parameter() {
    let spec = ParamSpec {
        key: "objects.cylinder.radius_m".parse().unwrap(),
        min: 0.0,
        max: 0.01,
    };
    let obj = objective(vec![spec]);
    // The largest step, 1e-4 m, takes the radius below 0.
    let err = fd_sweeps(&obj, &[5e-5], || {}).unwrap_err();
    assert_eq!(
        err.to_string(),
        "finite differences of objects.cylinder.radius_m"
    );
    let cause = std::error::Error::source(&err).expect("the render's error");
    assert!(cause.to_string().contains("radius"), "{cause}");
}
