//! The transport gradient: `∂L/∂θ_j = Σ d_channels·∂P/∂θ_j` for named scene
//! parameters, without a tape the size of the render (`DESIGN.md`).
//!
//! # Method
//! The channel data is `P = s ⋆ Σ_k a_k·δ_lin(t − τ_k)` (linear splat, then the
//! pulse; [`crate::deposit`]). For `g = d_channels`:
//! 1. Correlate each record with the pulse taps once: `G = g ⋆ s`
//!    (`usray_signal::pulse::convolve_vjp`; `G = g` with
//!    [`RenderOptions::impulse_only`]).
//! 2. Replay every path with the **same random numbers** as the render with the
//!    same `opts` (common random numbers: same seed, same chunks) in an AD scalar.
//!    At each deposit `(e, a, τ)` with splat index `i = ⌊(τ − t0) f_s⌋` and
//!    fraction `f`: `ā = (1−f)·G[i] + f·G[i+1]`, `τ̄ = a·f_s·(G[i+1] − G[i])`
//!    (`G` = 0 outside the record), and accumulate `ā·∂a/∂θ + τ̄·∂τ/∂θ`. This is
//!    exactly the derivative of the forward splat + convolution.
//! 3. Pulse-shape parameters (`probe.center_frequency_hz`, `probe.cycles`) also
//!    change the taps: add `Σ_k a_k·[(1−f)·G'[i] + f·G'[i+1]]` with
//!    `G' = g ⋆ ∂s/∂θ` (derivative taps from `usray_signal::pulse::pulse` in a
//!    dual). `f_c` also enters the attenuation inside the paths, which step 2
//!    covers.
//! 4. With attenuation, a deposit of shift `x` is placed through the
//!    down-shift nodes' records `b` with weights `c_b(x)` ([`crate::downshift`]):
//!    with `G_b = g ⋆ taps_b`, `ā = Σ_b c_b·interp(G_b)(τ)`,
//!    `τ̄ = a·f_s·Σ_b c_b·(G_b[i+1] − G_b[i])` and `x̄ = a·Σ_b c_b'(x)·interp(G_b)(τ)`;
//!    the pulse terms of step 3 are taken per record the same way.
//!
//! # Mode
//! Up to [`REVERSE_MIN_PARAMS`]` − 1` parameters: forward [`Dual`] passes of at
//! most 8 partials each (one replay per pass). From [`REVERSE_MIN_PARAMS`] on:
//! one replay with a per-path reverse [`Recording`] (the scene is lifted once
//! per work chunk onto the tape, reusing meshes and BVHs placed once,
//! [`Scene::lift_with`], and frozen there: every path rewinds the tape to it,
//! [`Recording::freeze`]); the recording lives inside one work chunk, never
//! around a rayon call. Either way the memory is one path's tape plus one
//! gradient vector per chunk: nothing grows with the ray count.
//!
//! # What it is the derivative of
//! The replay differentiates the realization itself (common random numbers):
//! every continuous step of a path is differentiated, sampling included (the
//! microfacet normal is a smooth function of the parameters for fixed uniforms,
//! MIS weights are differentiated), and no step makes a discrete choice whose
//! probability depends on a parameter (interactions split into reflection *and*
//! transmission). Against finite differences of one realization every parameter
//! agrees to < 1e-6 (`tests/gradient_fd.rs`). Since the estimator is unbiased for
//! every parameter value and smooth in it, this derivative is also an unbiased
//! estimate of the derivative of the expected data, up to the one thing not
//! differentiated: visibility changes (a ray starting or ceasing to hit a
//! surface or an element face).
//!
//! # Determinism
//! Chunks are those of the render (transmit, block of [`crate::render::ELEMENT_BLOCK`]
//! emitting elements); each returns its partial gradient, and partials are summed
//! in chunk order. The result is bit-identical for any thread count.

use crate::integrator::{Deposit, Horizon, Responses, TraceSettings};
use crate::plan::{AcquisitionPlan, SampleGrid};
use crate::render::{element_blocks, in_pool, settings, trace_block_within, RenderOptions};
use crate::scene::{Field, Owner, ParamKey, Scene, SceneError, SceneT};
use rayon::prelude::*;
use usray_ad::{Dual, Real, Recording, Var};

/// From this many parameters on, [`channel_gradient`] uses per-path reverse mode
/// (below: forward duals, `⌈P/8⌉` replays). Measured crossover: see
/// `docs/performance.md`, section *usray-transport*.
pub const REVERSE_MIN_PARAMS: usize = 12;

