//! GGX microfacet interface: χ² test of the visible-normal sampler against its
//! density, and the sampled-weight estimator against the numerically integrated
//! BSDF (reflection + transmission); the tracer's one-pass `eval_pdf` against
//! the reference `eval` and `pdf`, in 3-D and in 2-D (`ggx_planar`).

mod common;
use common::{assert_counts_follow, mean_split_weight};
use usray_ad::{Dual, Real};
use usray_geometry::Vec3;
use usray_transport::ggx::{sample_vndf, vndf_pdf, Interface};
use usray_transport::rng::PathSampler;

#[test]
fn vndf_samples_follow_their_density_chi2() {
    // Bins over (q, φh) with q = atan(tan θh / α)/(π/2) ∈ [0, 1) (a polar variable
    // that resolves the peak for any α) and φh ∈ [0, 2π); expected counts by
    // integrating the density with an 8×8 midpoint rule inside each bin
    // (dω = sin θ (dθ/dq) dq dφ); bins with expected < 5 are merged into one.
    // Threshold: p-value > 1e-3.
    let (n_ct, n_phi) = (20, 24);
    let n = 400_000usize;
    for &(alpha, theta_i) in &[(0.3f64, 0.5f64), (0.6, 1.2), (0.1, 0.0)] {
        let wv = Vec3::new(theta_i.sin(), 0.0, theta_i.cos());
        let mut counts = vec![0f64; n_ct * n_phi];
        for k in 0..n {
            let s = PathSampler::new(11, 0, 0, k as u32);
            let h = sample_vndf(wv, alpha, s.uniform(0, 0), s.uniform(0, 1));
            let theta = h.z.clamp(-1.0, 1.0).acos();
            let q = ((theta.tan() / alpha).atan() / std::f64::consts::FRAC_PI_2)
                .clamp(0.0, 1.0 - 1e-12);
            let mut phi = h.y.atan2(h.x);
            if phi < 0.0 {
                phi += 2.0 * std::f64::consts::PI;
            }
            let i = (q * n_ct as f64) as usize;
            let j = ((phi / (2.0 * std::f64::consts::PI)) * n_phi as f64) as usize % n_phi;
            counts[i * n_phi + j] += 1.0;
        }
        let mut expected = vec![0f64; n_ct * n_phi];
        let sub = 8;
        for i in 0..n_ct {
            for j in 0..n_phi {
                let mut acc = 0.0;
                for a in 0..sub {
                    for b in 0..sub {
                        let q = (i as f64 + (a as f64 + 0.5) / sub as f64) / n_ct as f64;
                        let tq = (q * std::f64::consts::FRAC_PI_2).tan();
                        let theta = (alpha * tq).atan();
                        let dtheta_dq = alpha * std::f64::consts::FRAC_PI_2 * (1.0 + tq * tq)
                            / (1.0 + alpha * alpha * tq * tq);
                        let ct = theta.cos();
                        let phi = (j as f64 + (b as f64 + 0.5) / sub as f64) / n_phi as f64
                            * 2.0
                            * std::f64::consts::PI;
                        let st = (1.0 - ct * ct).sqrt();
                        let h = Vec3::new(st * phi.cos(), st * phi.sin(), ct);
                        acc += vndf_pdf(wv, h, alpha) * st * dtheta_dq;
                    }
                }
                let area = (1.0 / n_ct as f64) * (2.0 * std::f64::consts::PI / n_phi as f64);
                expected[i * n_phi + j] = acc / (sub * sub) as f64 * area * n as f64;
            }
        }
        assert_counts_follow(
            &counts,
            &expected,
            n,
            &format!("alpha {alpha}, θi {theta_i}"),
        );
    }
}

#[test]
fn sampled_weight_matches_integrated_bsdf() {
    let n_vec = Vec3::new(0.0, 0.0, 1.0);
    for &(alpha, theta_i, c2, z2) in &[
        (0.3f64, 0.4f64, 1800.0f64, 2.5f64),
        (0.5, 1.0, 1300.0, 1.0),
        (0.2, 0.2, 1300.0, 1.99),
    ] {
        let iface = Interface {
            c1: 1540.0,
            c2,
            z1: 1.54,
            z2,
            alpha,
            planar: false,
        };
        let wi = Vec3::new(theta_i.sin(), 0.0, theta_i.cos());
        // Monte Carlo: mean weight and its standard error.
        let n = 200_000usize;
        let (mean, se) = mean_split_weight(&iface, wi, n_vec, n);
        // Quadrature of ∫ f(wi, wo)|wo·n| dwo over the sphere: midpoint rule in
        // (cos θo, φo), refined near the specular directions by a fine grid.
        let (n_c, n_p) = (1600, 720);
        let mut integral = 0.0;
        for a in 0..n_c {
            let ct = -1.0 + 2.0 * (a as f64 + 0.5) / n_c as f64;
            let st = (1.0 - ct * ct).sqrt();
            for b in 0..n_p {
                let phi = (b as f64 + 0.5) / n_p as f64 * 2.0 * std::f64::consts::PI;
                let wo = Vec3::new(st * phi.cos(), st * phi.sin(), ct);
                integral += iface.eval(wi, wo, n_vec);
            }
        }
        integral *= (2.0 / n_c as f64) * (2.0 * std::f64::consts::PI / n_p as f64);
        eprintln!(
            "alpha {alpha}, θi {theta_i}, c2 {c2}, Z2 {z2}: MC {mean:.5} ± {se:.5}, quadrature {integral:.5}"
        );
        // Allowance for the quadrature error of the midpoint rule: 0.5 % of the value.
        let tol = 4.0 * se + 5e-3 * integral.abs();
        assert!(
            (mean - integral).abs() < tol,
            "MC {mean} vs quadrature {integral}"
        );
    }
}

