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
//! direction), so a point scatterer's echo falls as `1/r²` in this model.
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
//!    parameters). The transmitted branch updates the medium stack.
//! 6. A branch stops after `max_bounces` interactions, on escape, on a dead
//!    sample, or below [`MIN_BRANCH_AMPLITUDE`].
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
//! on the connection, as in the paper; total internal reflection blocks it) and
//! the attenuation of every medium; time accumulates `length / c` per medium.

use crate::effects::{attenuation_and_exponent, depth_gain, ScattererField};
use crate::fresnel::fresnel;
use crate::ggx::{Interface, SMOOTH_ALPHA};
use crate::plan::SampleGrid;
use crate::probe::{
    array_surface_t, centre3, cos_to_normal, cosine_hemisphere, distance_bound_m, element_at,
    face_point, from_element_frame, transmit_directivity, ReceiveLobe,
};
use crate::rng::{dim, PathSampler};
use crate::scene::{Emission, MaterialT, Sampler, SceneT};
use usray_ad::Real;
use usray_geometry::{Hit, MediumStack, Ray, Vec3};
use usray_signal::transmit::TransmitWave;

/// Closest distance (m) a ray may hit after leaving a surface: 0.1 µm, far below
/// a wavelength (0.3 mm at 5 MHz) and above the f64 rounding of hit points.
pub const T_MIN: f64 = 1e-7;

/// Maximum boundaries a receiver connection crosses before it is dropped.
const MAX_CONNECTION_CROSSINGS: usize = 32;

/// Maximum volume-scattering events per segment (bounds the work; at most
/// densities the expected count is far below).
const MAX_VOLUME_EVENTS: u32 = 256;

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

/// Fixed settings of a trace.
#[derive(Clone, Copy, Debug)]
pub struct TraceSettings {
    /// Acquisition seed.
    pub seed: u64,
    /// Maximum interactions per path.
    pub max_bounces: u32,
    /// Rays per element (deposits are divided by it).
    pub rays_per_element: usize,
    /// Receivers each interaction connects to (`acquisition.receivers_per_event`):
    /// `K ≥ N_e` (or 0) = every element, deterministically, weight 1; `K < N_e` =
    /// one element drawn uniformly in each of `K` contiguous strata, weight = the
    /// stratum's size (`N_e/K`); `K = 1` is the paper's uniform choice.
    pub receivers_per_event: usize,
    /// How an element's rays draw their random numbers (`acquisition.sampler`).
    pub sampler: Sampler,
}

impl TraceSettings {
    /// The receiving elements of one interaction and their estimator weights,
    /// from the interaction's uniform `u` (see
    /// [`TraceSettings::receivers_per_event`]): stratum `j` of `K` holds elements
    /// `⌊jN/K⌋ .. ⌊(j+1)N/K⌋`; its element is `lo + ⌊u·size⌋`, weight `size`.
    #[inline]
    pub fn receivers(&self, n_el: usize, u: f64) -> impl Iterator<Item = (usize, f64)> {
        let k = match self.receivers_per_event {
            0 => n_el,
            k => k.min(n_el),
        };
        (0..k).map(move |j| {
            if k == n_el {
                return (j, 1.0); // every element (the default): no divisions
            }
            let lo = j * n_el / k;
            let hi = (j + 1) * n_el / k;
            let size = hi - lo;
            let e = lo + ((u * size as f64) as usize).min(size - 1);
            (e, size as f64)
        })
    }

    /// The estimator weight [`TraceSettings::receivers`] gives element `e` (its
    /// stratum's size).
    pub fn receiver_weight(&self, n_el: usize, e: usize) -> f64 {
        let k = match self.receivers_per_event {
            0 => n_el,
            k => k.min(n_el),
        };
        (0..k)
            .map(|j| (j * n_el / k, (j + 1) * n_el / k))
            .find(|&(lo, hi)| (lo..hi).contains(&e))
            .map_or(1.0, |(lo, hi)| (hi - lo) as f64)
    }
}

