//! The spectral down-shift of attenuated echoes.
//!
//! # Physics
//! A frequency-linear attenuation `α(f) = α₀·f` (Szabo, *Diagnostic Ultrasound
//! Imaging*, §4.2) multiplies an echo's spectrum by `e^{−β f}`, where
//! `β = Σ_i α_i d_i` (Np/Hz) sums the attenuation exponent over the path's
//! segments ([`crate::effects::attenuation_exponent`]). For the Gaussian pulse
//! of `usray_signal::pulse` (amplitude spectrum `E(f − f_c)`, standard
//! deviation `σ_f`, [`usray_signal::pulse::pulse_bandwidth_hz`]), completing
//! the square gives (Kuc, *IEEE Trans. Sonics Ultrason.* 31, 1984)
//!
//! `E(f − f_c)·e^{−βf} = e^{−βf_c + β²σ_f²/2}·E(f − (f_c − βσ_f²))`:
//!
//! the echo is the same pulse, envelope unchanged, with its carrier moved down
//! by `βσ_f²` and its amplitude scaled by `e^{−βf_c}` (the path's attenuation
//! at `f_c`, [`crate::effects::attenuation`]) times `e^{β²σ_f²/2}`. (The
//! negative-frequency half is neglected, `e^{−(f_c/σ_f)²/2}` = 10⁻¹⁴ for 3
//! cycles; so is the dispersion that causality ties to the attenuation.) A
//! deposit carries its shift `x = −βσ_f` in spectral standard deviations
//! ([`crate::integrator::Deposit::shift`]) and the factor `e^{x²/2}` in its
//! amplitude.
//!
//! # Rendering a different carrier per deposit
//! The records are convolved with the pulse once, not deposit by deposit, so
//! the pulse of carrier `s = −x ≥ 0` is written on a fixed grid of **nodes**
//! `s_k = k·h` ([`NODE_SPACING`] `h`) by cubic Hermite interpolation between
//! the two nodes around it, from each node's pulse `V_k` and its derivative
//! `D_k = ∂V/∂s` ([`usray_signal::pulse::shifted_pulse`], `…_ds`):
//!
//! `p(s) ≈ H₀₀(u)V_j + h H₁₀(u)D_j + H₀₁(u)V_{j+1} + h H₁₁(u)D_{j+1}`,
//! `j = ⌊s/h⌋`, `u = s/h − j`.
//!
//! A deposit is splatted into the four records of those terms with those
//! weights ([`basis`]); each record is convolved with its own taps
//! ([`node_taps`]). At `h = 0.5` the relative error of the interpolated pulse
//! is below 5·10⁻⁴ over `s ∈ [0, 1.5]` (unit test). The interpolant is `C¹` in
//! `s`, and exact with its derivative at `s = 0`, so the derivative of the data
//! with respect to an attenuation at its null value is that of the true pulse.
//! A scene without attenuation uses one record and the unshifted pulse: its
//! data are those of the renderer without this module, bit for bit.

use usray_ad::Real;

/// Spacing `h` of the nodes, in spectral standard deviations `σ_f`.
pub const NODE_SPACING: f64 = 0.5;