/// `∂L/∂θ_j = Σ d_channels·∂P/∂θ_j` for each parameter in `params`, for the render of
/// `scene` with `opts` (same seed ⇒ the same random numbers: see the module
/// docs). `d_channels` is in `ChannelData::samples` layout (`[tx, el, sample]`).
/// Parameters the transport does not depend on (imaging keys, …) get 0.
///
/// Errors: a parameter the scene lacks (named by its path), or `d_channels`
/// of the wrong length.
///
/// ```
/// # let text = include_str!("../../../scenes/cylinder.toml");
/// # let scene = usray_transport::Scene::from_toml_str(text, "cylinder.toml", ".").unwrap();
/// use usray_transport::{channel_gradient, render, Field, ParamKey, RenderOptions};
/// let opts = RenderOptions { rays_per_element: Some(2), ..Default::default() };
/// let (data, _) = render(&scene, &opts).unwrap();
/// // L = ½‖P‖²: dL/dP = P.
/// let radius = ParamKey::object("cylinder", Field::Radius);
/// let g = channel_gradient(&scene, &[radius], &data.samples, &opts).unwrap();
/// assert!(g[0].is_finite() && g[0] != 0.0);
/// let nope = ParamKey::object("nope", Field::Radius);
/// assert!(channel_gradient(&scene, &[nope], &data.samples, &opts).is_err());
/// ```
pub fn channel_gradient(
    scene: &Scene,
    params: &[ParamKey],
    d_channels: &[f64],
    opts: &RenderOptions,
) -> Result<Vec<f64>, SceneError> {
    for p in params {
        scene.get(p)?;
    }
    let plan = AcquisitionPlan::new(scene);
    let n_samples = plan.grid.n_samples;
    let n_el = plan.elements.len();
    let n_tx = plan.transmits.len();
    let expected = plan.channel_len();
    if d_channels.len() != expected {
        return Err(SceneError::new(
            &scene.source,
            "d_channels",
            format!(
                "expected {expected} values ({n_tx} transmits × {n_el} elements × {n_samples} samples), found {}",
                d_channels.len()
            ),
        ));
    }
    if params.is_empty() {
        return Ok(Vec::new());
    }
    let fs = plan.grid.fs_hz;
    // Step 1: G_b = g ⋆ taps_b for the render's records `b` (the pulse, or the
    // down-shift nodes' records), each followed by g ⋆ ∂taps_b/∂f_c and
    // g ⋆ ∂taps_b/∂cycles when either is asked for.
    let want_pulse = params.iter().any(|p| pulse_term(p).is_some());
    let differentiated = params.iter().any(ParamKey::is_attenuation);
    let nodes = if opts.impulse_only {
        1
    } else {
        plan.pulse.nodes(differentiated)
    };
    let taps = (!opts.impulse_only).then(|| {
        let values = plan.pulse.taps(fs, nodes);
        if !want_pulse {
            return values;
        }
        let mut all = Vec::with_capacity(3 * values.len());
        for (v, d) in values
            .into_iter()
            .zip(plan.pulse.shape_derivative_taps(fs, nodes))
        {
            all.push(v);
            all.extend(d);
        }
        all
    });
    let adj = Adjoint::new(d_channels, taps.as_deref(), nodes, opts.threads, &plan.grid);
    let s = settings(scene, opts);
    let mut grad = vec![0.0; params.len()];
    if params.len() >= REVERSE_MIN_PARAMS {
        reverse_pass(scene, &plan, params, &adj, &s, opts, &mut grad)?;
    } else {
        for (pass, group) in params.chunks(8).enumerate() {
            let out = &mut grad[pass * 8..pass * 8 + group.len()];
            match group.len() {
                1 => dual_pass::<1>(scene, &plan, group, &adj, &s, opts, out)?,
                2 => dual_pass::<2>(scene, &plan, group, &adj, &s, opts, out)?,
                3 => dual_pass::<3>(scene, &plan, group, &adj, &s, opts, out)?,
                4 => dual_pass::<4>(scene, &plan, group, &adj, &s, opts, out)?,
                5 => dual_pass::<5>(scene, &plan, group, &adj, &s, opts, out)?,
                6 => dual_pass::<6>(scene, &plan, group, &adj, &s, opts, out)?,
                7 => dual_pass::<7>(scene, &plan, group, &adj, &s, opts, out)?,
                _ => dual_pass::<8>(scene, &plan, group, &adj, &s, opts, out)?,
            }
        }
    }
    Ok(grad)
}

