//! Reverse mode under rayon: many threads differentiate different functions at
//! the same time on their own thread-local tapes; every gradient must be right
//! and independent of the scheduling.

mod common;

use common::{eval, point, tree, E, NVARS};
use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::TestRunner;
use rayon::prelude::*;
use usray_ad::reverse::{Recording, Var};
use usray_ad::{Dual, Real};

fn grad_rev(e: &E, x: &[f64]) -> [f64; NVARS] {
    let rec = Recording::start();
    let xs: [Var; NVARS] = rec.inputs_array(x);
    let y = eval(e, &xs);
    let mut g = [0.0; NVARS];
    rec.gradient(y, &mut g);
    g
}

fn grad_dual(e: &E, x: &[f64]) -> [f64; NVARS] {
    let xs: Vec<Dual<NVARS>> = (0..NVARS).map(|i| Dual::variable(x[i], i)).collect();
    eval(e, &xs).eps
}

fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .expect("thread pool")
}

/// 600 different random functions, differentiated in parallel on 7 threads
/// (more than the machine's cores, so recordings interleave), compared with
/// forward mode computed serially (same tolerance as `expr_trees.rs`), and
/// bit-identical to a single-threaded run.
#[test]
fn parallel_reverse_gradients_of_different_functions() {
    let mut runner = TestRunner::deterministic();
    let cases: Vec<(E, Vec<f64>)> = (0..600)
        .map(|_| {
            let e = tree().new_tree(&mut runner).expect("tree").current();
            let x = point().new_tree(&mut runner).expect("point").current();
            (e, x)
        })
        .filter(|(e, x)| eval(e, x).is_finite())
        .collect();
    assert!(cases.len() > 500);

    let par = pool(7).install(|| {
        cases
            .par_iter()
            .map(|(e, x)| grad_rev(e, x))
            .collect::<Vec<_>>()
    });
    let one = pool(1).install(|| {
        cases
            .par_iter()
            .map(|(e, x)| grad_rev(e, x))
            .collect::<Vec<_>>()
    });
    for (((e, x), gp), g1) in cases.iter().zip(&par).zip(&one) {
        let gd = grad_dual(e, x);
        let gmax = gd.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        for i in 0..NVARS {
            assert_eq!(
                gp[i].to_bits(),
                g1[i].to_bits(),
                "scheduling changed a gradient"
            );
            let tol = 1e-12 * gp[i].abs().max(gd[i].abs()) + 1e-12 * gmax.max(1.0);
            assert!(
                (gp[i] - gd[i]).abs() <= tol,
                "{e:?} at {x:?}: reverse {gp:?} vs dual {gd:?}"
            );
        }
    }
}

/// A family of functions with known gradients, one per task, with recordings
/// of very different lengths (so tapes grow at different times on different
/// threads): f_k(x, y) = Σ_{j<k} sin(j·x)·y² / j, ∂f/∂x = Σ cos(j·x)·y²,
/// ∂f/∂y = Σ 2·sin(j·x)·y / j.
#[test]
fn parallel_known_gradients_with_varied_tape_lengths() {
    let results: Vec<(usize, [f64; 2], [f64; 2])> = pool(5).install(|| {
        (1..400usize)
            .into_par_iter()
            .map(|k| {
                let (x0, y0) = (0.1 + 0.001 * k as f64, 1.0 - 0.002 * k as f64);
                let rec = Recording::start();
                let [x, y] = rec.inputs_array::<2>(&[x0, y0]);
                let f: Var = (1..=k)
                    .map(|j| (x.scale(j as f64)).sin() * y * y / Var::constant(j as f64))
                    .sum();
                let mut g = [0.0; 2];
                rec.gradient(f, &mut g);
                let mut exact = [0.0; 2];
                for j in 1..=k {
                    let jf = j as f64;
                    exact[0] += (jf * x0).cos() * y0 * y0;
                    exact[1] += 2.0 * (jf * x0).sin() * y0 / jf;
                }
                (k, g, exact)
            })
            .collect()
    });
    for (k, g, exact) in results {
        for i in 0..2 {
            // Sums of k ≤ 400 terms of size ≤ 1: rounding ≤ k·ε relative to Σ|terms| ≤ k.
            assert!(
                (g[i] - exact[i]).abs() <= 1e-13 * k as f64,
                "k = {k}: {g:?} vs {exact:?}"
            );
        }
    }
}

/// A `Var` moved to another thread cannot silently read that thread's tape.
#[test]
fn var_from_another_thread_panics_clearly() {
    let rec = Recording::start();
    let x = rec.input(2.0);
    let handle = std::thread::spawn(move || {
        let rec2 = Recording::start();
        let y = rec2.input(1.0);
        let _ = x * y; // x belongs to the main thread's recording
    });
    let err = handle.join().expect_err("must panic");
    let msg = err.downcast_ref::<String>().cloned().unwrap_or_default();
    assert!(msg.contains("belongs to another thread"), "message: {msg}");
    drop(rec);
}