/// Power-heuristic MIS weight (β = 2) of a strategy with density `p` against one
/// with density `q` (Veach 1997, §9.2.3): `p²/(p² + q²)`. Differentiated (the
/// weights of the two strategies sum to one for any parameters, so the estimate
/// stays unbiased and its fixed-seed derivative is exact).
#[inline]
fn power_heuristic<T: Real>(p: T, q: T) -> T {
    let (p2, q2) = (p * p, q * q);
    let s = p2 + q2;
    if s.value() > 0.0 && s.is_finite() {
        p2 / s
    } else if p.value().is_infinite() {
        T::one()
    } else {
        T::zero()
    }
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

/// The straight line of a receiver connection (see `PathCtx::link`).
#[derive(Clone, Copy)]
struct Link<T> {
    /// Receiving element.
    e: usize,
    /// Unit direction towards the element's centre.
    wo: Vec3<T>,
    /// Distance to it, metres.
    r: T,
}

/// The values of a receiver connection's line that passed the checks of
/// `PathCtx::aim`.
#[derive(Clone, Copy)]
struct Aim {
    /// Receiving element.
    e: usize,
    /// Unit direction towards the element's centre (values).
    wo: Vec3<f64>,
}

/// The unit direction from `p` to the element centre `target` and the
/// distance, in any number type (`PathCtx::aim` in values, `PathCtx::link` in
/// `T`).
#[inline]
fn line<U: Real>(target: Vec3<U>, p: Vec3<U>) -> (Vec3<U>, U) {
    let v = target - p;
    let r = v.length();
    (v * r.recip(), r)
}

/// The end of the recorded time window: deposits arriving at `τ ≥ end` are
/// dropped by the caller (past the last sample of a record), so a trace may
/// skip what can only deposit that late (`PathCtx::late`). The renderer and the
/// gradient replay set it; the public per-path functions do not (they report
/// every deposit).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Horizon {
    /// Time (s) from which deposits are dropped.
    end: f64,
    /// The largest sound speed of the scene's media (m/s): no path or
    /// connection covers a distance `d` in less than `d / c_max`.
    c_max: f64,
    /// How much earlier (s) than that bound a deposit through a volume
    /// scatterer can arrive (0 without volume scattering): see
    /// `PathCtx::vertex_late`.
    volume_slack: f64,
}

impl Horizon {
    /// The window of records on `grid` for the media of `st`, or `None` when
    /// it cannot be bounded (no finite positive sound speed). The end is
    /// pushed out by a relative 10⁻⁹ so that rounding of the traced times
    /// (≈ 10⁻¹⁵ relative) can never skip a deposit that would land in the
    /// record.
    pub(crate) fn of<T: Real>(st: &SceneT<T>, grid: &SampleGrid) -> Option<Self> {
        let (n_samples, t0, fs) = (grid.n_samples, grid.t0_s, grid.fs_hz);
        let speeds = || {
            std::iter::once(&st.medium)
                .chain(st.objects.iter().map(|o| &o.material))
                .map(|m| m.sound_speed.value())
        };
        let c_max = speeds().fold(f64::NEG_INFINITY, f64::max);
        let c_min = speeds().fold(f64::INFINITY, f64::min);
        // A volume scatterer lies in the cell of the point on the ray that
        // selected it: at most `δ = √3·h` (the cell's diagonal) from it.
        let delta = st
            .objects
            .iter()
            .filter_map(|o| ScattererField::new(0, o.material.scatterer_density_per_mm3.value()))
            .map(|f| 3f64.sqrt() * f.cell_m)
            .fold(0.0, f64::max);
        let volume_slack = 2.0 * delta / c_max + delta / c_min;
        let end = t0 + n_samples as f64 / fs * (1.0 + 1e-9);
        let ok = c_min > 0.0 && c_max.is_finite() && volume_slack.is_finite() && end.is_finite();
        ok.then_some(Self {
            end,
            c_max,
            volume_slack,
        })
    }
}

