//! The Monte Carlo path tracer: one generic function of `T: Real` from a lifted
//! scene and a path key to a list of deposits `(element, amplitude a, time τ)`.
//!
//! # Estimator and units
//! Channel data is `P(e, t) = Σ_k a_k·s(t − τ_k)` (`DESIGN.md`). Each element
//! emits `rays_per_element` primary rays per transmit; every deposit is divided by
//! that number, so the data is the Monte Carlo mean over an element's rays,
//! summed over emitting elements. Emission has weight 1 (directivity divided by
//! the cosine-hemisphere density, normalised by `π`). The weight a path carries is
//! a *pressure amplitude* in the paper's radiance-like transport (eq.
//! `pressure_equation`): spreading is carried by the ray density, never by an
//! explicit `1/r` on the path. Receiver connections evaluate the element's solid
//! angle `A_e cos θ_e / r²` (the same ray density, written for a chosen
//! direction), so a point scatterer's echo falls as `1/r²` in this model. In
//! 2-D (`acquisition.dimensions = 2`) everything stays in the `xz` plane, the
//! densities are per radian and a connection carries the element's angle
//! `w cos θ_e / r` ([`crate::scene::SceneT::element_measure`]): a line
//! scatterer's echo falls as `1/r`.
//!
//! # Path loop (pbrt-style)
//! 1. Emit: point on the element face, a direction (`acquisition.emission`:
//!    the transmit's propagation direction at the element, or the cosine
//!    hemisphere about the element normal), time stamp = the element's firing
//!    time in the transmit ([`usray_signal::transmit::TransmitWave`], CONTRACT §1).
//! 2. Intersect the scene (values in `f64` by the geometry's BVH / roots, hit
//!    distance, point and normal recomputed in `T`).
//! 3. Before the hit, volume scatterers along the segment (if the medium has
//!    them) send receiver connections; a ray that reaches the array's surface
//!    first (the plane `z = 0`, or a convex array's arc:
//!    [`crate::probe::array_surface_t`]) deposits directly if it lands on an
//!    element face and its path is purely specular so far.
//! 4. Advance: time `+= d/c` of the medium crossed, amplitude `×=` attenuation.
//! 5. At the interface: the media on both sides from the medium stack; a
//!    receiver connection if the interface is rough; then sample one microfacet
//!    normal (GGX) and **split**: the reflected and the transmitted continuation
//!    are both traced, each with its own weight (see [`crate::ggx::Interface::scatter`];
//!    the paper's `R²` choice would make the fixed-seed estimate jump in the
//!    parameters). The transmitted branch updates the medium stack. With
//!    `acquisition.thin_layer_tunnelling`, entering a
//!    thin layer (a tube's wall, a slab) beyond its critical angle, the
//!    transmitted branch is the wave that tunnels through it
//!    ([`crate::thin_layer`]): it resumes on the far surface, in the medium it
//!    came from.
//! 6. A branch stops after `max_bounces` interactions, on escape, on a dead
//!    sample, or below [`MIN_BRANCH_AMPLITUDE`].
//!
//! Each step has its file: `path` (the entry points and the loop over pending
//! branches), `emission` (step 1), `branch` (what a branch carries; steps 2–4),
//! `volume` (3a), `arrival` (3b), `interface` (5), and `connection` (every
//! receiver connection, with its MIS weight). `context` holds the state the
//! steps share (casting a ray, making a deposit), `horizon` the time window
//! that lets a path skip work that could only deposit after it, and `settings`
//! the fixed settings and the receivers of an interaction. The steps called
//! once per path or branch are `#[inline]`, so that they are compiled into the
//! path loop as they were when the tracer was one module (the compiler places
//! each module's functions in their own codegen unit).
//!
//! **Double counting and MIS.** A path deposits by a direct array hit while every
//! interaction so far was a delta (smooth) lobe (weight 1). After a rough vertex,
//! arrival at the array is estimated by two strategies combined with the power
//! heuristic (Veach 1997, §9.2): the vertex's receiver connection to element `e`
//! (density `1/(sel_w·Ω_e)`, `Ω_e = A_e cos θ_e / r²`) and the continuation it
//! samples reaching element `e`'s face directly with no other interaction
//! (density `pdf(wi, wo)` of [`crate::ggx::Interface::pdf`]). The weights are
//! differentiated (they sum to one for any parameters, so value and gradient stay
//! unbiased); connections that cross a boundary keep weight 1 (the continuation
//! cannot produce them). A connection crossing a boundary treats it as smooth
//! (Fresnel `T`, no refraction), so it already estimates every later path that
//! *transmits* through that boundary towards the array: after the first rough
//! vertex of a path, transmission-side connections and direct hits after a
//! rough transmission are therefore not made (else the distal wall of a vessel
//! would be counted twice, once through the near-delta lobe). This removes the fireflies of connections through a
//! nearly delta lobe: GGX transmission between two almost index-matched media
//! (1540 → 1570 m/s) is a narrow spike around the straight-through direction,
//! which a fixed connection direction samples with enormous variance. Paths
//! that need a delta lobe *after* the last rough vertex to reach the array (rough
//! → mirror → array) are not counted: the connection is a straight line.
//!
//! **Connections** (paper, "Transducer Sampling"): by default every interaction
//! connects to **every** element (a deterministic sum over receivers, weight 1:
//! no selection variance, so each scattering event is a perfectly focused point
//! source in the delay-and-sum image). `acquisition.receivers_per_event = K < N_e`
//! instead draws one element uniformly in each of `K` contiguous strata (weight
//! `N_e/K`, the stratum size); `K = 1` is the paper's single uniformly chosen
//! element (probability `1/N_e`, divided out). The aim point is the centre, and the
//! straight segment to it is traced through the scene multiplying the Fresnel
//! transmission coefficient of every boundary crossed (refraction is **ignored**
//! on the connection, as in the paper; total internal reflection blocks it,
//! except at a thin layer where the scene asks for tunnelling, which passes
//! `|T|` of [`crate::thin_layer`]) and
//! the attenuation of every medium; time accumulates `length / c` per medium.

