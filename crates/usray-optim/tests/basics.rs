//! Tests of the optimisation building blocks against independent computations.

use usray_optim::{fd_sweep, Adam, AdamGroup, ParamMap, ParamSpec, ParamSpecError, L1L2};
use usray_transport::Scene;

/// The shipped cylinder scene (parameter paths are checked against it).
fn cylinder() -> Scene {
    Scene::from_toml_str(
        include_str!("../../../scenes/cylinder.toml"),
        "cylinder.toml",
        ".",
    )
    .unwrap()
}

/// Deterministic pseudo-random numbers for test data (SplitMix64).
fn rand_vec(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

#[test]
fn loss_gradient_matches_central_differences_away_from_kinks() {
    let loss = L1L2 {
        lambda1: 0.7,
        lambda2: 1.3,
    };
    let img = rand_vec(1, 64);
    let reference = rand_vec(2, 64);
    let mut grad = vec![0.0; 64];
    loss.value_and_gradient(&img, &reference, &mut grad);
    for u in 0..64 {
        // The ℓ1 kink is at I = R; a step smaller than the distance to it keeps the
        // central difference exact up to round-off (the loss is quadratic there).
        let h = 0.25 * (img[u] - reference[u]).abs().min(1e-3);
        let fd = fd_sweep(|x| loss.value(x, &reference), &img, u, &[h])[0].fd;
        // Round-off bound: |L| ≈ 1, ε_mach·|L|/h.
        let tol = 1e-14 / h + 1e-12;
        assert!(
            (fd - grad[u]).abs() < tol,
            "pixel {u}: fd {fd} vs {}",
            grad[u]
        );
    }
}

#[test]
fn loss_is_zero_with_zero_gradient_at_a_perfect_match() {
    let img = rand_vec(3, 16);
    let mut grad = vec![1.0; 16];
    assert_eq!(
        L1L2::default().value_and_gradient(&img, &img, &mut grad),
        0.0
    );
    assert!(grad.iter().all(|&g| g == 0.0));
}

#[test]
fn map_chain_rule_matches_finite_differences_inside_and_vanishes_outside() {
    let specs = vec![
        ParamSpec::parse("objects.cylinder.radius_m=0.003:0.007", &cylinder()).unwrap(),
        ParamSpec::parse("materials.target.impedance_mrayl=1:3", &cylinder()).unwrap(),
    ];
    let map = ParamMap::new(specs);
    // f(θ) = Σ w_j θ_j² with known ∂f/∂θ.
    let w = [3.0e4, 0.5];
    let f = |state: &[f64]| -> f64 {
        let p = map.physical(state);
        p.iter().zip(w).map(|(x, w)| w * x * x).sum()
    };
    for state in [[0.3, 0.6], [0.9, 0.1]] {
        let p = map.physical(&state);
        let d_phys: Vec<f64> = p.iter().zip(w).map(|(x, w)| 2.0 * w * x).collect();
        let g = map.state_gradient(&state, &d_phys);
        for j in 0..2 {
            let fd = fd_sweep(f, &state, j, &[1e-5])[0].fd;
            assert!(
                (fd - g[j]).abs() < 1e-6 * g[j].abs().max(1.0),
                "{j}: {fd} vs {}",
                g[j]
            );
        }
    }
    // Saturated at or beyond a bound: clipped value and zero gradient (eq. clip_grad).
    let g = map.state_gradient(&[1.0, -0.2], &[1.0, 1.0]);
    assert_eq!(g, vec![0.0, 0.0]);
    assert_eq!(map.physical(&[1.5, -0.2]), vec![0.007, 1.0]);
}

#[test]
fn adam_groups_move_at_their_own_rates_and_clipping_bounds_the_step() {
    let groups = vec![
        AdamGroup {
            learning_rate: 0.1,
            ..Default::default()
        },
        AdamGroup {
            learning_rate: 0.01,
            ..Default::default()
        },
    ];
    let mut adam = Adam::new(groups, vec![0, 1]);
    let mut x = [0.0, 0.0];
    // First Adam step moves each entry by exactly its learning rate (m̂/√v̂ = ±1).
    adam.step(&mut x, &[1.0, 1.0]);
    assert!(
        (x[0] + 0.1).abs() < 1e-9 && (x[1] + 0.01).abs() < 1e-9,
        "{x:?}"
    );

    let mut clipped = Adam::new(vec![AdamGroup::default()], vec![0, 0]);
    clipped.clip_norm = Some(1.0);
    let norm = clipped.step(&mut [0.0, 0.0], &[30.0, 40.0]);
    assert_eq!(norm, 50.0);
}

#[test]
fn adam_minimises_a_badly_scaled_quadratic() {
    // f = 100 (x−1)² + 0.01 (y+2)²: Adam's per-coordinate scaling handles both.
    let mut adam = Adam::new(
        vec![AdamGroup {
            learning_rate: 0.05,
            ..Default::default()
        }],
        vec![0, 0],
    );
    let mut x = [0.0, 0.0];
    for _ in 0..2000 {
        let g = [200.0 * (x[0] - 1.0), 0.02 * (x[1] + 2.0)];
        adam.step(&mut x, &g);
    }
    assert!(
        (x[0] - 1.0).abs() < 1e-2 && (x[1] + 2.0).abs() < 1e-2,
        "{x:?}"
    );
}

#[test]
fn spec_errors_say_what_is_wrong() {
    let s = cylinder();
    assert_eq!(
        ParamSpec::parse("probe.cycles=1", &s),
        Err(ParamSpecError::Syntax("probe.cycles=1".into()))
    );
    assert!(matches!(
        ParamSpec::parse("probe.cycles=x:2", &s),
        Err(ParamSpecError::Bound { .. })
    ));
    assert!(matches!(
        ParamSpec::parse("probe.cycles=2:1", &s),
        Err(ParamSpecError::EmptyRange { .. })
    ));
    assert!(matches!(
        ParamSpec::parse("probe.cycles=NaN:1", &s),
        Err(ParamSpecError::Bound { .. })
    ));
    assert!(matches!(
        ParamSpec::parse("a=1:2", &s),
        Err(ParamSpecError::Unknown { .. })
    ));
    let msg = ParamSpec::parse("probe.cycles=2:1", &s)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("`probe.cycles`") && msg.contains("MIN must be below MAX"),
        "{msg}"
    );
}