/// State shared by the steps of one path.
struct PathCtx<'a, T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> {
    st: &'a SceneT<T>,
    settings: &'a TraceSettings,
    norm: T,
    /// The largest down-shift placed, in `σ_f` ([`SceneT::max_shift`]).
    max_shift: f64,
    /// The elements' receive directivity.
    lobe: ReceiveLobe<T>,
    /// Deposits from this time on are dropped by the caller (`None`: keep all).
    horizon: Option<Horizon>,
    counters: TraceCounters,
    out: F,
    cast: C,
}

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// Cast `ray` through the scene (`t ∈ [T_MIN, t_max]`): counted, reported to
    /// the `cast` hook, then [`usray_geometry::Geometry::intersect`].
    #[inline(always)]
    fn intersect(&mut self, ray: &Ray<T>, t_max: f64) -> Option<Hit<T>> {
        self.counters.rays += 1;
        (self.cast)(ray, T_MIN, t_max);
        self.st.geometry.intersect(ray, T_MIN, t_max)
    }

    /// Deposit on element `e` an echo of amplitude `a` (attenuated at `f_c`)
    /// whose path has the attenuation exponent `beta` (Np/Hz), at time `tau`:
    /// applies the depth gain, the `1/rays` norm and the down-shift's
    /// amplitude factor `e^{x²/2}`, `x = −βσ_f` ([`crate::downshift`]).
    fn deposit(&mut self, e: usize, a: T, beta: T, tau: T) {
        let st = self.st;
        let g = depth_gain(st.depth_gain_db_per_cm, st.imaging_sound_speed, tau);
        // Beyond the model's largest shift (`downshift::max_shift`) the echo is
        // placed at it, and its factor is taken there (bounded by e^{s²/2}).
        let shift = (-(beta * st.pulse_bandwidth)).max(T::from_f64(-self.max_shift));
        let mut amplitude = a * g * self.norm;
        if shift.value() != 0.0 {
            // At x = 0 the factor is 1 with zero derivative: skipped.
            amplitude *= (shift * shift).scale(0.5).exp();
        }
        if amplitude.value() == 0.0 || !amplitude.is_finite() || !tau.is_finite() {
            return;
        }
        self.counters.deposits += 1;
        (self.out)(Deposit {
            element: e as u32,
            amplitude,
            time: tau,
            shift,
        });
    }

    /// True when every deposit a path at `time` (s) can still make after
    /// covering at least `dist` metres arrives after the horizon, i.e. would be
    /// dropped: that takes at least `dist / c_max` (shortened by a relative 10⁻⁹
    /// for rounding, see [`Horizon::of`]).
    #[inline]
    fn late(&self, time: f64, dist: f64) -> bool {
        self.horizon
            .is_some_and(|h| time + dist / h.c_max * (1.0 - 1e-9) >= h.end)
    }

    /// True when nothing a vertex at `time` and `depth` (m) and its
    /// continuations can deposit arrives before the horizon. Its connections
    /// and everything after it travel at least `depth` back to the array plane
    /// (triangle inequality), except deposits through a volume scatterer, which
    /// sits up to `δ` off the ray that selected it: with `c_min` the smallest
    /// speed, such a deposit arrives no earlier than
    /// `time + (depth − 2δ)/c_max − δ/c_min` (`Horizon::volume_slack`).
    #[inline]
    fn vertex_late(&self, time: f64, depth: f64) -> bool {
        self.horizon
            .is_some_and(|h| self.late(time - h.volume_slack, depth))
    }

    /// The line from `p` to element `e`'s centre in values (the values of
    /// [`PathCtx::link`]'s, bit for bit), or `None` when no connection is made:
    /// closer than [`T_MIN`], beyond the element's receive cutoff (where its
    /// directivity is 0), or certainly arriving after the horizon from `time`.
    /// Checked before any `T` arithmetic, which rejected connections then skip.
    #[inline]
    fn aim(&self, p: Vec3<f64>, e: usize, time: f64) -> Option<Aim> {
        let st = self.st;
        let el = &st.elements[e];
        let (wo, r) = line(centre3(el).to_f64(), p);
        let n = [el.normal[0].value(), el.normal[1].value()];
        let facing = cos_to_normal(st.array.kind, &n, wo);
        if r <= T_MIN || !self.lobe.may_receive(-facing) || self.late(time, r) {
            return None;
        }
        Some(Aim { e, wo })
    }

    /// The straight line from `p` to the element of `aim` in `T`.
    #[inline]
    fn link(&self, p: Vec3<T>, aim: &Aim) -> Link<T> {
        let (wo, r) = line(centre3(&self.st.elements[aim.e]), p);
        Link { e: aim.e, wo, r }
    }

    /// Receiver connection from `p` along `link` (medium stack `stack` on the
    /// side the connection leaves into) with scattering factor `f_cos` (1/sr)
    /// and path amplitude `w` and attenuation exponent `beta` at time `tau`, estimator weight `sel_w` (see
    /// [`TraceSettings::receivers`]). `p_bsdf` is the density (1/sr) with which
    /// the vertex's own continuation sampling would produce the connection
    /// direction (0 for volume scatterers): an unobstructed connection is then
    /// MIS-weighted against a direct array hit of that continuation.
    #[allow(clippy::too_many_arguments)]
    fn connect(
        &mut self,
        p: Vec3<T>,
        mut stack: MediumStack,
        w: T,
        beta: T,
        f_cos: T,
        tau: T,
        link: &Link<T>,
        sel_w: f64,
        p_bsdf: T,
    ) {
        let st = self.st;
        if f_cos.value() == 0.0 {
            return;
        }
        let Link { e, wo, r } = *link;
        let cos_e = -cos_to_normal(st.array.kind, &st.elements[e].normal, wo);
        let fd = self.lobe.eval(cos_e);
        if fd.value() == 0.0 {
            return;
        }
        // Trace the straight segment, crossing boundaries.
        let mut amp = w * f_cos;
        let mut beta = beta;
        let mut time = tau;
        let mut origin = p;
        let mut remaining = r;
        for crossing in 0..MAX_CONNECTION_CROSSINGS {
            let medium = *st.medium_of(stack.top());
            let hit = self.intersect(&Ray::new(origin, wo), remaining.value() - T_MIN);
            let Some(hit) = hit else {
                time += remaining / medium.sound_speed;
                let (k, b) = attenuation_and_exponent(
                    medium.attenuation_db_cm_mhz,
                    st.center_frequency,
                    remaining,
                );
                amp *= k;
                beta += b;
                let solid = st.array.element_width_m * st.elevation * cos_e / (r * r);
                // Unobstructed: the continuation could have hit the element too.
                let mis = if crossing == 0 && p_bsdf.value() > 0.0 {
                    power_heuristic((solid.scale(sel_w)).recip(), p_bsdf)
                } else {
                    T::one()
                };
                let a = amp * solid * fd.scale(sel_w) * mis;
                self.deposit(e, a, beta, time);
                return;
            };
            time += hit.t / medium.sound_speed;
            let (k, b) =
                attenuation_and_exponent(medium.attenuation_db_cm_mhz, st.center_frequency, hit.t);
            amp *= k;
            beta += b;
            remaining -= hit.t;
            let entering = hit.entering(&wo);
            let other = if entering {
                st.objects[hit.object].material
            } else {
                *st.medium_of(stack.after_exit(hit.object))
            };
            let cos_i = wo.dot(hit.normal).abs();
            let f = fresnel(
                cos_i,
                medium.sound_speed,
                other.sound_speed,
                medium.impedance,
                other.impedance,
            );
            if f.tir {
                return;
            }
            amp *= f.t;
            stack.cross(hit.object, entering);
            origin = hit.point;
        }
    }

    /// Volume scatterers along a segment of length `len` from `origin` along `dir`
    /// in `medium` (inside object `obj`), path amplitude `w`, attenuation
    /// exponent `beta` and time `tau` at origin.
    #[allow(clippy::too_many_arguments)]
    fn volume(
        &mut self,
        obj: usize,
        medium: &MaterialT<T>,
        stack: MediumStack,
        origin: Vec3<T>,
        dir: Vec3<T>,
        len: f64,
        w: T,
        beta: T,
        tau: T,
        sampler: &PathSampler,
        bounce: u32,
    ) {
        let Some(field) = ScattererField::new(obj, medium.scatterer_density_per_mm3.value()) else {
            return;
        };
        if medium.scatterer_strength.value() == 0.0 {
            return;
        }
        // √(ρ/ρ_g)·(1 mm/h)²: the density's (differentiable) share of each
        // event's amplitude, and the cell's cross-section (see ScattererField).
        let density_weight = field.event_weight(medium.scatterer_density_per_mm3);
        let mu = 1.0 / field.cell_m;
        let mut s = 0.0;
        for k in 0..MAX_VOLUME_EVENTS {
            let u = sampler.uniform(bounce, dim::VOLUME_BASE + 2 * k);
            s += -(1.0 - u).ln() / mu;
            if s >= len {
                return;
            }
            let on_line = origin.to_f64() + dir.to_f64().scale(s);
            let (q, g) = field.scatterer_near::<T>(on_line.value());
            // Time at the scatterer: along the ray to its projection, then across.
            let along = (q - origin).dot(dir);
            let t_q = tau + along / medium.sound_speed;
            let (k_q, b_q) = attenuation_and_exponent(
                medium.attenuation_db_cm_mhz,
                self.st.center_frequency,
                along,
            );
            let (a_q, beta_q) = (w * k_q, beta + b_q);
            let f = (medium.scatterer_strength * density_weight)
                .scale(g / (4.0 * core::f64::consts::PI));
            let ue = sampler.uniform(bounce, dim::VOLUME_BASE + 2 * k + 1);
            let settings = self.settings;
            for (e, sel_w) in settings.receivers(self.st.n_elements, ue) {
                if let Some(aim) = self.aim(q.to_f64(), e, t_q.value()) {
                    let link = self.link(q, &aim);
                    self.connect(q, stack, a_q, beta_q, f, t_q, &link, sel_w, T::zero());
                }
            }
        }
    }
}