/// Random unit vector from dimensions `d`, `d + 1` of `s`; in the `xz` plane
/// (from dimension `d` alone) when `planar`.
fn unit(s: &PathSampler, d: u32, planar: bool) -> Vec3<f64> {
    if planar {
        let a = 2.0 * std::f64::consts::PI * s.uniform(0, d);
        return Vec3::new(a.sin(), 0.0, a.cos());
    }
    let z = 2.0 * s.uniform(0, d) - 1.0;
    let phi = 2.0 * std::f64::consts::PI * s.uniform(0, d + 1);
    let r = (1.0 - z * z).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

#[test]
fn eval_pdf_agrees_with_eval_and_pdf() {
    // Reflection and transmission directions around tilted normals, for media
    // faster and slower than the incident one (the slower one has TIR lobes),
    // in 3-D and in the plane (the 2-D model of `ggx_planar`).
    for planar in [false, true] {
        let mut checked = [0usize; 2];
        for &(alpha, c2, z2) in &[(0.25f64, 1600.0f64, 1.75f64), (0.6, 1300.0, 1.2)] {
            let iface = Interface {
                c1: 1540.0,
                c2,
                z1: 1.54,
                z2,
                alpha,
                planar,
            };
            for k in 0..4000u32 {
                let s = PathSampler::new(3, 0, 0, k);
                let (mut n, wi, wo) = (
                    unit(&s, 0, planar),
                    unit(&s, 2, planar),
                    unit(&s, 4, planar),
                );
                if wi.dot(n) < 0.0 {
                    n = -n;
                }
                let (v, p) = iface.eval_pdf(wi, wo, n);
                let (v0, p0) = (iface.eval(wi, wo, n), iface.pdf(wi, wo, n));
                let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(b.abs());
                assert!(close(v, v0), "eval {v} vs {v0} at {wi:?} {wo:?} {n:?}");
                assert!(close(p, p0), "pdf {p} vs {p0} at {wi:?} {wo:?} {n:?}");
                if v0 != 0.0 {
                    checked[usize::from(wo.dot(n) < 0.0)] += 1;
                }
            }
        }
        assert!(
            checked.iter().all(|&c| c > 100),
            "planar {planar}: cases {checked:?}"
        );
    }
}

#[test]
fn eval_pdf_derivatives_agree_with_eval_and_pdf() {
    // The same in forward-mode AD: partials with respect to the roughness, the
    // other medium's speed and a tilt of the normal (about x in 3-D, about y
    // in the plane) agree with those of `eval` and of the (frame-based) `pdf`,
    // which the MIS weights differentiate.
    type D = Dual<3>;
    for planar in [false, true] {
        let mut checked = [0usize; 2];
        for &(alpha, c2, z2) in &[(0.25f64, 1600.0f64, 1.75f64), (0.6, 1300.0, 1.2)] {
            let iface = Interface {
                c1: D::constant(1540.0),
                c2: D::variable(c2, 1),
                z1: D::constant(1.54),
                z2: D::constant(z2),
                alpha: D::variable(alpha, 0),
                planar,
            };
            for k in 0..2000u32 {
                let s = PathSampler::new(4, 0, 0, k);
                let (mut n, wi, wo) = (
                    unit(&s, 0, planar),
                    unit(&s, 2, planar),
                    unit(&s, 4, planar),
                );
                if wi.dot(n) < 0.0 {
                    n = -n;
                }
                let lift =
                    |v: Vec3<f64>| Vec3::new(D::constant(v.x), D::constant(v.y), D::constant(v.z));
                // Tilt the normal by a variable angle (0 at the point).
                let tilt = D::variable(0.0, 2);
                let (c, sn) = (tilt.cos(), tilt.sin());
                let nl = lift(n);
                let n_d = if planar {
                    Vec3::new(nl.x * c + nl.z * sn, nl.y, nl.z * c - nl.x * sn)
                } else {
                    Vec3::new(nl.x, nl.y * c - nl.z * sn, nl.y * sn + nl.z * c)
                };
                let (wi_d, wo_d) = (lift(wi), lift(wo));
                let (v, p) = iface.eval_pdf(wi_d, wo_d, n_d);
                let (v0, p0) = (iface.eval(wi_d, wo_d, n_d), iface.pdf(wi_d, wo_d, n_d));
                let close = |a: D, b: D| {
                    let scale = a.re.abs().max(b.re.abs());
                    (a.re - b.re).abs() <= 1e-12 * scale
                        && a.eps
                            .iter()
                            .zip(&b.eps)
                            .all(|(x, y)| (x - y).abs() <= 1e-9 * x.abs().max(y.abs()).max(scale))
                };
                assert!(close(v, v0), "eval {v:?} vs {v0:?} at {wi:?} {wo:?} {n:?}");
                assert!(close(p, p0), "pdf {p:?} vs {p0:?} at {wi:?} {wo:?} {n:?}");
                if v0.re != 0.0 && p0.eps[0] != 0.0 && p0.eps[2] != 0.0 {
                    checked[usize::from(wo.dot(n) < 0.0)] += 1;
                }
            }
        }
        assert!(
            checked.iter().all(|&c| c > 50),
            "planar {planar}: cases {checked:?}"
        );
    }
}
