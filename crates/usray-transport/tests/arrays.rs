//! Phased and convex arrays with diverging and focused transmits (issue 21,
//! the tracer side): echo times against closed forms, thread-count
//! determinism, and derivatives with respect to the array's radius and the
//! transmits' virtual source and focus against finite differences.

mod common;
use common::ad_and_fd;
use usray_signal::transmit::TransmitWave;
use usray_transport::{render, trace_path, RenderOptions, Scene, TraceSettings};

/// A scene with the given `[probe]` lines (kind, elements, pitch, width,
/// radius), `[[acquisition.transmits]]` tables and objects.
fn scene(probe: &str, transmits: &str, rays: usize, bounces: u32, objects: &str) -> Scene {
    let text = format!(
        r#"
[medium]
sound_speed_m_s = 1540.0
impedance_mrayl = 1.54

[probe]
{probe}
center_frequency_hz = 3.0e6
cycles = 2.0
main_lobe_deg = 5.0
cutoff_deg = 80.0
elevation_m = 4.0e-3

[acquisition]
sampling_frequency_hz = 40.0e6
max_depth_m = 0.06
rays_per_element = {rays}
max_bounces = {bounces}
seed = 7
{transmits}

[imaging]
x_range_m = [-0.02, 0.02]
z_range_m = [0.005, 0.05]
pixel_m = 0.2e-3
f_number = 1.0
dynamic_range_db = 60.0

{objects}
"#
    );
    Scene::from_toml_str(&text, "arrays.toml", ".").unwrap()
}

const PHASED: &str = r#"kind = "phased"
n_elements = 32
pitch_m = 0.2e-3
element_width_m = 0.2e-3"#;

const CONVEX: &str = r#"kind = "convex"
n_elements = 48
pitch_m = 0.5e-3
element_width_m = 0.5e-3
radius_m = 0.02"#;

/// A smooth plane interface at depth `depth_m` (everything deeper is the
/// target material).
fn plane(depth_m: f64) -> String {
    format!(
        r#"
[materials.target]
impedance_mrayl = 2.5
sound_speed_m_s = 1540.0
roughness = 0.0

[[objects]]
name = "interface"
shape = "plane"
center_m = [0.0, 0.0, {depth_m}]
material = "target"
"#
    )
}

/// Per receiving element: (amplitude-weighted mean deposit time, its standard
/// error, total amplitude) over every ray of every element for transmit `tx`.
fn echo_times(s: &Scene, tx: usize) -> Vec<Option<(f64, f64, f64)>> {
    let st = s.lift_const::<f64>().unwrap();
    let a = &s.acquisition;
    let settings = TraceSettings {
        seed: a.seed,
        max_bounces: a.max_bounces,
        rays_per_element: a.rays_per_element,
        receivers_per_event: 0,
        sampler: a.sampler,
    };
    let n = s.probe.n_elements;
    let mut acc = vec![Vec::<(f64, f64)>::new(); n];
    for el in 0..n {
        for ray in 0..a.rays_per_element as u32 {
            trace_path(&st, &settings, tx, el, ray, |d| {
                acc[d.element as usize].push((d.amplitude, d.time));
            });
        }
    }
    acc.iter()
        .map(|v| {
            let w: f64 = v.iter().map(|p| p.0).sum();
            if v.len() < 20 || w <= 0.0 {
                return None;
            }
            let mean = v.iter().map(|p| p.0 * p.1).sum::<f64>() / w;
            let var = v.iter().map(|p| p.0 * (p.1 - mean).powi(2)).sum::<f64>() / w;
            // Effective sample count of a weighted mean (Kish).
            let n_eff = w * w / v.iter().map(|p| p.0 * p.0).sum::<f64>();
            Some((mean, (var / n_eff).sqrt(), w))
        })
        .collect()
}

/// The echo of a plane `z = D` by the image principle: the reflected wave
/// reaches `e` when the incident wave would reach the mirror point
/// `e* = (x_e, 2D − z_e)` (transmit arrival at the reflection point plus
/// the path from it to the element, on CONTRACT §1's clock).
fn mirror_time(wave: &TransmitWave<f64>, e: [f64; 2], depth: f64, c: f64) -> f64 {
    wave.arrival_time_s([e[0], 2.0 * depth - e[1]], c)
}

/// Checks every receiving element's echo time against the image-principle
/// closed form; returns the largest error in samples.
fn check_echo_times(s: &Scene, depth: f64, tol_samples: f64) -> f64 {
    let waves = s.transmit_waves();
    let elements = s.array_geometry().elements();
    let (c, fs) = (1540.0, s.acquisition.sampling_frequency_hz);
    let mut worst = 0.0_f64;
    for (tx, wave) in waves.iter().enumerate() {
        let times = echo_times(s, tx);
        let received = times.iter().filter(|t| t.is_some()).count();
        assert!(
            received >= 8,
            "transmit {tx}: only {received} elements receive the echo"
        );
        for (e, t) in times.iter().enumerate() {
            let Some((mean, se, _)) = *t else { continue };
            let want = mirror_time(wave, elements[e].centre_m, depth, c);
            let err = (mean - want).abs() * fs;
            worst = worst.max(err);
            assert!(
                err < tol_samples + 3.0 * se * fs,
                "transmit {tx} element {e}: echo at {mean:e} s, closed form {want:e} s: {err:.3} samples (± {:.3})",
                se * fs
            );
        }
    }
    worst
}

