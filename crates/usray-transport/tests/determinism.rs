//! Bit-identical channel data with 1 and several threads (separate rayon pools),
//! and reproducibility of a seed.

mod common;
use common::scene_path;
use usray_transport::{render, RenderOptions, Scene};

#[test]
fn one_thread_and_many_are_bit_identical() {
    let scene = Scene::load(scene_path("ring.toml")).unwrap();
    let run = |threads| {
        let opts = RenderOptions {
            threads: Some(threads),
            rays_per_element: Some(40),
            ..Default::default()
        };
        render(&scene, &opts).unwrap().0
    };
    let a = run(1);
    let b = run(2);
    let c = run(4);
    assert!(a.samples.iter().any(|v| *v != 0.0));
    let bits =
        |d: &usray_signal::ChannelData| d.samples.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b), "1 vs 2 threads differ");
    assert_eq!(bits(&a), bits(&c), "1 vs 4 threads differ");
    // Another seed gives other data.
    let opts = RenderOptions {
        threads: Some(2),
        rays_per_element: Some(40),
        seed: Some(99),
        ..Default::default()
    };
    let d = render(&scene, &opts).unwrap().0;
    assert_ne!(bits(&a), bits(&d));
}
