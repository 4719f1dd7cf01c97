//! Rendering channel data: parallel, reproducible accumulation of deposits.
//!
//! Work is cut into fixed chunks, one per (transmit, emitting element); rayon runs
//! them in any order on any number of threads, each chunk returns its deposits
//! in path order, and the chunks are splatted in a fixed order (transmit-major,
//! then element, then ray). Random numbers are keyed by the path
//! ([`crate::rng`]), never by thread. So 1 thread and many give **bit-identical**
//! channel data.
//!
//! Sample grid: `t0_s = 0` on the clock of CONTRACT §1 (sample 0 is the instant the
//! plane wavefront passes the array centre); `n_samples = ⌈f_s·(2·max_depth/c +
//! max_e |x_e sin θ|/c + 4√σ)⌉ + 1` with `c` the imaging speed (the scanner's
//! record length) and `4√σ` the pulse half-support. Echoes from steered transmits
//! that arrive before `t = 0` (near-field, negative `x·sin θ`) are cut.

use crate::integrator::{element_stack, trace_path_from, Deposit, TraceCounters, TraceSettings};
use crate::scene::{Scene, SceneError, SceneT};
use rayon::prelude::*;
use std::time::Instant;
use usray_ad::Real;
use usray_signal::{ChannelData, ChannelMeta, ProbeMeta, TransmitMeta};

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
}

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

/// Number of samples per record and `t0_s` for a scene (see the module docs).
pub fn sample_grid(scene: &Scene) -> (usize, f64) {
    let c = scene.imaging_sound_speed();
    let fs = scene.acquisition.sampling_frequency_hz;
    let half_ap = 0.5 * (scene.probe.n_elements as f64 - 1.0) * scene.probe.pitch_m;
    let max_sin = scene
        .acquisition
        .angles_deg
        .iter()
        .map(|a| a.to_radians().sin().abs())
        .fold(0.0, f64::max);
    let support =
        usray_signal::pulse::pulse_support_s(scene.probe.center_frequency_hz, scene.probe.cycles);
    let dur = 2.0 * scene.acquisition.max_depth_m / c + half_ap * max_sin / c + support;
    ((dur * fs).ceil() as usize + 1, 0.0)
}

fn settings(scene: &Scene, opts: &RenderOptions) -> TraceSettings {
    TraceSettings {
        seed: opts.seed.unwrap_or(scene.acquisition.seed),
        max_bounces: scene.acquisition.max_bounces,
        rays_per_element: opts
            .rays_per_element
            .unwrap_or(scene.acquisition.rays_per_element)
            .max(1),
    }
}

fn in_pool<R: Send>(threads: Option<usize>, f: impl FnOnce() -> R + Send) -> R {
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

/// Trace every path of the scene in `T`: the deposits of each (transmit, element)
/// chunk, chunks in the fixed order `tx·N_e + el`, plus the work counters.
pub fn trace_all<T: Real>(
    scene: &Scene,
    st: &SceneT<T>,
    opts: &RenderOptions,
) -> (Vec<Vec<Deposit<T>>>, TraceCounters, u64) {
    let s = settings(scene, opts);
    let n_el = st.n_elements;
    let n_tx = st.angles.len();
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

/// Render the lifted scene in `T`: samples in C order `[tx, el, sample]`, the
/// number of samples per record, and the stats. This is the generic tracer the
/// `f64` [`render`] and the gradient code share.
pub fn render_lifted<T: Real>(
    scene: &Scene,
    st: &SceneT<T>,
    opts: &RenderOptions,
) -> (Vec<T>, usize, RenderStats) {
    let start = Instant::now();
    let (n_samples, t0) = sample_grid(scene);
    let (chunks, counters, paths) = trace_all(scene, st, opts);
    let n_el = st.n_elements;
    let n_tx = st.angles.len();
    let fs = st.fs;
    let mut impulses = vec![T::zero(); n_tx * n_el * n_samples];
    // Splat in the fixed chunk order; transmits are disjoint, so in parallel.
    in_pool(opts.threads, || {
        impulses
            .par_chunks_mut(n_el * n_samples)
            .enumerate()
            .for_each(|(tx, buf)| {
                for chunk in &chunks[tx * n_el..(tx + 1) * n_el] {
                    for d in chunk {
                        let e = d.element as usize;
                        let rec = &mut buf[e * n_samples..(e + 1) * n_samples];
                        crate::deposit::splat(rec, t0, fs, d.time, d.amplitude);
                    }
                }
            });
    });
    let samples = if opts.impulse_only {
        impulses
    } else {
        let taps = usray_signal::pulse::pulse_taps(
            fs,
            scene.probe.center_frequency_hz,
            scene.probe.cycles,
        );
        let mut out = vec![T::zero(); impulses.len()];
        in_pool(opts.threads, || {
            out.par_chunks_mut(n_samples)
                .zip(impulses.par_chunks(n_samples))
                .for_each(|(y, x)| crate::deposit::convolve(x, &taps, y));
        });
        out
    };
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

/// The channel-data metadata (CONTRACT §2) of a scene.
pub fn channel_meta(scene: &Scene) -> ChannelMeta {
    let (_, t0) = sample_grid(scene);
    ChannelMeta {
        format: usray_signal::channels::CHANNELS_FORMAT.to_string(),
        sampling_frequency_hz: scene.acquisition.sampling_frequency_hz,
        t0_s: t0,
        sound_speed_m_s: scene.imaging_sound_speed(),
        center_frequency_hz: scene.probe.center_frequency_hz,
        probe: ProbeMeta {
            kind: scene.probe.kind.clone(),
            n_elements: scene.probe.n_elements,
            pitch_m: scene.probe.pitch_m,
            element_width_m: scene.probe.element_width_m,
            extra: Default::default(),
        },
        transmits: scene
            .acquisition
            .angles_deg
            .iter()
            .map(|a| TransmitMeta {
                kind: "plane_wave".into(),
                angle_rad: a.to_radians(),
                t0_s: None,
                extra: Default::default(),
            })
            .collect(),
        extra: Default::default(),
    }
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
    let st = scene.lift_const::<f64>()?;
    let (samples, n_samples, stats) = render_lifted(scene, &st, opts);
    Ok((
        ChannelData {
            meta: channel_meta(scene),
            n_samples,
            samples,
        },
        stats,
    ))
}