/// Phased array, two diverging waves (one off-axis): the echo of a plane
/// 30 mm deep at each element within 0.1 sample (2.5 ns at 40 MHz, plus
/// three standard errors of the mean) of the image-principle time
/// (measured: 0.004 sample). The mean over a receiving face equals the time
/// at its centre up to the front's curvature over the face, O(w²).
#[test]
fn phased_diverging_echo_times_match_the_image_principle() {
    let tx = r#"
[[acquisition.transmits]]
kind = "diverging"
virtual_source_m = [0.0, -0.01]

[[acquisition.transmits]]
kind = "diverging"
virtual_source_m = [0.003, -0.008]
"#;
    let s = scene(PHASED, tx, 512, 1, &plane(0.03));
    let worst = check_echo_times(&s, 0.03, 0.1);
    eprintln!("phased, diverging: worst echo-time error {worst:.4} samples");
}

/// Convex array (R = 20 mm), a focused wave (focus at 20 mm, before the
/// plane: the echo comes back from beyond the focus, the `+` branch of the
/// time model) and a diverging one: same closed form, same tolerance
/// (measured: 0.08 sample; the emitting face is its flat tangent, the
/// receiving face the arc).
#[test]
fn convex_focused_and_diverging_echo_times_match_the_image_principle() {
    let tx = r#"
[[acquisition.transmits]]
kind = "focused"
focus_m = [0.002, 0.02]

[[acquisition.transmits]]
kind = "diverging"
virtual_source_m = [-0.002, -0.015]
"#;
    let s = scene(CONVEX, tx, 512, 1, &plane(0.03));
    let worst = check_echo_times(&s, 0.03, 0.1);
    eprintln!("convex: worst echo-time error {worst:.4} samples");
}

/// A rough cylinder (connections to every element, volume-free) 25 mm deep.
const CYLINDER: &str = r#"
[materials.target]
impedance_mrayl = 1.99
sound_speed_m_s = 1570.0
roughness = 0.3

[[objects]]
name = "cylinder"
shape = "cylinder"
center_m = [0.002, 0.0, 0.025]
radius_m = 0.005
material = "target"
"#;

const FOCUSED_AND_DIVERGING: &str = r#"
[[acquisition.transmits]]
kind = "focused"
focus_m = [0.002, 0.03]

[[acquisition.transmits]]
kind = "diverging"
virtual_source_m = [-0.002, -0.015]
"#;

/// Same seed, same bits, on 1 and 2 threads: both array kinds, both
/// emission models.
#[test]
fn renders_are_bit_identical_across_thread_counts() {
    for (probe, emission) in [
        (PHASED, "plane_wave"),
        (CONVEX, "plane_wave"),
        (CONVEX, "cosine"),
    ] {
        let tx = format!("emission = \"{emission}\"\n{FOCUSED_AND_DIVERGING}");
        let s = scene(probe, &tx, 6, 3, CYLINDER);
        let run = |threads| {
            let opts = RenderOptions {
                threads: Some(threads),
                ..Default::default()
            };
            render(&s, &opts).unwrap().0.samples
        };
        let (one, two) = (run(1), run(2));
        assert!(one.iter().any(|v| *v != 0.0), "{probe}: empty render");
        assert!(
            one.iter()
                .zip(&two)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{probe}, {emission}: 1 and 2 threads differ"
        );
    }
}

/// The convex radius, the focus and the virtual source are differentiable
/// parameters (`usray params` lists them) whose AD derivative matches
/// central differences of the same realization within 1e-6.
#[test]
fn radius_focus_and_virtual_source_match_finite_differences() {
    let s = scene(CONVEX, FOCUSED_AND_DIVERGING, 4, 3, CYLINDER);
    let names: Vec<String> = s.params().into_iter().map(|p| p.0.to_string()).collect();
    for p in [
        "probe.radius_m",
        "acquisition.transmits.0.focus_m.0",
        "acquisition.transmits.0.focus_m.1",
        "acquisition.transmits.1.virtual_source_m.0",
        "acquisition.transmits.1.virtual_source_m.1",
    ] {
        assert!(names.iter().any(|n| n == p), "{p} is not a parameter");
    }
    // Central differences at h = 1e-8, 1e-9 and 1e-10 m: the realization is
    // piecewise smooth (a ray crossing an element's edge or the array's end
    // is a visibility change, not differentiated), so a step may straddle
    // such a crossing (measured: 1e-4 … 3e-4 there) and below 1e-10 m the
    // roundoff ε·|L|/h grows as h shrinks (3e-6 at 1e-9 m for the virtual
    // source's depth, whose derivative is 1000× smaller than the focus's).
    // The derivative must match the difference of at least one of the steps
    // within 1e-6.
    let params = [
        "probe.radius_m",
        "acquisition.transmits.0.focus_m.0",
        "acquisition.transmits.0.focus_m.1",
        "acquisition.transmits.1.virtual_source_m.0",
        "acquisition.transmits.1.virtual_source_m.1",
    ];
    let at = |h: f64| ad_and_fd(&s, &params.map(|p| (p, h)));
    let steps = [at(1e-8), at(1e-9), at(1e-10)];
    let r: Vec<_> = (0..params.len())
        .map(|i| {
            let best = steps.iter().map(|s| s[i]);
            best.min_by(|a, b| a.2.total_cmp(&b.2)).unwrap()
        })
        .collect();
    for (i, (ad, fd, rel)) in r.iter().enumerate() {
        assert!(*rel < 1e-6, "parameter {i}: AD {ad} FD {fd} rel {rel}");
    }
}

