//! The scoped reverse-mode API: accumulation, restart, VJP, steady-state
//! memory, and clear panics on misuse.

use usray_ad::reverse::{self, Recording, Var};
use usray_ad::Real;

fn f<T: Real>(x: T, y: T) -> T {
    (x * y).sin() + x.exp() / y
}

fn df(x: f64, y: f64) -> [f64; 2] {
    let c = (x * y).cos();
    [c * y + x.exp() / y, c * x - x.exp() / (y * y)]
}

#[test]
fn gradient_accumulates_into_the_buffer() {
    let mut g = [10.0, 20.0];
    let rec = Recording::start();
    let [x, y] = rec.inputs_array::<2>(&[0.3, 1.7]);
    let z = f(x, y);
    rec.gradient(z, &mut g);
    rec.gradient(z, &mut g); // the tape is intact: same gradient again
    let e = df(0.3, 1.7);
    for i in 0..2 {
        assert!((g[i] - ([10.0, 20.0][i] + 2.0 * e[i])).abs() < 1e-13);
    }
}

#[test]
fn per_path_loop_with_restart_matches_separate_recordings() {
    let points = [(0.1, 1.0), (0.5, 2.0), (-0.3, 0.7), (1.2, 1.1)];
    let mut acc = [0.0; 2];
    let mut rec = Recording::start();
    for &(a, b) in &points {
        rec.restart();
        let [x, y] = rec.inputs_array::<2>(&[a, b]);
        rec.gradient(f(x, y), &mut acc);
    }
    drop(rec);
    let mut sep = [0.0; 2];
    for &(a, b) in &points {
        let (_, g) = reverse::gradient(|v| f(v[0], v[1]), &[a, b]);
        sep[0] += g[0];
        sep[1] += g[1];
    }
    assert_eq!(acc, sep);
}

#[test]
fn vjp_weights_several_outputs_in_one_sweep() {
    let rec = Recording::start();
    let [x, y] = rec.inputs_array::<2>(&[0.4, 1.3]);
    let outs = [f(x, y), x * y, y.ln()];
    let w = [2.0, -1.0, 0.5];
    let mut g = [0.0; 2];
    rec.vjp(&outs, &w, &mut g);
    let e = df(0.4, 1.3);
    let exact = [2.0 * e[0] - 1.3, 2.0 * e[1] - 0.4 + 0.5 / 1.3];
    for i in 0..2 {
        assert!((g[i] - exact[i]).abs() < 1e-13, "{g:?} vs {exact:?}");
    }
}

#[test]
fn constants_unused_inputs_and_late_inputs_get_zero() {
    let rec = Recording::start();
    let x = rec.input(2.0);
    let unused = rec.input(5.0);
    let y = x * x;
    let late = rec.input(7.0); // created after the output
    let c = Var::constant(3.0) * Var::constant(4.0); // records nothing
    assert!(c.is_constant());
    let mut g = [0.0; 3];
    rec.gradient(y, &mut g);
    assert_eq!(g, [4.0, 0.0, 0.0]);
    let mut g2 = [0.0; 3];
    rec.gradient(c, &mut g2);
    assert_eq!(g2, [0.0; 3]);
    let _ = (unused, late);
    assert_eq!(rec.num_inputs(), 3);
}

#[test]
fn constants_work_outside_any_recording() {
    let a = Var::constant(2.0);
    let b = (a * a + a.sqrt()).exp();
    assert!(b.is_constant());
    assert_eq!(b.value(), (4.0 + 2f64.sqrt()).exp());
}

#[test]
fn steady_state_does_not_allocate() {
    // Warm up: grow the tape to the longest path.
    let run = |n: usize| {
        let rec = Recording::start();
        let [x, y] = rec.inputs_array::<2>(&[0.5, 1.5]);
        let mut z = x;
        for _ in 0..n {
            z = f(z, y);
        }
        let mut g = [0.0; 2];
        rec.gradient(z, &mut g);
        g
    };
    run(200);
    let cap = reverse::tape_capacity();
    for n in (0..200).rev() {
        run(n);
    }
    assert_eq!(
        reverse::tape_capacity(),
        cap,
        "tape memory changed in steady state"
    );
}

#[test]
#[should_panic(expected = "nested reverse-mode recordings are not supported")]
fn nested_recordings_panic() {
    let _a = Recording::start();
    let _b = Recording::start();
}

#[test]
#[should_panic(expected = "used after its Recording ended")]
fn var_after_its_recording_ended_panics() {
    let x = {
        let rec = Recording::start();
        rec.input(1.0)
    };
    let _ = x.sin();
}

#[test]
#[should_panic(expected = "outlived its Recording")]
fn var_from_an_earlier_recording_panics() {
    let mut rec = Recording::start();
    let x = rec.input(1.0);
    rec.restart();
    let y = rec.input(2.0);
    let _ = x + y;
}

#[test]
#[should_panic(expected = "recording has 2 inputs")]
fn gradient_buffer_of_wrong_length_panics() {
    let rec = Recording::start();
    let [x, y] = rec.inputs_array::<2>(&[1.0, 2.0]);
    let mut g = [0.0; 3];
    rec.gradient(x * y, &mut g);
}

#[test]
fn tape_is_released_after_a_panic() {
    let r = std::panic::catch_unwind(|| {
        let rec = Recording::start();
        let x = rec.input(1.0);
        let _ = x.sin();
        panic!("boom");
    });
    assert!(r.is_err());
    // The recording was dropped during unwinding: a new one can start.
    let (v, g) = reverse::gradient(|x| x[0] * x[0], &[3.0]);
    assert_eq!((v, g), (9.0, vec![6.0]));
}