mod arrival;
mod branch;
mod connection;
mod context;
mod edge;
mod emission;
mod horizon;
mod interface;
mod path;
mod responses;
mod settings;
mod spreading;
mod volume;

pub use edge::EdgeWaves;
pub(crate) use horizon::Horizon;
pub(crate) use path::trace_path_within;
pub use path::{element_stack, trace_path, trace_path_casts, trace_path_from};
pub(crate) use responses::Responses;
pub use settings::TraceSettings;
pub use spreading::POINT_SOURCE_REFERENCE_M;

/// Closest distance (m) a ray may hit after leaving a surface: 0.1 µm, far below
/// a wavelength (0.3 mm at 5 MHz) and above the f64 rounding of hit points.
pub const T_MIN: f64 = 1e-7;

/// One contribution to the channel data: `a·s(t − τ)` on element `element`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Deposit<T> {
    /// Receiving element.
    pub element: u32,
    /// Amplitude `a` (already divided by `rays_per_element`, depth gain applied).
    pub amplitude: T,
    /// Time of flight `τ` on the clock of CONTRACT §1, seconds.
    pub time: T,
    /// Spectral shift `x = −β σ_f` of the echo's carrier, in standard
    /// deviations `σ_f` of the pulse spectrum (≤ 0; 0 without attenuation):
    /// the pulse to place is [`usray_signal::pulse::shifted_pulse`] at `s = −x`
    /// ([`crate::downshift`]). `amplitude` includes its factor `e^{x²/2}`.
    pub shift: T,
}

/// Branches whose path amplitude falls below this are ended: −80 dB, 20 dB below
/// the deepest dynamic range the display uses by default (60 dB), so the
/// truncation is invisible in B-mode; it bounds the work of reverberations that
/// splitting would otherwise follow to `max_bounces`.
pub const MIN_BRANCH_AMPLITUDE: f64 = 1e-4;

/// Work counters of one trace.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceCounters {
    /// Rays cast (primary segments, connection segments).
    pub rays: u64,
    /// Deposits made.
    pub deposits: u64,
}
