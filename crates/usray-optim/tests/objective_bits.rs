//! The objective's loss and gradient at a fixed seed, pinned by a hash of
//! their bits (FNV-1a): restructuring the render and gradient plumbing must
//! keep them. The demodulation's centre-frequency part is pinned separately
//! (it is checked against finite differences in `demod_fc.rs`).

use usray_optim::{Objective, ParamSpec};
use usray_transport::{RenderOptions, Scene};

fn hash(v: &[f64]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for x in v {
        for b in x.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// The demo cylinder on 32 elements and two transmits, imaged on a small grid.
fn scene() -> Scene {
    let text = include_str!("../../../scenes/cylinder.toml")
        .replace("n_elements = 128", "n_elements = 32")
        .replace(
            "angles_deg = [-10.0, -5.0, 0.0, 5.0, 10.0]",
            "angles_deg = [-5.0, 5.0]",
        )
        .replace("x_range_m = [-0.015, 0.015]", "x_range_m = [-0.004, 0.004]")
        .replace("z_range_m = [0.002, 0.028]", "z_range_m = [0.008, 0.013]")
        .replace("pixel_m = 0.1e-3", "pixel_m = 0.2e-3");
    Scene::from_toml_str(&text, "cylinder.toml", ".").unwrap()
}

const PARAMS: [&str; 5] = [
    "objects.cylinder.radius_m",
    "materials.target.impedance_mrayl",
    "probe.pitch_m",
    "imaging.sound_speed_m_s",
    "probe.center_frequency_hz",
];

/// An objective against the truth's image, evaluated at a moved radius.
fn objective(paired: bool) -> (Objective, Vec<f64>) {
    let truth = scene();
    let opts = RenderOptions {
        rays_per_element: Some(4),
        threads: Some(2),
        ..Default::default()
    };
    let (nz, nx) = usray_optim::grid_shape(&truth).unwrap();
    let helper = Objective::new(truth.clone(), vec![0.0; nz * nx], vec![], opts.clone()).unwrap();
    let reference = helper.value(&[]).unwrap().image.data;
    let mut start = truth;
    start
        .set(&"objects.cylinder.radius_m".parse().unwrap(), 0.0052)
        .unwrap();
    let specs: Vec<ParamSpec> = PARAMS
        .iter()
        .map(|p| ParamSpec::parse(p, &start).unwrap())
        .collect();
    let at = PARAMS
        .iter()
        .map(|p| start.get(&p.parse().unwrap()).unwrap())
        .collect();
    let obj = Objective::new(start, reference, specs, opts)
        .unwrap()
        .with_pairing(paired);
    (obj, at)
}

/// The hash of the loss and the gradient of the parameters other than `f_c`;
/// `f_c`'s gradient without its demodulation part; that part.
fn evaluate(paired: bool) -> (u64, f64, f64) {
    let (obj, at) = objective(paired);
    let e = obj.value_and_gradient(&at).unwrap();
    let fc = PARAMS.len() - 1;
    let mut bits = vec![e.loss];
    bits.extend(&e.gradient[..fc]);
    assert!(e.demod_fc_part[..fc].iter().all(|d| *d == 0.0));
    (
        hash(&bits),
        e.gradient[fc] - e.demod_fc_part[fc],
        e.demod_fc_part[fc],
    )
}

/// Per loss (one render, paired): the hash of the loss and the other
/// parameters' gradient, `f_c`'s transport part, and the demodulation part
/// as the central difference in `f_c` (step `10⁻⁴ f_c`) gave it before the
/// exact derivative replaced it.
const PINNED: [(u64, f64, f64); 2] = [
    (
        7_499_836_982_772_408_803,
        -1.731_987_718_278_852_5e-8,
        1.604_349_930_683_923_7e-11,
    ),
    (
        8_094_158_158_671_367_525,
        -6.092_193_102_584_459e-9,
        2.287_272_456_158_451e-11,
    ),
];

#[test]
fn loss_and_gradient_keep_their_bits() {
    for (paired, pinned) in [false, true].into_iter().zip(PINNED) {
        let (bits, transport, demod) = evaluate(paired);
        println!("paired {paired}: {bits} {transport:e} {demod:e}");
        assert_eq!(bits, pinned.0, "paired {paired}");
        // `f_c`'s gradient less its demodulation part: the transport part up
        // to the rounding of that subtraction.
        assert!(
            (transport - pinned.1).abs() <= 1e-12 * pinned.1.abs(),
            "paired {paired}: {transport:e} vs {:e}",
            pinned.1
        );
        println!(
            "paired {paired}: demodulation f_c part {demod:e}, the old central difference {:e}, relative {:e}",
            pinned.2,
            (demod - pinned.2).abs() / pinned.2.abs()
        );
    }
}

/// The exact demodulation part of `f_c`'s gradient against the objective's
/// old central difference (step `10⁻⁴ f_c`, the loss of the B-mode rebuilt at
/// `f_c ± h` with the channel data held, recomputed here and equal to the
/// pinned value) and against its Richardson extrapolation from `h` and `h/2`:
/// the old difference is within twice its own truncation error estimate,
/// `4/3·|D(h) − D(h/2)|`, and the extrapolation agrees to 10⁻⁶ relative.
#[test]
fn exact_demodulation_part_agrees_with_the_old_central_difference() {
    let (obj, at) = objective(false);
    let exact = obj.value_and_gradient(&at).unwrap().demod_fc_part[PARAMS.len() - 1];
    let scene = obj.scene_at(&at).unwrap();
    let (ch, _) = usray_transport::render(&scene, &obj.opts).unwrap();
    let loss_at = |fc: f64| {
        let mut meta = ch.meta.clone();
        meta.center_frequency_hz = fc;
        let b = usray_signal::BMode::new(&scene.imaging_settings(), &meta, ch.n_samples).unwrap();
        let mut ws = b.workspace();
        let img = b.forward(&ch, &mut ws).unwrap();
        obj.loss.value(&obj.compared(&img), &obj.reference)
    };
    let fc = ch.meta.center_frequency_hz;
    let d = |h: f64| (loss_at(fc + h) - loss_at(fc - h)) / (2.0 * h);
    let h = 1e-4 * fc;
    let (old, half) = (d(h), d(0.5 * h));
    assert_eq!(old, PINNED[0].2, "the old difference, recomputed");
    let accuracy = 4.0 / 3.0 * (old - half).abs();
    let richardson = (4.0 * half - old) / 3.0;
    println!(
        "exact {exact:e}, old FD {old:e} (error estimate {accuracy:e}), Richardson {richardson:e}, relative {:e}",
        (exact - richardson).abs() / exact.abs()
    );
    assert!((old - exact).abs() <= 2.0 * accuracy);
    assert!((richardson - exact).abs() < 1e-6 * exact.abs());
}
