//! Dot-product (adjoint) identities `⟨A x, y⟩ = ⟨x, Aᵀ y⟩` for every linear operator,
//! with random sizes and data (proptest).
//!
//! Tolerances come from the standard floating-point bound for a sum of products
//! (Higham, "Accuracy and Stability of Numerical Algorithms", 2nd ed., ch. 3): a computed sum
//! of `m` terms `Σ a_i b_i` has error at most `γ_m Σ|a_i b_i|`, `γ_m ≈ m·ε`. Both
//! sides of the identity evaluate the same bilinear form `Σ y_p W_pk x_k` in
//! different orders, so `|lhs − rhs| ≤ 2 m ε Σ |y_p||W_pk||x_k|`, with `m` the longest
//! accumulation chain. For DAS, `Σ|y||W||x|` is computed exactly as the RF
//! delay-and-sum of `|x|` against `|y|` (the interpolation weights are ≥ 0). For the
//! IIR filters, where the error of a recursion is amplified by the filter, the
//! bound uses `‖x‖₂‖y‖₂·κ` with `κ = ‖h‖₁²` (ℓ1 norm of the one-pass impulse response
//! squared: forward and backward pass) and `m = n·(sections)`.

mod common;
use common::*;
use proptest::prelude::*;
use usray_signal::das::{linspace, Das};
use usray_signal::demod::{Analytic, IqDemod};
use usray_signal::filter::Sos;
use usray_signal::{gain, pulse, Complex64};

fn das_case(seed: u64, ne: usize, nt: usize, nx: usize, nz: usize, fnum: f64, rotate: bool) -> Das {
    das_case_grid(seed, ne, nt, nx, nz, fnum, rotate, false)
}

