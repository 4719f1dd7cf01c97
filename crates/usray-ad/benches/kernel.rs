//! Cost of derivatives on a tracer-like kernel, relative to plain `f64`.
//!
//! Kernel (generic over `T: Real`, written once): ray–sphere intersection, Snell
//! refraction with sound speeds (vector form), acoustic Fresnel amplitude
//! `A_r = (Z1 cosθi − Z2 cosθt)/(Z1 cosθi + Z2 cosθt)`, exit chord through the
//! sphere, and time of flight; the output is `A_r + ω·τ` (one scalar per ray, as
//! a per-path deposit weight would be).
//!
//! Variants, interleaved in one run so the ratios are side by side:
//! - `f64`: value only;
//! - `Dual<1>` (radius), `Dual<3>` (radius, c2, z2), `Dual<8>` (all 8 parameters);
//! - `reverse`: per ray, start a `Recording`, create 8 inputs, evaluate, sweep the
//!   gradient into a buffer, drop (tape cleared, memory kept) — a per-path tape.
//!
//! The rays are split into chunks of `CHUNK`; every (repetition, chunk) is timed
//! for every variant in turn. For each variant and chunk the median over `REPS`
//! repetitions is taken (robust to preemption on a shared machine), and the
//! medians are summed over chunks and divided by the number of rays. Run:
//! `cargo bench -p usray-ad --bench kernel`

use std::hint::black_box;
use std::ops::Range;
use std::time::Instant;
use usray_ad::reverse::{self, Recording};
use usray_ad::{Dual, Real};

const RAYS: usize = 4096;
const CHUNK: usize = 128;
const REPS: usize = 41;

/// Scene parameters θ: sphere centre (3, m), radius (m), sound speeds c1, c2
/// (m/s), impedances Z1, Z2 (MRayl).
const THETA: [f64; 8] = [0.01, -0.02, 0.0, 1.0, 1540.0, 1580.0, 1.63, 1.70];

#[inline(always)]
fn dot<T: Real>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn sub<T: Real>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The kernel. `o`, `d` (unit) are the ray (constants); `p` holds θ.
#[inline(always)]
fn kernel<T: Real>(o: [f64; 3], d: [f64; 3], p: &[T; 8]) -> T {
    let o = o.map(T::from_f64);
    let d = d.map(T::from_f64);
    let centre = [p[0], p[1], p[2]];
    let (r, c1, c2, z1, z2) = (p[3], p[4], p[5], p[6], p[7]);
    // Ray–sphere: |o + t d − c|² = r², t = −b − √(b² − (|oc|² − r²)).
    let oc = sub(o, centre);
    let b = dot(oc, d);
    let disc = b * b - (dot(oc, oc) - r * r);
    if disc.value() <= 0.0 {
        return T::zero(); // miss: no deposit, no derivative
    }
    let t = -b - disc.sqrt();
    let hit = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
    let inv_r = r.recip();
    let rel = sub(hit, centre);
    let n = [rel[0] * inv_r, rel[1] * inv_r, rel[2] * inv_r]; // outward unit normal
                                                              // Snell with sound speeds: sinθt = (c2/c1) sinθi.
    let cos_i = -dot(d, n);
    let eta = c2 / c1;
    let sin_t2 = eta * eta * (T::one() - cos_i * cos_i);
    let one = T::one();
    let tof_in = t / c1;
    if sin_t2.value() >= 1.0 {
        return one + tof_in.scale(1e3); // total internal reflection: A_r = 1
    }
    let cos_t = (one - sin_t2).safe_sqrt();
    // Acoustic Fresnel (pressure) amplitude, Z in MRayl.
    let zi = z1 * cos_i;
    let zt = z2 * cos_t;
    let a_r = (zi - zt) / (zi + zt);
    // Refracted direction d_t = η d + (η cosθi − cosθt) n; exit chord inside the
    // sphere from the hit point: t₂ = −2 (hit − c)·d_t.
    let k = eta * cos_i - cos_t;
    let dt = [
        eta * d[0] + k * n[0],
        eta * d[1] + k * n[1],
        eta * d[2] + k * n[2],
    ];
    let chord = -(dot(rel, dt) + dot(rel, dt));
    let tof = tof_in + chord / c2;
    a_r + tof.scale(1e3) // ms-scaled time of flight keeps both terms O(1)
}

/// Deterministic random rays (xorshift), origins on z = −5, aimed at the sphere.
fn rays() -> Vec<([f64; 3], [f64; 3])> {
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut u = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..RAYS)
        .map(|_| {
            // Uniform on a disc of radius 1.1 around the axis: most rays hit,
            // some graze (total internal reflection) or miss.
            let (rho, phi) = (1.1 * u().sqrt(), core::f64::consts::TAU * u());
            let o = [rho * phi.cos(), rho * phi.sin(), -5.0];
            let d = [0.1 * u() - 0.05, 0.1 * u() - 0.05, 1.0];
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            (o, [d[0] / l, d[1] / l, d[2] / l])
        })
        .collect()
}

