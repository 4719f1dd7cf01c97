//! Step 1 of the path loop: the primary branch leaves a point of the element's
//! face, in a direction set by `acquisition.emission`, at the time the
//! transmit's wave leaves that point.

use super::branch::Branch;
use super::settings::TraceSettings;
use super::spreading::Spread;
use crate::probe::{
    along_width, cos_to_normal, cosine_hemisphere, face_point, from_element_frame,
    from_element_frame_xz, transmit_directivity,
};
use crate::rng::{dim, PathSampler};
use crate::scene::{Emission, Sampler, SceneT};
use usray_ad::Real;
use usray_geometry::{MediumStack, Vec3};
use usray_signal::transmit::TransmitWave;

/// Step 1: the primary branch of the path (transmit `tx`, emitting element
/// `el`, ray index `ray`) in the element's medium stack `start_stack`, or
/// `None` when its sampled direction has no density (a cosine sample in the
/// face's plane).
#[inline]
pub(super) fn emit<T: Real>(
    st: &SceneT<T>,
    settings: &TraceSettings,
    tx: usize,
    el: usize,
    ray: u32,
    start_stack: MediumStack,
) -> Option<Branch<T>> {
    let sampler = path_sampler(settings, tx, el, ray);
    // Step 1: emission from the element face, at the element's firing time.
    let kind = st.array.kind;
    let element = st.elements[el];
    let ux = sampler.uniform(0, dim::EMIT_X) - 0.5;
    // In 2-D every ray leaves the element's centre line (`y = 0`).
    let uy = if st.planar {
        0.0
    } else {
        sampler.uniform(0, dim::EMIT_Y) - 0.5
    };
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
    let (dir, w, time, tube) = match st.emission {
        Emission::Cosine => {
            let (u1, u2) = (
                sampler.uniform(0, dim::EMIT_U1),
                sampler.uniform(0, dim::EMIT_U2),
            );
            // f_d(ω)/p(ω) with p = cos θ/π about the normal (1/sr), normalised
            // by π: value 1. In 2-D, p = cos θ/2 (1/rad: `sin θ` uniform),
            // normalised by 2.
            let (dl, pdf, norm) = if st.planar {
                let s = 2.0 * u1 - 1.0;
                let c = (1.0 - s * s).max(0.0).sqrt();
                ([s, 0.0, c], c / 2.0, 2.0)
            } else {
                let dl = cosine_hemisphere(u1, u2);
                (dl, dl[2] / core::f64::consts::PI, core::f64::consts::PI)
            };
            let dir = from_element_frame(kind, &element, dl);
            if pdf <= 0.0 {
                return None;
            }
            let w = transmit_directivity(kind, &element, dir) / T::from_f64(pdf * norm);
            // The element radiates as a whole at its firing time.
            (dir, w, firing_time, Spread::point_source())
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
            let tube = Spread::wavefront(front_curvature(&wave, origin));
            (dir, transmit_directivity(kind, &element, dir), time, tube)
        }
    };
    Some(emitted(
        origin,
        dir,
        w,
        time,
        start_stack,
        st.planar.then_some(tube),
        sampler,
    ))
}

/// The random numbers of path `ray` of element `el` in transmit `tx`,
/// stratified with the element's other rays when the sampler is.
fn path_sampler(settings: &TraceSettings, tx: usize, el: usize, ray: u32) -> PathSampler {
    let stratified_rays = match settings.sampler {
        Sampler::Stratified => settings.rays_per_element as u32,
        Sampler::Independent => 1,
    };
    PathSampler::stratified(settings.seed, tx as u32, el as u32, ray, stratified_rays)
}

/// A branch leaving the array: before its first interaction, every one so
/// far a delta lobe, no attenuation yet.
fn emitted<T: Real>(
    origin: Vec3<T>,
    dir: Vec3<T>,
    w: T,
    time: T,
    stack: MediumStack,
    spread: Option<Spread<T>>,
    sampler: PathSampler,
) -> Branch<T> {
    Branch {
        origin,
        dir,
        w,
        beta: T::zero(),
        time,
        stack,
        specular_chain: true,
        last_rough: None,
        rough_vertices: 0,
        spread,
        bounce: 1,
        sampler,
    }
}