/// The number of nodes a render needs: 1 without attenuation (the plain
/// pulse) and, with it, enough to cover the largest shift any deposit inside
/// the records can have, at least 2. `alpha_max` (dB/(cm·MHz)) and `c_max`
/// (m/s) are the largest attenuation and sound speed of the scene's media,
/// `t_end` (s) the records' end plus the largest transmit delay, `fc` (Hz)
/// and `cycles` the pulse's ([`crate::plan::PulsePlan::nodes`] adds the
/// second node a differentiated attenuation needs at `α = 0`).
///
/// The bound: a deposit inside the records has travelled at most
/// `L = c_max·t_end` (the transmit delays are at least `−max|x_e sin θ|/c`),
/// so `β ≤ α_max·L` and `s = βσ_f ≤ α_max·L·σ_f`. It is capped at
/// [`max_shift`], where the model stops being valid; larger shifts are placed
/// at the cap ([`basis`]), so that an extreme attenuation cannot ask for an
/// unbounded number of records.
///
/// ```
/// use usray_transport::downshift::node_count;
/// assert_eq!(node_count(0.0, 1570.0, 50e-6, 5e6, 3.0), 1);
/// assert!(node_count(1.0, 1570.0, 50e-6, 5e6, 3.0) >= 2);
/// // 100 dB/(cm·MHz): capped at a shift of f_c/2 (4 σ_f for 3 cycles).
/// assert_eq!(node_count(100.0, 1570.0, 50e-6, 5e6, 3.0), 10);
/// ```
pub fn node_count(alpha_max: f64, c_max: f64, t_end: f64, fc: f64, cycles: f64) -> usize {
    if alpha_max <= 0.0 || !alpha_max.is_finite() {
        return 1;
    }
    let beta_max = crate::effects::attenuation_exponent(alpha_max, c_max * t_end);
    let s_max = beta_max * usray_signal::pulse::pulse_bandwidth_hz(fc, cycles);
    let s_max = s_max.min(max_shift(fc, cycles));
    if !s_max.is_finite() {
        return 2;
    }
    ((s_max / NODE_SPACING).floor() as usize + 2).max(2)
}

/// The largest shift the renderer places, in `σ_f`: the carrier down to
/// `f_c/2`, i.e. `s = f_c/(2σ_f)` (4.0 for 3 cycles). Beyond it the neglected
/// negative-frequency half of the spectrum matters and the closed form no
/// longer holds; for 3 cycles an echo shifted that far is also attenuated by
/// `e^{−βf_c + s²/2}` = `e^{−24}` at least. A deposit beyond it gets the
/// shift and the amplitude factor `e^{s²/2}` of the cap
/// (`Deposit::shift`), so the factor cannot overflow.
///
/// ```
/// use usray_transport::downshift::max_shift;
/// assert!((max_shift(5e6, 3.0) - 4.002).abs() < 1e-3);
/// ```
pub fn max_shift(fc: f64, cycles: f64) -> f64 {
    fc / (2.0 * usray_signal::pulse::pulse_bandwidth_hz(fc, cycles))
}

/// The taps of the `2·n_nodes` records: `[V_0, D_0, V_1, D_1, …]`, each
/// sampled like `usray_signal::pulse::pulse_taps` (same length; `V_0` is the
/// plain pulse, bit for bit).
///
/// ```
/// use usray_transport::downshift::node_taps;
/// let t = node_taps(40e6, 5e6, 3.0, 2);
/// assert_eq!(t.len(), 4);
/// assert_eq!(t[0], usray_signal::pulse::pulse_taps(40e6, 5e6, 3.0));
/// ```
pub fn node_taps(fs: f64, fc: f64, cycles: f64, n_nodes: usize) -> Vec<Vec<f64>> {
    node_taps_with(fs, fc, cycles, n_nodes, |t, s, slope| {
        if slope {
            usray_signal::pulse::shifted_pulse_ds(t, fc, cycles, s)
        } else {
            usray_signal::pulse::shifted_pulse(t, fc, cycles, s)
        }
    })
}

/// [`node_taps`] with each tap given by `eval(t, s_k, is_slope)` (the
/// gradient evaluates them in a dual number for the pulse-shape derivatives).
pub fn node_taps_with<V>(
    fs: f64,
    fc: f64,
    cycles: f64,
    n_nodes: usize,
    mut eval: impl FnMut(f64, f64, bool) -> V,
) -> Vec<Vec<V>> {
    let k = (usray_signal::pulse::pulse_support_s(fc, cycles) * fs).ceil() as i64;
    let mut out = Vec::with_capacity(2 * n_nodes);
    for node in 0..n_nodes {
        let s = node as f64 * NODE_SPACING;
        for slope in [false, true] {
            out.push((-k..=k).map(|i| eval(i as f64 / fs, s, slope)).collect());
        }
    }
    out
}

