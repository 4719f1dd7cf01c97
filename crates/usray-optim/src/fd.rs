//! Finite-difference checks next to AD gradients (paper figure "FD and AD vs ε").

/// One central finite difference `(f(x + ε e_j) − f(x − ε e_j)) / 2ε`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FdPoint {
    /// The step `ε`, in the parameter's own unit.
    pub eps: f64,
    /// The finite-difference estimate of `∂f/∂x_j`.
    pub fd: f64,
}

/// Central differences of `f` along coordinate `j` at `x` for each step in `steps`.
///
/// Truncation error is `O(ε² f''')`, round-off `O(δ_f / ε)` where `δ_f` is the noise
/// in `f` (machine precision, or Monte Carlo noise when seeds differ — with common
/// random numbers it is only round-off), so the sweep shows a valley at the best ε.
///
/// ```
/// use usray_optim::fd_sweep;
/// let sweep = fd_sweep(|x: &[f64]| x[0].powi(3), &[2.0], 0, &[1e-2, 1e-4]);
/// assert!((sweep[1].fd - 12.0).abs() < 1e-6);
/// ```
pub fn fd_sweep(
    mut f: impl FnMut(&[f64]) -> f64,
    x: &[f64],
    j: usize,
    steps: &[f64],
) -> Vec<FdPoint> {
    let mut xp = x.to_vec();
    steps
        .iter()
        .map(|&eps| {
            xp[j] = x[j] + eps;
            let fp = f(&xp);
            xp[j] = x[j] - eps;
            let fm = f(&xp);
            xp[j] = x[j];
            FdPoint {
                eps,
                fd: (fp - fm) / (2.0 * eps),
            }
        })
        .collect()
}

/// `n` steps spaced logarithmically from `largest` down by factors of `ratio`.
///
/// ```
/// assert_eq!(usray_optim::log_steps(1e-2, 10.0, 3), vec![1e-2, 1e-3, 1e-4]);
/// ```
pub fn log_steps(largest: f64, ratio: f64, n: usize) -> Vec<f64> {
    let mut v = Vec::with_capacity(n);
    let mut e = largest;
    for _ in 0..n {
        v.push(e);
        e /= ratio;
    }
    v
}