/// Step 1, edge waves: the branches that the outer edges of an end element's
/// face (element 0's left, the last element's right) emit besides its primary
/// branch, when the scene models the aperture's edge waves
/// ([`super::edge`]): [`super::edge::EdgeWaves::rays_per_edge`] rays from each edge this
/// element ends, their directions stratified over the element's rays and
/// these sub-rays together, each on a branch key of its own.
#[inline]
pub(super) fn emit_edges<T: Real>(
    st: &SceneT<T>,
    settings: &TraceSettings,
    tx: usize,
    el: usize,
    ray: u32,
    start_stack: MediumStack,
    mut push: impl FnMut(Branch<T>),
) {
    let Some(edges) = st.edge_waves else {
        return;
    };
    let last = st.n_elements - 1;
    // (side, branch key): the outward tangent is `side` times the element's.
    let ends = [(-1.0, 2), (1.0, 3)]
        .into_iter()
        .filter(|&(side, _)| (side < 0.0 && el == 0) || (side > 0.0 && el == last));
    let n_sub = edges.rays_per_edge();
    let per_ray = T::from_f64(1.0 / f64::from(n_sub));
    for (side, key) in ends {
        let ray_sampler = path_sampler(settings, tx, el, ray).branch(key);
        let kind = st.array.kind;
        let element = st.elements[el];
        let origin = face_point(
            kind,
            &element,
            st.array.element_width_m,
            st.elevation,
            0.5 * side,
            0.0,
        );
        let wave = st.transmits[tx];
        // The wave's direction at the edge, in the element's frame.
        let t = propagation_direction(&wave, origin);
        let sin_theta = along_width(kind, &element.normal, t);
        let cos_theta = cos_to_normal(kind, &element.normal, t);
        let time =
            wave.arrival_time_s([origin.x, origin.z], st.imaging_sound_speed) + edges.delay_s();
        let u_ray = ray_sampler.uniform(0, dim::EMIT_U1);
        for m in 0..n_sub {
            let sampler = ray_sampler.branch(16 + m);
            let u = (f64::from(m) + u_ray) / f64::from(n_sub);
            let Some((sin_psi, pdf)) = edges.sample(sin_theta, side, u) else {
                continue;
            };
            let cos_psi = (T::one() - sin_psi * sin_psi).max(T::zero()).sqrt();
            let dir = from_element_frame_xz(kind, &element, sin_psi, cos_psi);
            // u = τ·(t − d), τ = side · tangent.
            let u = (sin_theta - sin_psi).scale(side);
            let w = edges.amplitude(cos_theta.max(T::zero()), u) / pdf * per_ray;
            push(emitted(
                origin,
                dir,
                w,
                time,
                start_stack,
                Some(Spread::point_source()),
                sampler,
            ));
        }
    }
}

/// The in-plane curvature (1/m, positive diverging) of the transmitted
/// wave's front at the point `p` of an element's face: 0 for a plane wave,
/// `1/|p − v|` for a diverging wave from `v`, `−1/|f − p|` for a wave focused
/// at `f` (the fronts of [`TransmitWave::arrival_time_s`]).
fn front_curvature<T: Real>(wave: &TransmitWave<T>, p: Vec3<T>) -> T {
    let distance = |dx: T, dz: T| (dx * dx + dz * dz).sqrt();
    match *wave {
        TransmitWave::PlaneWave { .. } => T::zero(),
        TransmitWave::Diverging { source_m: [x, z] } => distance(p.x - x, p.z - z).recip(),
        TransmitWave::Focused { focus_m: [x, z] } => -distance(x - p.x, z - p.z).recip(),
    }
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
