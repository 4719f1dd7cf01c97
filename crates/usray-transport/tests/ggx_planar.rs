//! The 2-D (flatland) GGX interface of `usray_transport::ggx_planar`: χ² test
//! of its visible-normal sampler against its density, its sampled weights
//! against the numerically integrated BSDF, the density's integral against the
//! share of valid samples, and the sampler's smoothness at normal incidence
//! (`eval_pdf` against `eval` and `pdf`: `tests/ggx.rs`, for both models).

mod common;
use common::{assert_counts_follow, mean_split_weight};
use std::f64::consts::{FRAC_PI_2, PI};
use usray_ad::{Dual, Real};
use usray_geometry::Vec3;
use usray_transport::ggx::Interface;
use usray_transport::ggx_planar::{sample_vndf, vndf_pdf};
use usray_transport::rng::PathSampler;

/// The in-plane unit vector at angle `a` from `+z` towards `+x`.
fn at(a: f64) -> Vec3<f64> {
    Vec3::new(a.sin(), 0.0, a.cos())
}

fn interface(alpha: f64, c2: f64, z2: f64) -> Interface<f64> {
    Interface {
        c1: 1540.0,
        c2,
        z1: 1.54,
        z2,
        alpha,
        planar: true,
    }
}

#[test]
fn planar_vndf_samples_follow_their_density_chi2() {
    // Bins over q = atan(tan θh / α)/(π/2) ∈ (−1, 1), a variable that resolves
    // the peak for any α; expected counts by a 16-point midpoint rule of the
    // density in each bin (dθ = (dθ/dq) dq); bins with expected < 5 merged.
    // Both signs of θi (the sampler's two forms of the visible arc) and
    // normal incidence, where they meet. Threshold: p-value > 1e-3.
    let n_bins = 60;
    let n = 300_000usize;
    for &(alpha, theta_i) in &[(0.3f64, 0.5f64), (0.6, -1.2), (0.1, 0.0), (0.02, 0.3)] {
        let wi = [theta_i.sin(), theta_i.cos()];
        let q_of =
            |hx: f64, hz: f64| ((hx / hz / alpha).atan() / FRAC_PI_2).clamp(-1.0, 1.0 - 1e-12);
        let mut counts = vec![0f64; n_bins];
        for k in 0..n {
            let s = PathSampler::new(11, 0, 0, k as u32);
            let h = sample_vndf(wi, alpha, s.uniform(0, 0));
            assert!((h[0] * h[0] + h[1] * h[1] - 1.0).abs() < 1e-12 && h[1] > 0.0);
            let i = (((q_of(h[0], h[1]) + 1.0) / 2.0) * n_bins as f64) as usize;
            counts[i.min(n_bins - 1)] += 1.0;
        }
        let sub = 16;
        let expected: Vec<f64> = (0..n_bins)
            .map(|i| {
                let mut acc = 0.0;
                for a in 0..sub {
                    let q = -1.0 + 2.0 * (i as f64 + (a as f64 + 0.5) / sub as f64) / n_bins as f64;
                    let tq = (q * FRAC_PI_2).tan();
                    let theta = (alpha * tq).atan();
                    let dtheta_dq =
                        alpha * FRAC_PI_2 * (1.0 + tq * tq) / (1.0 + alpha * alpha * tq * tq);
                    acc += vndf_pdf(wi, [theta.sin(), theta.cos()], alpha) * dtheta_dq;
                }
                acc / sub as f64 * (2.0 / n_bins as f64) * n as f64
            })
            .collect();
        assert_counts_follow(
            &counts,
            &expected,
            n,
            &format!("alpha {alpha}, θi {theta_i}"),
        );
    }
}

#[test]
fn planar_sampled_weight_matches_integrated_bsdf() {
    // E[weight of both continuations] = ∫ f(wi, wo)|wo·n| dθo over the circle.
    let n_vec = at(0.0);
    for &(alpha, theta_i, c2, z2) in &[
        (0.3f64, 0.4f64, 1800.0f64, 2.5f64),
        (0.5, -1.0, 1300.0, 1.0),
        (0.2, 0.2, 1300.0, 1.99),
        (0.05, 0.6, 1600.0, 1.76),
    ] {
        let iface = interface(alpha, c2, z2);
        let wi = at(theta_i);
        let n = 200_000usize;
        let (mean, se) = mean_split_weight(&iface, wi, n_vec, n);
        let m = 400_000;
        let integral: f64 = (0..m)
            .map(|k| iface.eval(wi, at((k as f64 + 0.5) / m as f64 * 2.0 * PI), n_vec))
            .sum::<f64>()
            * (2.0 * PI / m as f64);
        eprintln!(
            "alpha {alpha}, θi {theta_i}, c2 {c2}, Z2 {z2}: MC {mean:.5} ± {se:.5}, quadrature {integral:.5}"
        );
        // 4 standard errors, and 0.1% for the midpoint rule over 400 000 angles
        // (a step of 1.6e-5 rad against the narrowest lobe's width of 2α = 0.1).
        assert!(
            (mean - integral).abs() < 4.0 * se + 1e-3 * integral.abs(),
            "MC {mean} vs quadrature {integral}"
        );
    }
}

