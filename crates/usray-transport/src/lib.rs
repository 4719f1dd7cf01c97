//! usray-transport: Monte Carlo acoustic ray transport for ultrasound.
//!
//! Loads a scene (CONTRACT §3), lists and sets its parameters by dotted path,
//! lifts its numbers into any scalar `T: Real` (plain `f64`, a forward dual, a
//! reverse-mode variable), and traces full paths from a linear array through the
//! scene — Snell refraction with sound speeds, acoustic Fresnel split with
//! impedances, GGX rough interfaces, receiver-directed connections — into RF
//! channel data (CONTRACT §2). One generic tracer serves rendering and gradients.
//!
//! ```
//! use usray_transport::{render, RenderOptions, Scene};
//! let text = r#"
//! [medium]
//! sound_speed_m_s = 1540.0
//! impedance_mrayl = 1.54
//! [probe]
//! kind = "linear"
//! n_elements = 16
//! pitch_m = 0.3e-3
//! element_width_m = 0.27e-3
//! center_frequency_hz = 5.0e6
//! cycles = 3.0
//! main_lobe_deg = 5.0
//! cutoff_deg = 60.0
//! [acquisition]
//! angles_deg = [0.0]
//! sampling_frequency_hz = 40.0e6
//! max_depth_m = 0.02
//! rays_per_element = 100
//! max_bounces = 3
//! seed = 7
//! [materials.target]
//! impedance_mrayl = 1.99
//! sound_speed_m_s = 1570.0
//! roughness = 0.3
//! [[objects]]
//! name = "cylinder"
//! shape = "cylinder"
//! center_m = [0.0, 0.0, 0.015]
//! radius_m = 0.005
//! material = "target"
//! "#;
//! let scene = Scene::from_toml_str(text, "<example>", ".").unwrap();
//! let radius = usray_transport::ParamKey::object("cylinder", usray_transport::Field::Radius);
//! assert_eq!(scene.get(&radius).unwrap(), 0.005);
//! let (data, stats) = render(&scene, &RenderOptions::default()).unwrap();
//! // The strongest sample of a central element is the proximal wall echo at
//! // 2 · 10 mm / c = 13 µs.
//! let rec = data.record(0, 8);
//! let k = (0..rec.len()).max_by(|&a, &b| rec[a].abs().total_cmp(&rec[b].abs())).unwrap();
//! let t = k as f64 / 40.0e6;
//! assert!((t - 2.0 * 0.010 / 1540.0).abs() < 0.5e-6, "echo at {t}");
//! assert!(stats.rays_per_second > 0.0);
//! ```
//!
//! # Conventions
//! - **Frame and clock** (CONTRACT §1): `x` lateral, `y` elevation, `z` depth;
//!   elements on `z = 0`; `t = 0` when the plane wavefront passes `(0, 0)`. An
//!   element at `x_e` fires at `x_e·sin θ / c_img` (`c_img` = the speed the scanner
//!   assumes, `imaging.sound_speed_m_s`, default the medium's). Records start at
//!   `t0_s = 0` ([`plan`]).
//! - **Pulse**: `usray_signal::pulse` (paper eq. `axial_sig`), envelope FWHM =
//!   `cycles / f_c`, i.e. `σ = (cycles/(2 f_c))² / ln 2`; centred on the time of
//!   flight. Attenuated echoes carry the pulse with its carrier moved down by
//!   `βσ_f²` ([`downshift`]: the exact result for a Gaussian pulse).
//! - **Amplitude**: emission weight 1 per ray; every deposit is divided by
//!   `rays_per_element`, so data is the mean over an element's rays summed over
//!   emitting elements. Weights are pressure amplitudes; reflection multiplies by
//!   `R`, transmission by `T = 1 + R` (Kinsler §6.3, energy
//!   `R² + T²·Z1 cos θt/(Z2 cos θi) = 1`); a path splits into both
//!   continuations at every interface (no reflect-or-transmit choice; see
//!   [`ggx::Interface::scatter`]). Spreading is carried by ray density; receiver
//!   connections use the element's solid angle `A_e cos θ_e / r²`.
//! - **Emission** (`acquisition.emission`): `"plane_wave"` (default: rays
//!   along the transmitted wave's rays, a collimated bundle along the
//!   steering direction for a plane wave, weight `n·ω`) or
//!   `"cosine"` (the paper's element lobe `max(0, n·ω)` importance-sampled on
//!   the full 3-D cosine-weighted hemisphere: no restriction in elevation; the
//!   cosine model leaves incoherent off-axis echoes
//!   as noise, about −6 dB in the cylinder's lumen at 200 rays/element against
//!   −59 dB for the bundle). Emission points cover the element face
//!   (`element_width_m × elevation_m`) in both.
//! - **Receivers** (`acquisition.receivers_per_event`): every rough
//!   interaction and volume scatterer connects to **all** elements by default
//!   (a deterministic sum, weight 1), so each event is a focused point in the
//!   delay-and-sum image; `K < N_e` draws one element per stratum of `N_e/K`
//!   (weight `N_e/K`), `K = 1` is the paper's single uniform choice (weight
//!   `N_e`). Connections are MIS-combined with direct array hits of the sampled
//!   continuation ([`integrator`], "Double counting and MIS").
//! - **Memory**: deposits are splatted as they are made into per-(transmit,
//!   16-element block) buffers summed in block order ([`mod@render`]); nothing
//!   grows with the ray count, and results are bit-identical for any thread count.
//! - **Gradients**: every continuous quantity is computed in `T` from the lifted
//!   scene, sampling included (microfacet normals, MIS weights); visibility
//!   changes (which surface is hit, which element a ray lands on) carry no
//!   derivative. [`channel_gradient`] returns `Σ d_channels·∂P/∂θ` for named
//!   parameters by replaying the render's paths (same `RenderOptions` ⇒ same
//!   random numbers) against the pulse-correlated adjoint `G = g ⋆ s`: `Dual<N ≤ 8>`
//!   passes below [`gradient::REVERSE_MIN_PARAMS`] parameters, per-path reverse
//!   mode from there; memory does not grow with the ray count; bit-identical for
//!   any thread count. It is the derivative of the realization (agreeing with its
//!   finite differences to < 1e-6, `tests/gradient_fd.rs`), and, the estimator
//!   being unbiased and smooth in every parameter, an unbiased estimate of the
//!   derivative of the expected data up to visibility (see [`gradient`]).
//!
//! Modules: [`scene`] (file, validation, parameters, lifting), [`plan`] (the
//! acquisition derived once: elements, transmits, sample grid, pulse), [`probe`],
//! [`fresnel`], [`ggx`], [`rng`], [`integrator`] (the path tracer),
//! [`deposit`] (placing echoes in time), [`downshift`] (the spectral
//! down-shift of attenuated echoes), [`effects`], [`mod@render`] (parallel,
//! reproducible accumulation), [`gradient`] (the transport gradient).

pub mod deposit;
pub mod downshift;
pub mod effects;
pub mod fresnel;
pub mod ggx;
pub mod ggx_planar;
pub mod gradient;
pub mod integrator;
pub mod plan;
pub mod probe;
pub mod render;
pub mod rng;
pub mod scene;
pub mod thin_layer;

pub use gradient::channel_gradient;
pub use integrator::{trace_path, Deposit, TraceSettings};
pub use plan::AcquisitionPlan;
pub use render::{render, render_lifted, trace_all, trace_block, RenderOptions, RenderStats};
pub use scene::{Field, ParamKey, Scene, SceneError, SceneT};