/// The medium stack at element `el`'s centre: the objects the element sits
/// in (normally none). Emission points of an element share it.
pub fn element_stack<T: Real>(st: &SceneT<T>, el: usize) -> MediumStack {
    st.geometry.stack_at(centre3(&st.elements[el]).value())
}

/// Trace one primary path (transmit `tx`, emitting element `el`, ray index `ray`)
/// and call `out` for each deposit. Returns the work counters.
pub fn trace_path<T: Real>(
    st: &SceneT<T>,
    settings: &TraceSettings,
    tx: usize,
    el: usize,
    ray: u32,
    out: impl FnMut(Deposit<T>),
) -> TraceCounters {
    trace_path_from(st, settings, tx, el, ray, element_stack(st, el), out)
}

/// One branch of a path: what the path loop carries from vertex to vertex. A
/// split interaction (reflection and transmission) continues as two branches.
#[derive(Clone, Copy)]
struct Branch<T> {
    origin: Vec3<T>,
    dir: Vec3<T>,
    /// Path amplitude so far.
    w: T,
    /// Attenuation exponent so far, Np/Hz ([`attenuation_exponent`]).
    beta: T,
    /// Time stamp at `origin`, s.
    time: T,
    stack: MediumStack,
    /// Every interaction so far was a delta lobe.
    specular_chain: bool,
    /// Density (1/sr) of the continuation sampled at the previous vertex when it
    /// was rough and is the last interaction so far (for the MIS'd direct hit).
    last_rough: Option<T>,
    /// Rough vertices so far (connections through boundaries cover later
    /// transmissions; see the module docs).
    rough_vertices: u32,
    /// Index of the vertex this branch is heading to (1 = first interaction).
    bounce: u32,
    /// Random numbers of this branch (keyed by the branch choices so far).
    sampler: PathSampler,
}