/// The adjoint records and the sample grid.
struct Adjoint {
    /// Per sample of the channel layout, `stride` values: for each of the
    /// render's records `b` (one, or two per down-shift node), `G_b = g ⋆ s_b`,
    /// then `[g ⋆ ∂s_b/∂f_c, g ⋆ ∂s_b/∂cycles]` when a pulse-shape parameter is
    /// asked for. Interleaved so that the look-ups of one deposit share cache
    /// lines (the records a path deposits into are megabytes apart).
    g: Vec<f64>,
    /// Values per sample in `g`: `per_record` times the number of records.
    stride: usize,
    /// Values per record: 1, or 3 with the pulse terms.
    per_record: usize,
    /// Down-shift nodes (`crate::downshift::node_count`); 1 = the plain pulse.
    nodes: usize,
    n_samples: usize,
    t0: f64,
    fs: f64,
}

/// A deposit awaiting its adjoint weights: offset of its record in channel
/// layout, its amplitude, time and shift values, and the derivative carrier `P`.
type Pending<P> = (usize, f64, f64, f64, P);

impl Adjoint {
    /// The records `g ⋆ t` of `d_channels = g` for each `t` of `taps` (the
    /// pulse first, then the pulse-term derivative taps if any), interleaved
    /// per sample, computed record by record on `threads` (no full-size
    /// intermediate); `None` (impulse-only data): `G = g`.
    fn new(
        d_channels: &[f64],
        taps: Option<&[Vec<f64>]>,
        nodes: usize,
        threads: Option<usize>,
        grid: &SampleGrid,
    ) -> Self {
        let (n_samples, t0, fs) = (grid.n_samples, grid.t0_s, grid.fs_hz);
        let (g, stride) = match taps {
            None => (d_channels.to_vec(), 1),
            Some(taps) => {
                let stride = taps.len();
                let mut g = vec![0.0; d_channels.len() * stride];
                in_pool(threads, || {
                    g.par_chunks_mut(n_samples * stride)
                        .zip(d_channels.par_chunks(n_samples))
                        .for_each_init(
                            || vec![0.0; n_samples],
                            |x, (out, y)| {
                                // Each correlation of the record, then its values
                                // into every `stride`-th slot.
                                for (m, t) in taps.iter().enumerate() {
                                    usray_signal::pulse::convolve_vjp(y, t, x);
                                    for (o, &v) in out[m..].iter_mut().step_by(stride).zip(x.iter())
                                    {
                                        *o = v;
                                    }
                                }
                            },
                        );
                });
                (g, stride)
            }
        };
        let records = if nodes == 1 { 1 } else { 2 * nodes };
        Self {
            g,
            stride,
            per_record: (stride / records).max(1),
            nodes,
            n_samples,
            t0,
            fs,
        }
    }

    /// Number of pulse terms (the length of a `pulse_acc`).
    fn n_pulse(&self) -> usize {
        self.per_record - 1
    }

    /// For a deposit of value `a` at time value `tau` with shift `x` on record
    /// `rec` (offset of the record in channel layout): `(ā, τ̄, x̄)` and the
    /// pulse terms `a·Σ_b c_b·interp(G'_{b,m})(τ)` added into `pulse_acc`
    /// (module docs, steps 2–4). `None` when the splat drops it.
    #[inline]
    fn weights(
        &self,
        rec: usize,
        a: f64,
        tau: f64,
        x: f64,
        pulse_acc: &mut [f64],
    ) -> Option<(f64, f64, f64)> {
        // Same arithmetic as `deposit::splat` on values.
        let s = (tau - self.t0) * self.fs;
        if !s.is_finite() || s <= -1.0 {
            return None;
        }
        let i = s.floor();
        let f = s - i;
        let n = self.n_samples as f64;
        if i >= n {
            return None;
        }
        // Value `m` of sample `k` of the record (0 outside it).
        let at = |m: usize, k: f64| -> f64 {
            if k >= 0.0 && k < n {
                self.g[(rec + k as usize) * self.stride + m]
            } else {
                0.0
            }
        };
        if self.nodes == 1 {
            let (g0, g1) = (at(0, i), at(0, i + 1.0));
            for (m, acc) in pulse_acc.iter_mut().enumerate() {
                *acc += a * ((1.0 - f) * at(m + 1, i) + f * at(m + 1, i + 1.0));
            }
            return Some(((1.0 - f) * g0 + f * g1, a * self.fs * (g1 - g0), 0.0));
        }
        // The Hermite weights and their derivatives in x (step 4).
        let basis = crate::downshift::basis(Dual::<1>::variable(x, 0), self.nodes);
        let (mut ab, mut tb, mut xb) = (0.0, 0.0, 0.0);
        for (b, c) in basis {
            let base = b * self.per_record;
            let (g0, g1) = (at(base, i), at(base, i + 1.0));
            let gi = (1.0 - f) * g0 + f * g1;
            ab += c.re * gi;
            tb += c.re * (g1 - g0);
            xb += c.eps[0] * gi;
            for (m, acc) in pulse_acc.iter_mut().enumerate() {
                let k = base + m + 1;
                *acc += a * c.re * ((1.0 - f) * at(k, i) + f * at(k, i + 1.0));
            }
        }
        Some((ab, a * self.fs * tb, a * xb))
    }

