//! Finite-difference checks next to AD gradients (paper figure "FD and AD vs ε").

use crate::objective::Objective;
use crate::params::ParamSpec;
use crate::OptimError;

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

/// The default steps of an FD sweep for a parameter: eight steps from 10⁻² of its
/// range down to 10⁻⁹ of it, spaced by 10. Large steps show the truncation error
/// and the visibility jumps the gradient does not see (rays crossing an edge);
/// small ones the agreement with the fixed-seed derivative, down to round-off.
///
/// ```
/// use usray_optim::{sweep_steps, ParamSpec};
/// use usray_transport::{Field, ParamKey};
/// let spec = ParamSpec { key: ParamKey::object("c", Field::Radius), min: 1e-3, max: 3e-3 };
/// let steps = sweep_steps(&spec);
/// assert_eq!(steps.len(), 8);
/// assert!((steps[0] - 2e-5).abs() < 1e-20 && (steps[7] - 2e-12).abs() < 1e-24);
/// ```
pub fn sweep_steps(spec: &ParamSpec) -> Vec<f64> {
    log_steps(1e-2 * (spec.max - spec.min), 10.0, 8)
}

/// Central finite differences of the fixed-seed objective's loss along each of
/// its parameters at `at` (physical values), over [`sweep_steps`]: one sweep per
/// parameter, in [`Objective::specs`]' order. `tick` is called once per render
/// (two per step), for progress.
///
/// With common random numbers the loss is a deterministic function of the
/// parameters, so the sweeps check the AD gradient of the realisation
/// ([`Objective::value_and_gradient`]) down to round-off, where no ray changes
/// which surface it hits (paper figure "FD and AD vs ε").
///
/// # Errors
/// [`OptimError::FiniteDifference`] naming the parameter whose sweep hit a
/// failing render (e.g. a step outside the scene's valid region).
pub fn fd_sweeps(
    objective: &Objective,
    at: &[f64],
    mut tick: impl FnMut(),
) -> Result<Vec<Vec<FdPoint>>, OptimError> {
    let mut out = Vec::new();
    for (j, spec) in objective.specs.iter().enumerate() {
        let mut err = None;
        let sweep = fd_sweep(
            |x: &[f64]| {
                tick();
                match objective.value(x) {
                    Ok(e) => e.loss,
                    Err(e) => {
                        err.get_or_insert(e);
                        f64::NAN
                    }
                }
            },
            at,
            j,
            &sweep_steps(spec),
        );
        if let Some(e) = err {
            return Err(OptimError::FiniteDifference {
                key: spec.key.clone(),
                source: Box::new(e),
            });
        }
        out.push(sweep);
    }
    Ok(out)
}

/// The FD point of `sweep` closest to the AD value `ad` (the sweep's best step)
/// and its relative difference `|FD − AD| / |AD|`; `None` when no point is
/// finite.
///
/// ```
/// use usray_optim::{best_fd, FdPoint};
/// let sweep = [FdPoint { eps: 1e-2, fd: 2.5 }, FdPoint { eps: 1e-4, fd: 2.001 }];
/// let (p, rel) = best_fd(&sweep, 2.0).unwrap();
/// assert_eq!(p.eps, 1e-4);
/// assert!((rel - 5e-4).abs() < 1e-12);
/// ```
pub fn best_fd(sweep: &[FdPoint], ad: f64) -> Option<(FdPoint, f64)> {
    sweep
        .iter()
        .filter(|p| p.fd.is_finite())
        .min_by(|a, b| (a.fd - ad).abs().total_cmp(&(b.fd - ad).abs()))
        .map(|p| (*p, (p.fd - ad).abs() / ad.abs().max(f64::MIN_POSITIVE)))
}