/// [`trace_path`] with the element's medium stack given (see [`element_stack`];
/// computed once per element by the renderer).
pub fn trace_path_from<T: Real>(
    st: &SceneT<T>,
    settings: &TraceSettings,
    tx: usize,
    el: usize,
    ray: u32,
    start_stack: MediumStack,
    out: impl FnMut(Deposit<T>),
) -> TraceCounters {
    trace_path_casts(st, settings, tx, el, ray, start_stack, out, |_, _, _| {})
}

/// [`trace_path_from`] that also calls `cast(ray, t_min, t_max)` for every ray
/// the path casts, just before it is intersected with the scene
/// ([`usray_geometry::Geometry::intersect`] over `t ∈ [t_min, t_max]` metres):
/// path segments of every branch and receiver-connection segments, in order,
/// one call per [`TraceCounters::rays`]. The rays are the tracer's exact
/// hit-finding workload (the `render` bench replays them through bare BVH
/// traversal).
#[allow(clippy::too_many_arguments)]
pub fn trace_path_casts<T: Real>(
    st: &SceneT<T>,
    settings: &TraceSettings,
    tx: usize,
    el: usize,
    ray: u32,
    start_stack: MediumStack,
    out: impl FnMut(Deposit<T>),
    cast: impl FnMut(&Ray<T>, f64, f64),
) -> TraceCounters {
    trace(st, settings, tx, el, ray, start_stack, None, out, cast)
}