    /// Look up the weights of the `pending` deposits, in order, and hand each
    /// kept deposit's carrier and `(ā, τ̄, x̄)` to `use_weights`; `pending` is
    /// emptied. Done in a batch after the deposits were made rather than one
    /// by one inside the tracer, so that the independent look-ups (cache misses
    /// in records megabytes apart) overlap each other.
    fn settle<P>(
        &self,
        pending: &mut Vec<Pending<P>>,
        pulse_acc: &mut [f64],
        mut use_weights: impl FnMut(P, f64, f64, f64),
    ) {
        for (rec, a, tau, x, carrier) in pending.drain(..) {
            if let Some((ab, tb, xb)) = self.weights(rec, a, tau, x, pulse_acc) {
                use_weights(carrier, ab, tb, xb);
            }
        }
    }
}

/// Deposits buffered by a forward pass before [`Adjoint::settle`].
const SETTLE_BATCH: usize = 64;

/// Offset of record `(tx, e)` in channel layout.
#[inline]
fn record_offset(tx: usize, e: u32, n_el: usize, n_samples: usize) -> usize {
    (tx * n_el + e as usize) * n_samples
}

/// Add the pulse-shape terms (`pulse_total = [Σ a·G'_fc(τ), Σ a·G'_cycles(τ)]`)
/// to the gradient of the parameters of `group` that are pulse-shape keys.
fn add_pulse_terms(group: &[ParamKey], pulse_total: &[f64], out: &mut [f64]) {
    if pulse_total.is_empty() {
        return;
    }
    for (o, p) in out.iter_mut().zip(group) {
        if let Some(i) = pulse_term(p) {
            *o += pulse_total[i];
        }
    }
}

/// The index of `key`'s term in the pulse-shape totals: 0 for
/// `probe.center_frequency_hz`, 1 for `probe.cycles`, `None` for a parameter
/// that does not shape the pulse.
fn pulse_term(key: &ParamKey) -> Option<usize> {
    match (&key.owner, key.field) {
        (Owner::Probe, Field::CenterFrequency) => Some(0),
        (Owner::Probe, Field::Cycles) => Some(1),
        _ => None,
    }
}

/// The (transmit, element block) chunks in their fixed order.
fn chunks(n_tx: usize, n_el: usize) -> Vec<(usize, std::ops::Range<usize>)> {
    (0..n_tx)
        .flat_map(|tx| element_blocks(n_el).into_iter().map(move |b| (tx, b)))
        .collect()
}

/// One forward pass with `N` partials (`group`, `group.len() ≤ N`), adding into
/// `out[..group.len()]`.
fn dual_pass<const N: usize>(
    scene: &Scene,
    plan: &AcquisitionPlan,
    group: &[ParamKey],
    adj: &Adjoint,
    s: &TraceSettings,
    opts: &RenderOptions,
    out: &mut [f64],
) -> Result<(), SceneError> {
    let st: SceneT<Dual<N>> = scene.lift(|key, v| match group.iter().position(|q| q == key) {
        Some(i) => Dual::variable(v, i),
        None => Dual::from_f64(v),
    })?;
    let n_el = plan.elements.len();
    let work = chunks(plan.transmits.len(), n_el);
    // Deposits past the records' end have no weight (`Adjoint::weights`): not traced.
    let window = Horizon::of(&st, &plan.grid);
    let parts: Vec<([f64; N], Vec<f64>)> = in_pool(opts.threads, || {
        work.par_iter()
            .map(|(tx, els)| {
                let mut acc = [0.0; N];
                let mut pulse_acc = vec![0.0; adj.n_pulse()];
                let mut pending = Vec::with_capacity(SETTLE_BATCH);
                // `ā·∂a + τ̄·∂τ + x̄·∂x` of a deposit, in deposit order.
                let mut add =
                    |(da, dt, dx): ([f64; N], [f64; N], [f64; N]), ab: f64, tb: f64, xb: f64| {
                        for j in 0..N {
                            acc[j] += ab * da[j] + tb * dt[j] + xb * dx[j];
                        }
                    };
                trace_block_within(&st, s, *tx, els.clone(), window, |d: Deposit<Dual<N>>| {
                    let rec = record_offset(*tx, d.element, n_el, adj.n_samples);
                    pending.push((
                        rec,
                        d.amplitude.re,
                        d.time.re,
                        d.shift.re,
                        (d.amplitude.eps, d.time.eps, d.shift.eps),
                    ));
                    if pending.len() == SETTLE_BATCH {
                        adj.settle(&mut pending, &mut pulse_acc, &mut add);
                    }
                });
                adj.settle(&mut pending, &mut pulse_acc, &mut add);
                (acc, pulse_acc)
            })
            .collect()
    });
    // Fixed-order reduction over chunks.
    let mut pulse_total = vec![0.0; adj.n_pulse()];
    for (acc, p) in parts {
        for (o, a) in out.iter_mut().zip(acc) {
            *o += a;
        }
        for (t, v) in pulse_total.iter_mut().zip(p) {
            *t += v;
        }
    }
    add_pulse_terms(group, &pulse_total, out);
    Ok(())
}