/// `lattice`: x step 0.1 mm = pitch/3, which takes the receive-delay lattice path.
fn das_case_grid(
    seed: u64,
    ne: usize,
    nt: usize,
    nx: usize,
    nz: usize,
    fnum: f64,
    rotate: bool,
    lattice: bool,
) -> Das {
    let mut r = Rng(seed);
    let angles: Vec<f64> = (0..nt).map(|_| 0.2 * r.next()).collect();
    let t0s: Vec<f64> = (0..nt).map(|_| 0.3e-6 * r.next()).collect();
    let m = meta(ne, 10e6, 3e6, &angles, &t0s);
    let x = if lattice {
        linspace(-0.9e-3, -0.9e-3 + (nx as f64 - 1.0) * 0.1e-3, nx)
    } else {
        linspace(-1e-3, 1e-3, nx)
    };
    // Depths chosen so no element sits exactly on an F-number aperture edge
    // (where 1-ulp differences between two exact paths would flip inclusion).
    let z = linspace(1.03e-3, 3.03e-3, nz);
    Das::new(&m, 60, x, z, 1540.0 * (1.0 + 0.05 * r.next()), fnum, rotate).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]

    #[test]
    fn das_iq_adjoint(seed in any::<u64>(), ne in 1usize..12, nt in 1usize..4, nx in 1usize..12, nz in 1usize..7,
                      fnum in prop_oneof![Just(0.0), 0.5f64..2.0], lattice in any::<bool>()) {
        let das = das_case_grid(seed, ne, nt, nx, nz, fnum, true, lattice);
        let mut r = Rng(seed ^ 1);
        let x = r.cvec(das.data_len());
        let y = r.cvec(nx * nz);
        let mut ax = vec![Complex64::new(0.0, 0.0); nx * nz];
        das.forward(&x, &mut ax);
        let mut aty = vec![Complex64::new(0.0, 0.0); das.data_len()];
        let mut scratch = aty.clone();
        das.vjp(&y, &mut aty, &mut scratch);
        let (lhs, rhs) = (cdot(&ax, &y), cdot(&x, &aty));
        // Σ|y||W||x| via the RF DAS of |x| against |y|.
        let mut rf = das.clone();
        rf.rotate = false;
        let ax_abs: Vec<f64> = x.iter().map(|v| v.norm()).collect();
        let mut s = vec![0.0; nx * nz];
        rf.forward(&ax_abs, &mut s);
        let bound: f64 = s.iter().zip(&y).map(|(a, b)| a * b.norm()).sum();
        let m = (2 * ne * nt + 2 * nx * nz + das.data_len()) as f64;
        prop_assert!((lhs - rhs).abs() <= 2.0 * m * EPS * bound + 1e-300, "lhs {lhs} rhs {rhs} bound {bound}");
    }

    /// Several frames (one coherent image per frame, `[nz, nx, n_frames]`), with
    /// frames interleaved across transmits (`frame_of[t] = t mod F`).
    #[test]
    fn das_iq_adjoint_frames(seed in any::<u64>(), ne in 1usize..10, nt in 1usize..5, nf_sel in 0usize..4,
                             nx in 1usize..10, nz in 1usize..6, lattice in any::<bool>()) {
        let mut das = das_case_grid(seed, ne, nt, nx, nz, 1.0, true, lattice);
        let nf = 1 + nf_sel % nt;
        das.frame_of = (0..nt).map(|t| t % nf).collect();
        das.n_frames = nf;
        let mut r = Rng(seed ^ 3);
        let x = r.cvec(das.data_len());
        let y = r.cvec(das.out_len());
        let mut ax = vec![Complex64::new(0.0, 0.0); das.out_len()];
        das.forward(&x, &mut ax);
        let mut aty = vec![Complex64::new(0.0, 0.0); das.data_len()];
        let mut scratch = aty.clone();
        das.vjp(&y, &mut aty, &mut scratch);
        let (lhs, rhs) = (cdot(&ax, &y), cdot(&x, &aty));
        let mut rf = das.clone();
        rf.rotate = false;
        let ax_abs: Vec<f64> = x.iter().map(|v| v.norm()).collect();
        let mut s = vec![0.0; das.out_len()];
        rf.forward(&ax_abs, &mut s);
        let bound: f64 = s.iter().zip(&y).map(|(a, b)| a * b.norm()).sum();
        let m = (2 * ne * nt + 2 * das.out_len() + das.data_len()) as f64;
        prop_assert!((lhs - rhs).abs() <= 2.0 * m * EPS * bound + 1e-300, "lhs {lhs} rhs {rhs} bound {bound}");
    }

    #[test]
    fn das_rf_adjoint(seed in any::<u64>(), ne in 1usize..12, nt in 1usize..4, nx in 1usize..12, nz in 1usize..7,
                      fnum in prop_oneof![Just(0.0), 0.5f64..2.0], lattice in any::<bool>()) {
        let das = das_case_grid(seed, ne, nt, nx, nz, fnum, false, lattice);
        let mut r = Rng(seed ^ 2);
        let x = r.vec(das.data_len());
        let y = r.vec(nx * nz);
        let mut ax = vec![0.0; nx * nz];
        das.forward(&x, &mut ax);
        let mut aty = vec![0.0; das.data_len()];
        let mut scratch = aty.clone();
        das.vjp(&y, &mut aty, &mut scratch);
        let (lhs, rhs) = (dot(&ax, &y), dot(&x, &aty));
        let xa: Vec<f64> = x.iter().map(|v| v.abs()).collect();
        let mut s = vec![0.0; nx * nz];
        das.forward(&xa, &mut s);
        let bound: f64 = s.iter().zip(&y).map(|(a, b)| a * b.abs()).sum();
        let m = (2 * ne * nt + 2 * nx * nz + das.data_len()) as f64;
        prop_assert!((lhs - rhs).abs() <= 2.0 * m * EPS * bound + 1e-300, "lhs {lhs} rhs {rhs}");
    }

    #[test]
    fn filtfilt_adjoint(seed in any::<u64>(), n in 2usize..300, order in 1usize..7, cut in 0.02f64..0.45, band in any::<bool>()) {
        let fs = 1.0;
        let sos = if band {
            Sos::butter_bandpass(order, cut * 0.5, cut, fs).unwrap()
        } else {
            Sos::butter_lowpass(order, cut, fs).unwrap()
        };
        let mut r = Rng(seed);
        let (x, y) = (r.vec(n), r.vec(n));
        let mut ax = x.clone();
        sos.filtfilt_in_place(&mut ax);
        let mut aty = y.clone();
        sos.filtfilt_vjp_in_place(&mut aty);
        let (lhs, rhs) = (dot(&ax, &y), dot(&x, &aty));
        let mut h = vec![0.0; 2000];
        h[0] = 1.0;
        sos.filter_in_place(&mut h);
        let kappa = h.iter().map(|v| v.abs()).sum::<f64>().powi(2);
        let m = (n * sos.sections.len() * 4) as f64;
        prop_assert!((lhs - rhs).abs() <= 2.0 * m * EPS * kappa * norm2(&x) * norm2(&y), "lhs {lhs} rhs {rhs}");
    }

    #[test]
    fn iq_demod_adjoint(seed in any::<u64>(), n in 8usize..300, t0 in -1e-6f64..1e-5) {
        let (fs, fc) = (6.0e6, 5e6); // band-pass undersampled, like PWI_disk
        let d = IqDemod::new(fc, fs, 0.375e6, 5).unwrap();
        let mut r = Rng(seed);
        let x = r.vec(n);
        let y = r.cvec(n);
        let mut ax = vec![Complex64::new(0.0, 0.0); n];
        d.forward(&x, t0, &mut ax);
        let mut aty = vec![0.0; n];
        d.vjp(&y, t0, &mut aty);
        let (lhs, rhs) = (cdot(&ax, &y), dot(&x, &aty));
        let mut h = vec![0.0; 4000];
        h[0] = 1.0;
        d.lowpass.filter_in_place(&mut h);
        let kappa = h.iter().map(|v| v.abs()).sum::<f64>().powi(2);
        let ny = y.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
        let m = (n * d.lowpass.sections.len() * 4 + 8) as f64;
        prop_assert!((lhs - rhs).abs() <= 4.0 * m * EPS * kappa * norm2(&x) * ny, "lhs {lhs} rhs {rhs}");
    }

    #[test]
    fn analytic_adjoint(seed in any::<u64>(), n in 1usize..257) {
        let a = Analytic::new(n);
        let mut r = Rng(seed);
        let x = r.vec(n);
        let mut y = r.cvec(n);
        let y0 = y.clone();
        let mut sc = vec![Complex64::new(0.0, 0.0); a.scratch_len()];
        let mut ax = vec![Complex64::new(0.0, 0.0); n];
        a.forward(&x, &mut ax, &mut sc);
        let mut aty = vec![0.0; n];
        a.vjp(&mut y, &mut aty, &mut sc);
        let (lhs, rhs) = (cdot(&ax, &y0), dot(&x, &aty));
        // FFT round-off: O(ε log₂ n) relative in ℓ2 per transform (Higham, ch. 24);
        // 4 transforms, ‖A‖₂ ≤ 2.
        let ny = y0.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
        let lg = (n as f64).log2().max(1.0);
        prop_assert!((lhs - rhs).abs() <= 4.0 * 2.0 * 8.0 * lg * EPS * norm2(&x) * ny, "lhs {lhs} rhs {rhs}");
    }

    #[test]
    fn convolution_adjoint(seed in any::<u64>(), n in 1usize..200, cycles in 1.0f64..5.0) {
        let taps = pulse::pulse_taps(40e6, 5e6, cycles);
        let mut r = Rng(seed);
        let (x, y) = (r.vec(n), r.vec(n));
        let mut ax = vec![0.0; n];
        pulse::convolve(&x, &taps, &mut ax);
        let mut aty = vec![0.0; n];
        pulse::convolve_vjp(&y, &taps, &mut aty);
        let (lhs, rhs) = (dot(&ax, &y), dot(&x, &aty));
        let ta: Vec<f64> = taps.iter().map(|v| v.abs()).collect();
        let xa: Vec<f64> = x.iter().map(|v| v.abs()).collect();
        let mut s = vec![0.0; n];
        pulse::convolve(&xa, &ta, &mut s);
        let bound: f64 = s.iter().zip(&y).map(|(a, b)| a * b.abs()).sum();
        let m = (taps.len() + n) as f64;
        prop_assert!((lhs - rhs).abs() <= 2.0 * m * EPS * bound, "lhs {lhs} rhs {rhs}");
    }

    #[test]
    fn gain_adjoint(seed in any::<u64>(), n in 1usize..300, db in 0.0f64..3.0) {
        let g = gain::gain_table(n, 1e-6, 20e6, db, 1540.0);
        let mut r = Rng(seed);
        let (x, y) = (r.vec(n), r.vec(n));
        let mut ax = vec![0.0; n];
        gain::apply_gain(&x, &g, &mut ax);
        let mut aty = vec![0.0; n];
        gain::apply_gain_vjp(&y, &g, &mut aty);
        let (lhs, rhs) = (dot(&ax, &y), dot(&x, &aty));
        let bound: f64 = x.iter().zip(&y).zip(&g).map(|((a, b), c)| (a * b * c).abs()).sum();
        prop_assert!((lhs - rhs).abs() <= 2.0 * (n as f64 + 2.0) * EPS * bound);
    }
}