/// [`trace_path_from`] for a caller that drops every deposit arriving from
/// `horizon` on (the renderer and the gradient replay: past the records' last
/// sample): the work that can only produce such deposits is skipped (branches
/// and connections that certainly arrive later, see `PathCtx::late`); the
/// deposits that arrive earlier are the same, bit for bit.
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_path_within<T: Real>(
    st: &SceneT<T>,
    settings: &TraceSettings,
    tx: usize,
    el: usize,
    ray: u32,
    start_stack: MediumStack,
    horizon: Option<Horizon>,
    out: impl FnMut(Deposit<T>),
) -> TraceCounters {
    trace(
        st,
        settings,
        tx,
        el,
        ray,
        start_stack,
        horizon,
        out,
        |_, _, _| {},
    )
}

/// The path loop behind [`trace_path_casts`] and [`trace_path_within`].
#[allow(clippy::too_many_arguments)]
fn trace<T: Real>(
    st: &SceneT<T>,
    settings: &TraceSettings,
    tx: usize,
    el: usize,
    ray: u32,
    start_stack: MediumStack,
    horizon: Option<Horizon>,
    out: impl FnMut(Deposit<T>),
    cast: impl FnMut(&Ray<T>, f64, f64),
) -> TraceCounters {
    let mut ctx = PathCtx {
        st,
        settings,
        norm: T::from_f64(1.0 / settings.rays_per_element as f64),
        max_shift: st.max_shift,
        lobe: ReceiveLobe::new(st.main_lobe, st.cutoff),
        horizon,
        counters: TraceCounters::default(),
        out,
        cast,
    };
    let stratified_rays = match settings.sampler {
        Sampler::Stratified => settings.rays_per_element as u32,
        Sampler::Independent => 1,
    };
    let sampler =
        PathSampler::stratified(settings.seed, tx as u32, el as u32, ray, stratified_rays);
    // Step 1: emission from the element face, at the element's firing time.
    let kind = st.array.kind;
    let element = st.elements[el];
    let ux = sampler.uniform(0, dim::EMIT_X) - 0.5;
    let uy = sampler.uniform(0, dim::EMIT_Y) - 0.5;
    let origin = face_point(
        kind,
        &element,
        st.array.element_width_m,
        st.elevation,
        ux,
        uy,
    );
    let wave = st.transmits[tx];
    let c_img = st.imaging_sound_speed;
    let firing_time = wave.element_delay_s(element.centre_m, c_img);
    let (dir, w, time) = match st.emission {
        Emission::Cosine => {
            let dl = cosine_hemisphere(
                sampler.uniform(0, dim::EMIT_U1),
                sampler.uniform(0, dim::EMIT_U2),
            );
            let dir = from_element_frame(kind, &element, dl);
            // f_d(ω)/p(ω) with p = cos θ/π about the normal (constant in the
            // element's frame), normalised by π: value 1.
            let pdf = dl[2] / core::f64::consts::PI;
            if pdf <= 0.0 {
                return ctx.counters;
            }
            let w = transmit_directivity(kind, &element, dir)
                / T::from_f64(pdf * core::f64::consts::PI);
            // The element radiates as a whole at its firing time.
            (dir, w, firing_time)
        }
        Emission::PlaneWave => {
            // Along the wave's ray through the emission point, weight
            // f_d = n·ω (paper eq. `directivity`). A plane wave's rays are
            // parallel, so an element's beamlet returns onto one element's
            // width and the face offset from the ideal front (±(w/2)·sin θ/c)
            // averages out over the receiving face: its rays keep the
            // element's firing time. A curved wave's rays fan out (or in),
            // so one receiving element sees only part of an emitting face and
            // the offset would not average out (up to ±0.9 sample measured
            // on a convex array): each ray starts on the wave's front, at its
            // arrival time at the emission point (in the imaging plane).
            let dir = propagation_direction(&wave, origin);
            let time = match wave {
                TransmitWave::PlaneWave { .. } => firing_time,
                _ => wave.arrival_time_s([origin.x, origin.z], c_img),
            };
            (dir, transmit_directivity(kind, &element, dir), time)
        }
    };
    // Branches still to trace, depth first (at most one pending sibling per
    // vertex, so the stack stays shorter than `max_bounces + 2`).
    let mut pending = Vec::with_capacity(settings.max_bounces as usize + 2);
    pending.push(Branch {
        origin,
        dir,
        w,
        beta: T::zero(),
        time,
        stack: start_stack,
        specular_chain: true,
        last_rough: None,
        rough_vertices: 0,
        bounce: 1,
        sampler,
    });
    while let Some(b) = pending.pop() {
        ctx.trace_branch(b, &mut pending);
    }
    ctx.counters
}