/// Bad geometry is an error naming the scene key (usray-signal's rules).
#[test]
fn bad_arrays_and_transmits_name_their_key() {
    let with = |probe: &str, transmits: &str| {
        let text = format!(
            "[medium]\nsound_speed_m_s = 1540.0\nimpedance_mrayl = 1.54\n\n[probe]\n{probe}\n\
             center_frequency_hz = 3.0e6\ncycles = 2.0\nmain_lobe_deg = 5.0\ncutoff_deg = 80.0\n\n\
             [acquisition]\nsampling_frequency_hz = 40.0e6\nmax_depth_m = 0.06\n\
             rays_per_element = 4\nmax_bounces = 1\nseed = 7\n{transmits}\n"
        );
        Scene::from_toml_str(&text, "bad.toml", ".")
    };
    let diverging =
        "[[acquisition.transmits]]\nkind = \"diverging\"\nvirtual_source_m = [0.0, -0.01]";
    assert!(with(PHASED, diverging).is_ok());
    assert!(with(CONVEX, diverging).is_ok());
    let cases = [
        (
            PHASED.replace("phased", "curved"),
            diverging.to_string(),
            "probe.kind",
        ),
        (
            CONVEX.replace("0.02", "0.01"),
            diverging.to_string(),
            "probe.radius_m",
        ),
        (
            format!("{PHASED}\nradius_m = 0.05"),
            diverging.to_string(),
            "probe.radius_m",
        ),
        (
            CONVEX.replace("radius_m = 0.02", ""),
            diverging.to_string(),
            "probe.radius_m",
        ),
        (
            PHASED.replace("element_width_m = 0.2e-3", "element_width_m = 0.3e-3"),
            diverging.to_string(),
            "probe.element_width_m",
        ),
        (
            PHASED.into(),
            diverging.replace("-0.01]", "0.01]"),
            "acquisition.transmits.0.virtual_source_m",
        ),
        (
            PHASED.into(),
            "[[acquisition.transmits]]\nkind = \"focused\"\nfocus_m = [0.0, -0.02]".into(),
            "acquisition.transmits.0.focus_m",
        ),
        (
            PHASED.into(),
            "[[acquisition.transmits]]\nkind = \"focused\"\nvirtual_source_m = [0.0, -0.02]".into(),
            "acquisition.transmits.0.focus_m",
        ),
        (
            PHASED.into(),
            format!("{diverging}\nangle_deg = 5.0"),
            "acquisition.transmits.0.angle_deg",
        ),
        (
            PHASED.into(),
            "[[acquisition.transmits]]\nkind = \"plane_wave\"\nangle_deg = 95.0".into(),
            "acquisition.transmits.0.angle_deg",
        ),
        (
            PHASED.into(),
            "[[acquisition.transmits]]\nkind = \"spherical\"".into(),
            "acquisition.transmits.0.kind",
        ),
        (PHASED.into(), String::new(), "acquisition.angles_deg"),
    ];
    for (probe, transmits, key) in cases {
        let e = with(&probe, &transmits).expect_err(key);
        assert_eq!(e.key, key, "{e}");
        eprintln!("{e}");
    }
}

/// The channel file of a render carries the probe kind and radius and each
/// transmit's kind and point, read back by usray-signal (what `usray
/// beamform` does) as the scene's own geometry and waves.
#[test]
fn channel_metadata_carries_the_array_and_the_transmits() {
    let s = scene(CONVEX, FOCUSED_AND_DIVERGING, 2, 1, CYLINDER);
    let opts = RenderOptions {
        threads: Some(1),
        ..Default::default()
    };
    let meta = render(&s, &opts).unwrap().0.meta;
    let array = usray_signal::array::ArrayGeometry::from_meta(&meta.probe).unwrap();
    assert_eq!(array, s.array_geometry());
    let waves: Vec<_> = (meta.transmits.iter().enumerate())
        .map(|(i, t)| TransmitWave::from_meta(i, t).unwrap())
        .collect();
    assert_eq!(waves, s.transmit_waves());
    assert!(matches!(waves[0], TransmitWave::Focused { .. }));
    assert!(matches!(waves[1], TransmitWave::Diverging { .. }));
}
