//! Rendering channel data: parallel, reproducible accumulation of deposits.
//!
//! Work is cut into fixed chunks, one per (transmit, block of
//! [`ELEMENT_BLOCK`] emitting elements), independent of the thread count.
//! Transmits are processed one after another; the blocks of a transmit run in
//! parallel (rayon, any order, any number of threads), each **splatting its
//! deposits on the fly** into its own buffer of the transmit's records (paths in
//! order: element, then ray), and the block buffers are summed in block order
//! (then cleared for the next transmit). With attenuation a deposit goes to
//! the four records of its down-shift weights ([`crate::downshift`]), kept
//! side by side per sample so that its splats share cache lines.
//! Random numbers are keyed by the path ([`crate::rng`]), never by thread. So 1
//! thread and many give **bit-identical** channel data, and memory is
//! `O(channel data)`: at most `⌈N_e/ELEMENT_BLOCK⌉` transmit-sized buffers live
//! at once, whatever the number of rays or deposits.
//!
//! The acquisition — elements, transmits, sample grid, pulse and down-shift
//! basis — is derived once per render as an [`AcquisitionPlan`] and passed
//! down ([`crate::plan`]).

use crate::integrator::{
    element_stack, trace_path_from, trace_path_within, Deposit, Horizon, Responses, TraceCounters,
    TraceSettings,
};
use crate::plan::AcquisitionPlan;
use crate::scene::{Sampler, Scene, SceneError, SceneT};
use rayon::prelude::*;
use std::time::Instant;
use usray_ad::Real;
use usray_signal::ChannelData;

/// Options of a render that are not part of the scene.
#[derive(Clone, Debug, Default)]
pub struct RenderOptions {
    /// Worker threads: `None` uses rayon's global pool, `Some(n)` a private pool
    /// of `n` threads.
    pub threads: Option<usize>,
    /// Override of `acquisition.rays_per_element` (tests, previews).
    pub rays_per_element: Option<usize>,
    /// Override of `acquisition.seed`.
    pub seed: Option<u64>,
    /// Skip the pulse convolution: the data is the linearly splatted impulse
    /// train `Σ a_k δ(t − τ_k)` (for tests and for gradient replays).
    pub impulse_only: bool,
    /// Override of `acquisition.receivers_per_event` (`Some(1)`: the paper's
    /// single uniformly chosen receiver per interaction).
    pub receivers_per_event: Option<usize>,
    /// Override of `acquisition.sampler`.
    pub sampler: Option<Sampler>,
}