/// The direction a transmitted wave travels at the point `p` of an element's
/// face: a plane wave along `(sin θ, 0, cos θ)`; a diverging wave away from
/// its virtual source `v`, along `(p − v)` in the imaging plane; a focused
/// wave towards its focus `f`, along `(f − p)` in that plane: the rays of the
/// wavefronts of [`TransmitWave::arrival_time_s`], so an element's rays fan
/// out or in with the wave and the elements' beamlets tile the field as a
/// plane wave's do. The delays of a 1-D array shape the wave in `xz` only
/// (CONTRACT §1's time models are 2-D): `v` and `f` are lines along `y`, and
/// no ray turns in elevation, as for a plane wave.
fn propagation_direction<T: Real>(wave: &TransmitWave<T>, p: Vec3<T>) -> Vec3<T> {
    let in_plane = |dx: T, dz: T| Vec3::new(dx, T::zero(), dz).normalize();
    match *wave {
        TransmitWave::PlaneWave { angle_rad } => {
            Vec3::new(angle_rad.sin(), T::zero(), angle_rad.cos())
        }
        TransmitWave::Diverging { source_m: [x, z] } => in_plane(p.x - x, p.z - z),
        TransmitWave::Focused { focus_m: [x, z] } => in_plane(x - p.x, z - p.z),
    }
}

