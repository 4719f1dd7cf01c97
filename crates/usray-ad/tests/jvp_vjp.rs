//! The dot-product identity between forward-mode JVPs and reverse-mode VJPs on
//! random vector functions: ⟨J v, w⟩ = ⟨v, Jᵀ w⟩.

mod common;

use common::{eval, point, tree, Trees, NVARS};
use proptest::prelude::*;
use usray_ad::helpers::{jvp, vjp};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// `f: ℝ³ → ℝᵐ` (m = 1…4 random trees), random `v ∈ ℝ³`, `w ∈ ℝᵐ`.
    ///
    /// Both sides are sums of the same products `wᵢ·Jᵢⱼ·vⱼ`, with each `Jᵢⱼ`
    /// rounded differently (forward vs reverse association), so they differ by
    /// rounding relative to `Σ|wᵢ Jᵢⱼ vⱼ|`; bounded here by
    /// `1e-12·(Σᵢ|(Jv)ᵢ wᵢ| + Σⱼ|vⱼ (Jᵀw)ⱼ|) + 1e-300`.
    #[test]
    fn dot_product_identity(
        fs in prop::collection::vec(tree(), 1..5),
        x in point(),
        v in prop::collection::vec(-1.0..1.0f64, NVARS),
        w in prop::collection::vec(-1.0..1.0f64, 4),
    ) {
        let m = fs.len();
        prop_assume!(fs.iter().all(|e| eval(e, &x).is_finite()));
        let w = &w[..m];
        let f = Trees(fs);
        let (mut y1, mut jv) = (vec![0.0; m], vec![0.0; m]);
        let (mut y2, mut wj) = (vec![0.0; m], vec![0.0; NVARS]);
        jvp(&f, &x, &v, &mut y1, &mut jv);
        vjp(&f, &x, w, &mut y2, &mut wj);
        // Same values from both modes, and equal to plain f64 evaluation.
        for i in 0..m {
            prop_assert_eq!(y1[i].to_bits(), y2[i].to_bits());
            prop_assert_eq!(y1[i].to_bits(), eval(&f.0[i], &x).to_bits());
        }
        let lhs: f64 = jv.iter().zip(w).map(|(a, b)| a * b).sum();
        let rhs: f64 = v.iter().zip(&wj).map(|(a, b)| a * b).sum();
        let scale: f64 = jv.iter().zip(w).map(|(a, b)| (a * b).abs()).sum::<f64>()
            + v.iter().zip(&wj).map(|(a, b)| (a * b).abs()).sum::<f64>();
        prop_assert!((lhs - rhs).abs() <= 1e-12 * scale + 1e-300,
            "<Jv,w> = {} but <v,J^T w> = {}", lhs, rhs);
    }
}

/// The identity must be able to fail: a VJP with the wrong weights breaks it.
#[test]
fn identity_detects_a_wrong_vjp() {
    use usray_ad::helpers::VectorFn;
    use usray_ad::Real;
    struct F;
    impl VectorFn for F {
        fn eval<T: Real>(&self, x: &[T], out: &mut [T]) {
            out[0] = x[0] * x[1].sin();
            out[1] = x[0].exp() + x[1];
        }
    }
    let (x, v, w) = ([0.3, 1.1], [1.0, -2.0], [0.5, 2.0]);
    let (mut y, mut jv, mut wj) = ([0.0; 2], [0.0; 2], [0.0; 2]);
    jvp(&F, &x, &v, &mut y, &mut jv);
    vjp(&F, &x, &[w[1], w[0]], &mut y, &mut wj); // weights swapped
    let lhs = jv[0] * w[0] + jv[1] * w[1];
    let rhs = v[0] * wj[0] + v[1] * wj[1];
    assert!((lhs - rhs).abs() > 1e-3);
    vjp(&F, &x, &w, &mut y, &mut wj);
    let rhs = v[0] * wj[0] + v[1] * wj[1];
    assert!((lhs - rhs).abs() < 1e-14);
}