impl RenderOptions {
    /// Checks the overrides against the scene's limits (`scene::limits`), as a
    /// scene file's own values are: a ray count past
    /// `MAX_RAYS_PER_ELEMENT` would run for days.
    ///
    /// # Errors
    /// An override out of range, naming the scene key it overrides.
    pub fn check(&self, scene: &Scene) -> Result<(), SceneError> {
        use crate::scene::limits::MAX_RAYS_PER_ELEMENT;
        if let Some(r) = self.rays_per_element {
            if !(1..=MAX_RAYS_PER_ELEMENT).contains(&r) {
                return Err(SceneError::new(
                    &scene.source,
                    "acquisition.rays_per_element",
                    format!(
                        "the override (--rays) {r} is outside 1..={MAX_RAYS_PER_ELEMENT} (usray_transport::scene::limits)"
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Emitting elements per work chunk (fixed, so the chunking and hence the
/// floating-point summation order never depend on the thread count).
pub const ELEMENT_BLOCK: usize = 16;

/// Work and speed of a render.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderStats {
    /// Rays cast: primary path segments plus receiver-connection segments.
    pub rays_traced: u64,
    /// Primary paths emitted.
    pub paths: u64,
    /// Deposits made.
    pub deposits: u64,
    /// Wall-clock seconds of the whole render (tracing, splatting, convolution).
    pub seconds: f64,
    /// `rays_traced / seconds`.
    pub rays_per_second: f64,
}

/// The trace settings of a render: the scene's, with `opts`' overrides.
pub fn settings(scene: &Scene, opts: &RenderOptions) -> TraceSettings {
    TraceSettings {
        seed: opts.seed.unwrap_or(scene.acquisition.seed),
        max_bounces: scene.acquisition.max_bounces,
        rays_per_element: opts
            .rays_per_element
            .unwrap_or(scene.acquisition.rays_per_element)
            .max(1),
        receivers_per_event: opts
            .receivers_per_event
            .or(scene.acquisition.receivers_per_event)
            .unwrap_or(0),
        sampler: opts.sampler.unwrap_or(scene.acquisition.sampler),
    }
}

pub(crate) fn in_pool<R: Send>(threads: Option<usize>, f: impl FnOnce() -> R + Send) -> R {
    match threads {
        Some(n) => match rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build()
        {
            Ok(pool) => pool.install(f),
            Err(_) => f(),
        },
        None => f(),
    }
}

/// Trace every path of the scene in `T` and **keep** the deposits of each
/// (transmit, element) chunk, chunks in the fixed order `tx·N_e + el`, plus the
/// work counters. Memory grows with the number of deposits (×`N_e` per
/// interaction with all-receiver connections): for tests and diagnostics at
/// small ray counts only; [`render_lifted`] splats on the fly.
pub fn trace_all<T: Real>(
    scene: &Scene,
    st: &SceneT<T>,
    opts: &RenderOptions,
) -> (Vec<Vec<Deposit<T>>>, TraceCounters, u64) {
    let s = settings(scene, opts);
    let n_el = st.n_elements;
    let n_tx = st.transmits.len();
    let chunks: Vec<(Vec<Deposit<T>>, TraceCounters)> = in_pool(opts.threads, || {
        (0..n_tx * n_el)
            .into_par_iter()
            .map(|c| {
                let (tx, el) = (c / n_el, c % n_el);
                let mut deps = Vec::new();
                let mut cnt = TraceCounters::default();
                let stack = element_stack(st, el);
                for ray in 0..s.rays_per_element {
                    let k = trace_path_from(st, &s, tx, el, ray as u32, stack, |d| deps.push(d));
                    cnt.rays += k.rays;
                    cnt.deposits += k.deposits;
                }
                (deps, cnt)
            })
            .collect()
    });
    let mut total = TraceCounters::default();
    let mut out = Vec::with_capacity(chunks.len());
    for (d, c) in chunks {
        total.rays += c.rays;
        total.deposits += c.deposits;
        out.push(d);
    }
    let paths = (n_tx * n_el * s.rays_per_element) as u64;
    (out, total, paths)
}

/// The chunks of one transmit: ranges of emitting elements (see the module docs).
pub fn element_blocks(n_el: usize) -> Vec<std::ops::Range<usize>> {
    (0..n_el.div_ceil(ELEMENT_BLOCK))
        .map(|b| b * ELEMENT_BLOCK..((b + 1) * ELEMENT_BLOCK).min(n_el))
        .collect()
}

/// Trace the paths of transmit `tx` emitted by elements `els` (element-major,
/// then ray), calling `out` for every deposit.
pub fn trace_block<T: Real>(
    st: &SceneT<T>,
    s: &TraceSettings,
    tx: usize,
    els: std::ops::Range<usize>,
    out: impl FnMut(Deposit<T>),
) -> TraceCounters {
    trace_block_within(st, s, tx, els, None, out)
}

/// [`trace_block`] for a caller that drops the deposits arriving from `horizon`
/// on (they are not traced; the others are the same).
pub(crate) fn trace_block_within<T: Real>(
    st: &SceneT<T>,
    s: &TraceSettings,
    tx: usize,
    els: std::ops::Range<usize>,
    horizon: Option<Horizon>,
    mut out: impl FnMut(Deposit<T>),
) -> TraceCounters {
    let mut cnt = TraceCounters::default();
    // The chunk's paths share their volume scatterers' receiver responses.
    let mut responses = Responses::new();
    for el in els {
        let stack = element_stack(st, el);
        for ray in 0..s.rays_per_element {
            let k = trace_path_within(
                st,
                s,
                tx,
                el,
                ray as u32,
                stack,
                horizon,
                &mut responses,
                &mut out,
            );
            cnt.rays += k.rays;
            cnt.deposits += k.deposits;
        }
    }
    cnt
}

/// Render the lifted scene in `T`: samples in C order `[tx, el, sample]`, the
/// number of samples per record, and the stats. This is the generic tracer the
/// `f64` [`render`] and the gradient code share. Deposits are splatted as they
/// are made (module docs): memory does not grow with the ray count.
pub fn render_lifted<T: Real>(
    scene: &Scene,
    st: &SceneT<T>,
    opts: &RenderOptions,
) -> (Vec<T>, usize, RenderStats) {
    render_planned(
        &AcquisitionPlan::new(scene),
        &settings(scene, opts),
        st,
        opts,
    )
}

/// [`render_lifted`] of the scene whose plan is `plan`, traced with `s`.
fn render_planned<T: Real>(
    plan: &AcquisitionPlan,
    s: &TraceSettings,
    st: &SceneT<T>,
    opts: &RenderOptions,
) -> (Vec<T>, usize, RenderStats) {
    let start = Instant::now();
    let grid = plan.grid;
    let (n_samples, t0, fs) = (grid.n_samples, grid.t0_s, grid.fs_hz);
    let n_el = plan.elements.len();
    let n_tx = plan.transmits.len();
    let rec_len = n_el * n_samples;
    let blocks = element_blocks(n_el);
    // The splat drops deposits past the records' end: they are not traced.
    let window = Horizon::of(st, &grid);
    // Records per transmit: one for the plain pulse, or the value and slope
    // records of each down-shift node (`crate::downshift`) when the scene
    // attenuates. Impulse-only data place no pulse and ignore the shift.
    // A render in an AD type carries the shift's derivative even where the
    // attenuation is 0 (`PulsePlan::nodes`' `differentiated`).
    let nodes = if opts.impulse_only {
        1
    } else {
        let carries_derivatives = std::any::TypeId::of::<T>() != std::any::TypeId::of::<f64>();
        plan.pulse.nodes(carries_derivatives)
    };
    let n_buf = if nodes == 1 { 1 } else { 2 * nodes };
    let taps = (!opts.impulse_only).then(|| plan.pulse.taps(fs, nodes));
    let total = n_tx * rec_len;
    // One pool for the whole render (transmits in turn, blocks in parallel).
    let (samples, counters) = in_pool(opts.threads, || {
        // Records in channel order; with down-shift records, the `n_buf`
        // values of a sample side by side (`deposit::splat_interleaved`).
        let mut impulses = vec![T::zero(); n_buf * total];
        let mut counters = TraceCounters::default();
        // One buffer per block, reused by every transmit (cleared after its
        // reduction): fresh buffers cost a page fault per 4 KiB each time.
        let mut bufs: Vec<Vec<T>> = blocks
            .iter()
            .map(|_| vec![T::zero(); n_buf * rec_len])
            .collect();
        for tx in 0..n_tx {
            let counts: Vec<TraceCounters> = blocks
                .par_iter()
                .zip(bufs.par_iter_mut())
                .map(|(els, buf)| {
                    trace_block_within(st, s, tx, els.clone(), window, |d| {
                        let e = d.element as usize;
                        let rec = &mut buf[e * n_buf * n_samples..(e + 1) * n_buf * n_samples];
                        if n_buf == 1 {
                            crate::deposit::splat(rec, t0, fs, d.time, d.amplitude);
                        } else {
                            let w = crate::downshift::basis(d.shift, nodes)
                                .map(|(b, c)| (b, d.amplitude * c));
                            crate::deposit::splat_interleaved(rec, n_buf, t0, fs, d.time, &w);
                        }
                    })
                })
                .collect();
            // Fixed-order reduction: block 0, 1, 2, …
            for (buf, cnt) in bufs.iter_mut().zip(counts) {
                counters.rays += cnt.rays;
                counters.deposits += cnt.deposits;
                let out = &mut impulses[tx * n_buf * rec_len..(tx + 1) * n_buf * rec_len];
                for (o, v) in out.iter_mut().zip(buf.iter()) {
                    *o += *v;
                }
                buf.fill(T::zero());
            }
        }
        drop(bufs);
        let Some(taps) = taps else {
            return (impulses, counters);
        };
        let mut out = vec![T::zero(); total];
        let per_record = n_buf * n_samples;
        out.par_chunks_mut(n_samples)
            .zip(impulses.par_chunks(per_record))
            .for_each(|(y, x)| {
                if n_buf == 1 {
                    crate::deposit::convolve(x, &taps[0], y);
                } else {
                    crate::deposit::convolve_interleaved_add(x, n_buf, &taps, y);
                }
            });
        (out, counters)
    });
    let paths = (n_tx * n_el * s.rays_per_element) as u64;
    let seconds = start.elapsed().as_secs_f64();
    let stats = RenderStats {
        rays_traced: counters.rays,
        paths,
        deposits: counters.deposits,
        seconds,
        rays_per_second: counters.rays as f64 / seconds.max(1e-12),
    };
    (samples, n_samples, stats)
}

/// Render a scene's channel data in `f64` (CONTRACT §2 layout).
///
/// ```
/// # let text = include_str!("../../../scenes/cylinder.toml");
/// # let scene = usray_transport::Scene::from_toml_str(text, "cylinder.toml", ".").unwrap();
/// use usray_transport::{render, RenderOptions};
/// let opts = RenderOptions { rays_per_element: Some(20), ..Default::default() };
/// let (data, stats) = render(&scene, &opts).unwrap();
/// assert_eq!(data.samples.len(), data.n_transmits() * data.n_elements() * data.n_samples);
/// assert!(stats.rays_traced > 0);
/// ```
pub fn render(
    scene: &Scene,
    opts: &RenderOptions,
) -> Result<(ChannelData, RenderStats), SceneError> {
    opts.check(scene)?;
    let st = scene.lift_const::<f64>()?;
    let plan = AcquisitionPlan::new(scene);
    let (samples, n_samples, stats) = render_planned(&plan, &settings(scene, opts), &st, opts);
    Ok((
        ChannelData {
            meta: plan.channel_meta(),
            n_samples,
            samples,
        },
        stats,
    ))
}