/// One replay with a reverse-mode recording per path, adding into `out`.
fn reverse_pass(
    scene: &Scene,
    plan: &AcquisitionPlan,
    params: &[ParamKey],
    adj: &Adjoint,
    s: &TraceSettings,
    opts: &RenderOptions,
    out: &mut [f64],
) -> Result<(), SceneError> {
    let meshes = scene.mesh_instances()?;
    let theta: Vec<f64> = params
        .iter()
        .map(|p| scene.get(p))
        .collect::<Result<_, _>>()?;
    let n_el = plan.elements.len();
    let n_tx = plan.transmits.len();
    // Check the lift once (errors surface here, not inside the workers).
    scene.lift_with(Some(&meshes), |_, v| f64::from_f64(v))?;
    let work = chunks(n_tx, n_el);
    let np = params.len();
    let parts: Vec<(Vec<f64>, Vec<f64>)> = in_pool(opts.threads, || {
        work.par_iter()
            .map(|(tx, els)| {
                let mut acc = vec![0.0; np];
                let mut pulse_acc = vec![0.0; adj.n_pulse()];
                let mut vars = vec![Var::constant(0.0); np];
                let (mut ys, mut ws): (Vec<Var>, Vec<f64>) = (Vec::new(), Vec::new());
                let mut pending = Vec::new();
                // The inputs and the scene lifted onto them are recorded once per
                // chunk and frozen; each path rewinds the tape to that point.
                let mut rec = Recording::start();
                rec.inputs_into(&theta, &mut vars);
                let Ok(st) = scene.lift_with(Some(&meshes), |key, v| {
                    match params.iter().position(|q| q == key) {
                        Some(i) => vars[i],
                        None => Var::constant(v),
                    }
                }) else {
                    return (acc, pulse_acc); // checked above; cannot fail
                };
                rec.freeze();
                // Deposits past the records' end have no weight: not traced.
                let window = Horizon::of(&st, &plan.grid);
                // A response traced on the tape lives only until the next
                // rewind: none is kept (`integrator::Responses`).
                let mut responses = Responses::disabled();
                for el in els.clone() {
                    let stack = crate::integrator::element_stack(&st, el);
                    for ray in 0..s.rays_per_element {
                        rec.rewind();
                        crate::integrator::trace_path_within(
                            &st,
                            s,
                            *tx,
                            el,
                            ray as u32,
                            stack,
                            window,
                            &mut responses,
                            |d: Deposit<Var>| {
                                let r = record_offset(*tx, d.element, n_el, adj.n_samples);
                                let (a, tau, x) = (d.amplitude, d.time, d.shift);
                                pending.push((r, a.value(), tau.value(), x.value(), (a, tau, x)));
                            },
                        );
                        ys.clear();
                        ws.clear();
                        adj.settle(&mut pending, &mut pulse_acc, |(a, tau, x), ab, tb, xb| {
                            ys.extend([a, tau]);
                            ws.extend([ab, tb]);
                            if xb != 0.0 {
                                ys.push(x);
                                ws.push(xb);
                            }
                        });
                        if !ys.is_empty() {
                            rec.vjp(&ys, &ws, &mut acc);
                        }
                    }
                }
                drop(rec);
                (acc, pulse_acc)
            })
            .collect()
    });
    let mut pulse_total = vec![0.0; adj.n_pulse()];
    for (acc, p) in parts {
        for (o, a) in out.iter_mut().zip(acc) {
            *o += a;
        }
        for (t, v) in pulse_total.iter_mut().zip(p) {
            *t += v;
        }
    }
    add_pulse_terms(params, &pulse_total, out);
    Ok(())
}