impl<T: Real, F: FnMut(Deposit<T>), C: FnMut(&Ray<T>, f64, f64)> PathCtx<'_, T, F, C> {
    /// Trace branch `b` to its next interaction (steps 2–5 of the module docs)
    /// and push its continuations onto `pending`.
    fn trace_branch(&mut self, b: Branch<T>, pending: &mut Vec<Branch<T>>) {
        let st = self.st;
        let settings = self.settings;
        let n_el = st.n_elements;
        let Branch {
            origin,
            dir,
            mut w,
            mut beta,
            mut time,
            stack,
            specular_chain,
            last_rough,
            rough_vertices,
            bounce,
            sampler,
        } = b;
        let medium = *st.medium_of(stack.top());
        // Step 2: the next interface.
        let r = Ray::new(origin, dir);
        let hit = self.intersect(&r, f64::INFINITY);
        // The array's surface (the plane z = 0 or a convex arc), if reached.
        let t_array = array_surface_t(&st.array, origin, dir);
        let hit_first = hit.as_ref().is_some_and(|h| h.t.value() < t_array.value());
        let seg_len = match (&hit, hit_first) {
            (Some(h), true) => h.t.value(),
            _ => t_array.value(),
        };

        // Step 3a: volume scatterers along the segment.
        if let Some(obj) = stack.top() {
            if medium.scatterer_density_per_mm3.value() > 0.0 && seg_len.is_finite() {
                self.volume(
                    obj, &medium, stack, origin, dir, seg_len, w, beta, time, &sampler, bounce,
                );
            }
        }

        let Some(hit) = hit.filter(|_| hit_first) else {
            // Step 3b: escape, or arrival at the array plane.
            let direct = specular_chain || last_rough.is_some();
            if t_array.value().is_finite() && direct && stack.is_empty() {
                let p = r.at(t_array);
                let pv = p.value();
                if let Some(e) = element_at(&st.array, st.elevation, pv) {
                    let element = &st.elements[e];
                    // After a rough vertex: MIS against its receiver connection
                    // (density 1/(sel_w·Ω_e) of the element's solid angle).
                    let mis = match last_rough {
                        Some(p_b) if !specular_chain => {
                            let v = centre3(element) - origin;
                            let r2 = v.length_squared();
                            let cos_e =
                                -cos_to_normal(st.array.kind, &element.normal, v) / r2.sqrt();
                            let solid = st.array.element_width_m * st.elevation * cos_e / r2;
                            let sel_w = settings.receiver_weight(n_el, e);
                            power_heuristic(p_b, solid.scale(sel_w).recip())
                        }
                        _ => T::one(),
                    };
                    let fd = self
                        .lobe
                        .eval(-cos_to_normal(st.array.kind, &element.normal, dir));
                    let tau = time + t_array / medium.sound_speed;
                    let (k, b) = attenuation_and_exponent(
                        medium.attenuation_db_cm_mhz,
                        st.center_frequency,
                        t_array,
                    );
                    self.deposit(e, w * fd * mis * k, beta + b, tau);
                }
            }
            return;
        };

        // Step 4: advance to the interface.
        time += hit.t / medium.sound_speed;
        let (k, b) =
            attenuation_and_exponent(medium.attenuation_db_cm_mhz, st.center_frequency, hit.t);
        w *= k;
        beta += b;
        if bounce > settings.max_bounces {
            return;
        }
        // Whatever this vertex and its continuations deposit still has to reach
        // the array, at least `distance_bound_m` away: past the horizon, none
        // of it would be kept.
        let to_array = distance_bound_m(&st.array, hit.point.z.value());
        if self.vertex_late(time.value(), to_array) {
            return;
        }

        // Step 5: the interface between the current medium and the other side.
        let entering = hit.entering(&dir);
        let other = if entering {
            st.objects[hit.object].material
        } else {
            *st.medium_of(stack.after_exit(hit.object))
        };
        let iface = Interface {
            c1: medium.sound_speed,
            c2: other.sound_speed,
            z1: medium.impedance,
            z2: other.impedance,
            alpha: st.objects[hit.object].material.roughness,
        };
        let n_inc = if entering { hit.normal } else { -hit.normal };
        let wi = -dir;

        // The rough interface as seen from `wi`: BSDF and density terms shared by
        // every receiver connection and both continuations of this vertex.
        let incident = (iface.alpha.value() >= SMOOTH_ALPHA).then(|| iface.incident(wi, n_inc));

        // Step 5a: receiver connection from a rough interface.
        if let Some(inc) = &incident {
            let ue = sampler.uniform(bounce, dim::ELEMENT);
            let (p_v, n_v, time_v) = (hit.point.to_f64(), n_inc.to_f64(), time.value());
            for (e, sel_w) in settings.receivers(n_el, ue) {
                let Some(aim) = self.aim(p_v, e, time_v) else {
                    continue;
                };
                let transmitted = aim.wo.dot(n_v) < 0.0;
                if rough_vertices > 0 && transmitted {
                    // Transmission-side arrival after an earlier rough vertex:
                    // already counted by that vertex's connection through this
                    // boundary (module docs, "Double counting").
                    continue;
                }
                let link = self.link(hit.point, &aim);
                let (f_cos, p_b) = inc.eval_pdf(link.wo);
                if f_cos.value() != 0.0 {
                    // The connection leaves into the incident medium (reflection)
                    // or the other one (transmission).
                    let mut cstack = stack;
                    if transmitted {
                        cstack.cross(hit.object, entering);
                    }
                    self.connect(hit.point, cstack, w, beta, f_cos, time, &link, sel_w, p_b);
                }
            }
        }

        // Step 5b: split into the reflected and the transmitted continuation.
        let Some(s) = iface.scatter(
            wi,
            n_inc,
            sampler.uniform(bounce, dim::GGX_U1),
            sampler.uniform(bounce, dim::GGX_U2),
        ) else {
            return;
        };
        let rough = !s.specular;
        for (branch, lobe, reflected) in [(1, s.transmitted, false), (0, s.reflected, true)] {
            let Some(lobe) = lobe else { continue };
            let w_child = w * lobe.weight;
            if !w_child.is_finite() || w_child.value().abs() < MIN_BRANCH_AMPLITUDE {
                continue;
            }
            let mut child_stack = stack;
            if !reflected {
                child_stack.cross(hit.object, entering);
            }
            pending.push(Branch {
                origin: hit.point,
                dir: lobe.wo,
                w: w_child,
                beta,
                time,
                stack: child_stack,
                specular_chain: specular_chain && !rough,
                last_rough: incident
                    .as_ref()
                    .filter(|_| rough && (reflected || rough_vertices == 0))
                    .map(|inc| inc.eval_pdf(lobe.wo).1),
                rough_vertices: rough_vertices + u32::from(rough),
                bounce: bounce + 1,
                sampler: sampler.branch(branch),
            });
        }
    }
}