fn polymul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

#[test]
fn butterworth_matches_scipy() {
    // scipy 1.17.1: b, a = scipy.signal.butter(5, 0.25)
    let b_ref = [
        0.003279216306360205,
        0.016396081531801027,
        0.03279216306360205,
        0.03279216306360205,
        0.016396081531801027,
        0.003279216306360205,
    ];
    let a_ref = [
        1.0,
        -2.4744161749781632,
        2.8110063119115827,
        -1.7037722409154687,
        0.5444326948885343,
        -0.07231566910295853,
    ];
    let s = Sos::butter_lowpass(5, 0.125, 1.0).unwrap();
    let (mut b, mut a) = (vec![1.0], vec![1.0]);
    for q in &s.sections {
        let nb = if q.b[2] == 0.0 && q.a[1] == 0.0 { 2 } else { 3 };
        b = polymul(&b, &q.b[..nb]);
        a = polymul(&a, &[1.0, q.a[0], q.a[1]][..nb]);
    }
    assert_eq!((b.len(), a.len()), (6, 6));
    for k in 0..6 {
        assert!(
            (b[k] - b_ref[k]).abs() < 1e-14,
            "b[{k}] {} vs {}",
            b[k],
            b_ref[k]
        );
        assert!(
            (a[k] - a_ref[k]).abs() < 1e-13,
            "a[{k}] {} vs {}",
            a[k],
            a_ref[k]
        );
    }
    // Maximally flat: |H|² = 1/(1 + (tan(πf)/tan(πf_c))^(2N)) (bilinear Butterworth).
    for f in [0.0, 0.01, 0.05, 0.1, 0.125, 0.2, 0.3, 0.45] {
        let ratio = (core::f64::consts::PI * f).tan() / (core::f64::consts::PI * 0.125).tan();
        let want = 1.0 / (1.0 + ratio.powi(10)).sqrt();
        assert!(
            (s.magnitude(f, 1.0) - want).abs() < 1e-12,
            "f {f}: {} vs {want}",
            s.magnitude(f, 1.0)
        );
    }
}