fn run_f64(rays: &[([f64; 3], [f64; 3])]) -> f64 {
    let p = black_box(THETA);
    let mut acc = 0.0;
    for &(o, d) in rays {
        acc += kernel(black_box(o), d, &p);
    }
    acc
}

/// Seeds the first `N` entries of `order` (indices into θ) as dual variables.
fn run_dual<const N: usize>(rays: &[([f64; 3], [f64; 3])], order: &[usize; 8]) -> f64 {
    let theta = black_box(THETA);
    let mut p = theta.map(Dual::<N>::constant);
    for (k, &i) in order.iter().take(N).enumerate() {
        p[i] = Dual::variable(theta[i], k);
    }
    let mut acc = Dual::<N>::constant(0.0);
    for &(o, d) in rays {
        acc += kernel(black_box(o), d, &p);
    }
    acc.re + acc.eps.iter().sum::<f64>()
}

fn run_reverse(rays: &[([f64; 3], [f64; 3])], grad: &mut [f64; 8]) -> f64 {
    let theta = black_box(THETA);
    let mut acc = 0.0;
    for &(o, d) in rays {
        let rec = Recording::start();
        let p = rec.inputs_array::<8>(&theta);
        let y = kernel(black_box(o), d, &p);
        rec.gradient(y, grad);
        acc += y.value();
    }
    acc
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let rays = rays();
    let hits = rays
        .iter()
        .filter(|(o, d)| kernel(*o, *d, &THETA) != 0.0)
        .count();
    // radius first, then c2, z2 (Dual<3>), then the rest.
    let order = [3, 5, 7, 0, 1, 2, 4, 6];
    let mut grad = [0.0; 8];

    // Correctness guard: reverse and Dual<8> agree on the summed gradient.
    let mut g_rev = [0.0; 8];
    run_reverse(&rays, &mut g_rev);
    let d8 = {
        let mut p = THETA.map(Dual::<8>::constant);
        for i in 0..8 {
            p[i] = Dual::variable(THETA[i], i);
        }
        rays.iter()
            .map(|&(o, d)| kernel(o, d, &p))
            .fold(Dual::<8>::constant(0.0), |a, b| a + b)
    };
    for i in 0..8 {
        let scale = d8.eps[i].abs().max(1e-300);
        assert!(
            (g_rev[i] - d8.eps[i]).abs() <= 1e-9 * scale,
            "reverse and Dual<8> disagree on ∂/∂θ{i}: {} vs {}",
            g_rev[i],
            d8.eps[i]
        );
    }

    type Variant<'a> = (&'a str, Box<dyn FnMut(Range<usize>) -> f64 + 'a>);
    let rays_ref = &rays;
    let mut variants: Vec<Variant> = vec![
        ("f64", Box::new(move |r| run_f64(&rays_ref[r]))),
        (
            "Dual<1>",
            Box::new(move |r| run_dual::<1>(&rays_ref[r], &order)),
        ),
        (
            "Dual<3>",
            Box::new(move |r| run_dual::<3>(&rays_ref[r], &order)),
        ),
        (
            "Dual<8>",
            Box::new(move |r| run_dual::<8>(&rays_ref[r], &order)),
        ),
        (
            "reverse (8 inputs, tape per ray)",
            Box::new(|r| run_reverse(&rays_ref[r], &mut grad)),
        ),
    ];
    // Warm-up (also grows the tape to its steady-state size).
    for (_, f) in variants.iter_mut() {
        for _ in 0..3 {
            black_box(f(0..RAYS));
        }
    }
    let cap_before = reverse::tape_capacity();
    let nchunks = RAYS / CHUNK;
    // times[variant][chunk][rep]
    let mut times: Vec<Vec<Vec<f64>>> = (0..variants.len())
        .map(|_| (0..nchunks).map(|_| Vec::with_capacity(REPS)).collect())
        .collect();
    for _ in 0..REPS {
        for c in 0..nchunks {
            for (k, (_, f)) in variants.iter_mut().enumerate() {
                let t0 = Instant::now();
                black_box(f(c * CHUNK..(c + 1) * CHUNK));
                times[k][c].push(t0.elapsed().as_secs_f64() * 1e9);
            }
        }
    }
    let cap_after = reverse::tape_capacity();
    let meds: Vec<f64> = times
        .iter_mut()
        .map(|per_chunk| per_chunk.iter_mut().map(|t| median(t)).sum::<f64>() / RAYS as f64)
        .collect();
    println!(
        "usray-ad kernel: {RAYS} rays ({hits} hit the sphere), chunks of {CHUNK}, {REPS} interleaved repetitions, per-chunk medians"
    );
    println!("| variant | ns / evaluation | × f64 |");
    println!("|---|---:|---:|");
    for ((name, _), m) in variants.iter().zip(&meds) {
        println!("| {name} | {m:.1} | {:.2} |", m / meds[0]);
    }
    println!(
        "tape capacity (nodes + adjoints + inputs) before timing: {cap_before}, after: {cap_after} ({})",
        if cap_before == cap_after {
            "no growth: steady state allocation-free"
        } else {
            "GREW"
        }
    );
}