#[test]
fn planar_pdf_integrates_to_the_share_of_valid_samples() {
    // ∫ pdf over the reflected directions is the probability that a sampled
    // normal gives a reflection above the surface; the same for transmission.
    // Every lobe stays in the plane.
    let n_vec = at(0.0);
    for &(alpha, theta_i, c2) in &[(0.3f64, 0.4f64, 1800.0f64), (0.6, 1.1, 1300.0)] {
        let iface = interface(alpha, c2, 1.9);
        let wi = at(theta_i);
        let n = 200_000usize;
        let (mut refl, mut trans) = (0.0, 0.0);
        for k in 0..n {
            let s = PathSampler::new(6, 0, 0, k as u32);
            if let Some(x) = iface.scatter(wi, n_vec, s.uniform(1, 0), s.uniform(1, 1)) {
                for l in [x.reflected, x.transmitted].iter().flatten() {
                    assert!(l.wo.y == 0.0, "a planar lobe left the plane: {:?}", l.wo);
                }
                refl += f64::from(u8::from(x.reflected.is_some()));
                trans += f64::from(u8::from(x.transmitted.is_some()));
            }
        }
        let m = 400_000;
        let (mut p_r, mut p_t) = (0.0, 0.0);
        for k in 0..m {
            let wo = at((k as f64 + 0.5) / m as f64 * 2.0 * PI);
            let p = iface.pdf(wi, wo, n_vec) * (2.0 * PI / m as f64);
            if wo.z > 0.0 {
                p_r += p;
            } else {
                p_t += p;
            }
        }
        let (fr, ft) = (refl / n as f64, trans / n as f64);
        let se = |p: f64| (p * (1.0 - p) / n as f64).sqrt().max(1.0 / n as f64);
        eprintln!("alpha {alpha}, θi {theta_i}: reflection {fr:.4} vs ∫pdf {p_r:.4}, transmission {ft:.4} vs {p_t:.4}");
        assert!(
            (fr - p_r).abs() < 4.0 * se(fr) + 1e-3,
            "reflection {fr} vs {p_r}"
        );
        assert!(
            (ft - p_t).abs() < 4.0 * se(ft) + 1e-3,
            "transmission {ft} vs {p_t}"
        );
    }
}

#[test]
fn planar_sample_is_smooth_across_normal_incidence() {
    // The sampler's two forms of the visible arc meet at θi = 0: for a fixed
    // uniform the sampled normal and its derivative in θi are continuous there.
    for &(alpha, u) in &[(0.3f64, 0.2f64), (0.05, 0.7), (1.0, 0.5)] {
        let h_at = |t: f64| sample_vndf([t.sin(), t.cos()], alpha, u);
        let eps = 1e-7;
        let (a, b, c) = (h_at(-eps), h_at(0.0), h_at(eps));
        for k in 0..2 {
            assert!((a[k] - b[k]).abs() < 1e-5 && (c[k] - b[k]).abs() < 1e-5);
            let left = (b[k] - a[k]) / eps;
            let right = (c[k] - b[k]) / eps;
            assert!(
                (left - right).abs() < 1e-4 * left.abs().max(right.abs()).max(1.0),
                "alpha {alpha}, u {u}, component {k}: slope {left} vs {right}"
            );
        }
        // And in a dual: the derivative exists at 0 and matches the difference.
        let t = Dual::<1>::variable(0.0, 0);
        let h = sample_vndf([t.sin(), t.cos()], Dual::constant(alpha), u);
        let fd = (c[0] - a[0]) / (2.0 * eps);
        assert!(
            (h[0].eps[0] - fd).abs() < 1e-5 * fd.abs().max(1.0),
            "{} vs {fd}",
            h[0].eps[0]
        );
    }
}