#[test]
fn das_is_independent_of_thread_count() {
    let das = das_case(7, 16, 3, 9, 11, 0.0, true);
    let mut r = Rng(3);
    let x = r.cvec(das.data_len());
    let y = r.cvec(99);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut out = vec![Complex64::new(0.0, 0.0); 99];
            das.forward(&x, &mut out);
            let mut back = vec![Complex64::new(0.0, 0.0); das.data_len()];
            let mut sc = back.clone();
            das.vjp(&y, &mut back, &mut sc);
            let g = das.calibration_vjp(&x, &y);
            (out, back, g)
        })
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn bmode_is_independent_of_thread_count() {
    use usray_signal::{BMode, ChannelData, Demod, ImagingSettings};
    let m = meta(12, 10e6, 3e6, &[-0.1, 0.1], &[0.0, -0.2e-6]);
    let mut r = Rng(17);
    let ch = ChannelData {
        meta: m,
        n_samples: 64,
        samples: r.vec(2 * 12 * 64),
    };
    for demod in [Demod::Iq, Demod::Hilbert] {
        let mut s = ImagingSettings::new([-1e-3, 1e-3], [1e-3, 3e-3], 0.2e-3);
        s.demod = demod;
        s.f_number = 1.0;
        s.depth_gain_db_per_cm = 0.5;
        let b = BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
        let w = r.vec(11 * 11);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut ws = b.workspace();
                let img = b.forward(&ch, &mut ws).unwrap();
                (img.data, b.vjp(&mut ws, &w).unwrap())
            })
        };
        assert_eq!(run(1), run(3));
    }
}

/// The lattice path (uniform x grid, pitch a multiple of the step) gives the same
/// image as the direct path (one-column grids never use the lattice).
#[test]
fn das_lattice_path_matches_direct_path() {
    for fnum in [0.0, 1.0] {
        let das = das_case_grid(5, 16, 3, 25, 9, fnum, true, true);
        let mut r = Rng(8);
        let x = r.cvec(das.data_len());
        let mut full = vec![Complex64::new(0.0, 0.0); 25 * 9];
        das.forward(&x, &mut full);
        for ix in [0, 7, 12, 24] {
            let mut one = das.clone();
            one.x_m = vec![das.x_m[ix]];
            let mut col = vec![Complex64::new(0.0, 0.0); 9];
            one.forward(&x, &mut col);
            for iz in 0..9 {
                let (a, b) = (full[iz * 25 + ix], col[iz]);
                assert!(
                    (a - b).norm() <= 1e-9 * b.norm().max(1e-3),
                    "ix {ix} iz {iz}: {a} vs {b}"
                );
            }
        }
    }
}