/// The Hermite weights of a deposit of shift `x` (≤ 0, in `σ_f`) on a grid of
/// `n_nodes ≥ 2` nodes: four `(record index, weight)` pairs, record `2k` the
/// value `V_k` and `2k + 1` the slope `D_k` (module docs). Shifts beyond the
/// last node (which [`node_count`] rules out inside the records) are clamped
/// to it.
///
/// ```
/// use usray_transport::downshift::basis;
/// // On a node (s = 0.5: node 1): its own pulse alone, record 2.
/// let w = basis(-0.5_f64, 3);
/// assert_eq!(w.iter().map(|p| p.1).collect::<Vec<_>>(), vec![1.0, 0.0, 0.0, 0.0]);
/// assert_eq!(w[0].0, 2);
/// // The values' weights form a partition of unity.
/// let w = basis(-0.3_f64, 3);
/// assert!((w[0].1 + w[2].1 - 1.0).abs() < 1e-15);
/// ```
pub fn basis<T: Real>(x: T, n_nodes: usize) -> [(usize, T); 4] {
    let last = (n_nodes.max(2) - 1) as f64;
    let s = (-x).scale(1.0 / NODE_SPACING);
    let sv = s.value();
    let (j, u) = if sv.is_nan() || sv <= 0.0 {
        (0.0, s)
    } else if sv >= last {
        (last - 1.0, T::one())
    } else {
        let j = sv.floor().min(last - 1.0);
        (j, s - T::from_f64(j))
    };
    let j = j as usize;
    let (u2, u3) = (u * u, u * u * u);
    let (two, three) = (T::from_f64(2.0), T::from_f64(3.0));
    let h00 = two * u3 - three * u2 + T::one();
    let h10 = u3 - two * u2 + u;
    let h01 = three * u2 - two * u3;
    let h11 = u3 - u2;
    [
        (2 * j, h00),
        (2 * j + 1, h10.scale(NODE_SPACING)),
        (2 * j + 2, h01),
        (2 * j + 3, h11.scale(NODE_SPACING)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use usray_signal::pulse::{pulse_taps, shifted_pulse};

    /// The interpolated pulse against the exact shifted pulse over
    /// `s ∈ [0, 1.5]`: relative L2 error below 5·10⁻⁴ (the cubic Hermite
    /// error bound `h⁴/384·max|∂⁴p/∂s⁴|` with `|∂⁴p/∂s⁴| ≲ (2πσ_f t)⁴` over
    /// the envelope gives ≈ 3·10⁻⁴ at `h = 0.5`).
    #[test]
    fn hermite_pulse_matches_the_shifted_pulse() {
        let (fs, fc, cycles) = (40e6, 5e6, 3.0);
        let taps = node_taps(fs, fc, cycles, 5);
        let k = (taps[0].len() / 2) as i64;
        let mut worst = 0.0_f64;
        for i in 0..=150 {
            let s = i as f64 * 0.01;
            let w = basis(-s, 5);
            let (mut err, mut norm) = (0.0, 0.0);
            for (n, tap) in (-k..=k).enumerate() {
                let exact = shifted_pulse(tap as f64 / fs, fc, cycles, s);
                let approx: f64 = w.iter().map(|(b, c)| c * taps[*b][n]).sum();
                err += (approx - exact).powi(2);
                norm += exact * exact;
            }
            worst = worst.max((err / norm).sqrt());
        }
        assert!(worst < 5e-4, "worst relative error {worst}");
        assert_eq!(taps[0], pulse_taps(fs, fc, cycles));
    }

    /// `∂p/∂s` of the interpolant at `s = 0` is the exact `D_0`: the weights'
    /// derivatives there are `(0, 1, 0, 0)` per unit `s`.
    #[test]
    fn basis_slope_at_the_null_is_exact() {
        use usray_ad::Dual;
        let w = basis(Dual::<1>::variable(0.0, 0), 3);
        // x = −s: ∂/∂s = −∂/∂x.
        let d: Vec<f64> = w.iter().map(|(_, c)| -c.eps[0]).collect();
        assert_eq!(d, vec![0.0, 1.0, 0.0, 0.0]);
        let v: Vec<f64> = w.iter().map(|(_, c)| c.re).collect();
        assert_eq!(v, vec![1.0, 0.0, 0.0, 0.0]);
    }
}
