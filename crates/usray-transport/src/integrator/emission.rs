//! Step 1 of the path loop: the primary branch leaves a point of the element's
//! face, in a direction set by `acquisition.emission`, at the time the
//! transmit's wave leaves that point; with `acquisition.edge_waves`, an end
//! element's path also sends the aperture's edge waves ([`super::edge`]).

use super::branch::Branch;
use super::edge::EdgeWaves;
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

/// Step 1: push the branches the path (transmit `tx`, emitting element `el`,
/// ray index `ray`) starts with, in the element's medium stack
/// `start_stack`: an end element's edge-wave branches, if the scene models
/// them, then the primary branch (none when its sampled direction has no
/// density: a cosine sample in the face's plane), so that it is traced first.
#[inline]
pub(super) fn emit<T: Real>(
    st: &SceneT<T>,
    settings: &TraceSettings,
    tx: usize,
    el: usize,
    ray: u32,
    start_stack: MediumStack,
    mut push: impl FnMut(Branch<T>),
) {
    let stratified_rays = match settings.sampler {
        Sampler::Stratified => settings.rays_per_element as u32,
        Sampler::Independent => 1,
    };
    let sampler =
        PathSampler::stratified(settings.seed, tx as u32, el as u32, ray, stratified_rays);
    if let Some(edges) = st.edge_waves {
        emit_edges(st, &edges, tx, el, &sampler, start_stack, &mut push);
    }
    if let Some(primary) = emit_primary(st, tx, el, sampler, start_stack) {
        push(primary);
    }
}

/// The primary branch of the path, or `None` when its sampled direction has
/// no density.
#[inline]
fn emit_primary<T: Real>(
    st: &SceneT<T>,
    tx: usize,
    el: usize,
    sampler: PathSampler,
    start_stack: MediumStack,
) -> Option<Branch<T>> {
    // Emission from the element face, at the element's firing time.
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

/// The edge-wave branches of an end element's path (element 0's left edge,
/// the last element's right; [`super::edge`]):
/// [`EdgeWaves::rays_per_edge`] rays from each edge this element ends, their
/// directions stratified over the element's rays and these sub-rays
/// together, each on a branch key of its own under the path's `sampler`.
#[inline]
fn emit_edges<T: Real>(
    st: &SceneT<T>,
    edges: &EdgeWaves<T>,
    tx: usize,
    el: usize,
    sampler: &PathSampler,
    start_stack: MediumStack,
    push: &mut impl FnMut(Branch<T>),
) {
    let last = st.n_elements - 1;
    // (side, branch key): the outward tangent is `side` times the element's.
    let ends = [(-1.0, 2), (1.0, 3)]
        .into_iter()
        .filter(|&(side, _)| (side < 0.0 && el == 0) || (side > 0.0 && el == last));
    let kind = st.array.kind;
    let element = st.elements[el];
    let wave = st.transmits[tx];
    let n_sub = edges.rays_per_edge();
    let per_ray = T::from_f64(1.0 / f64::from(n_sub));
    for (side, key) in ends {
        let edge_sampler = sampler.branch(key);
        let origin = face_point(
            kind,
            &element,
            st.array.element_width_m,
            st.elevation,
            0.5 * side,
            0.0,
        );
        // The wave's direction at the edge, in the element's frame.
        let t = propagation_direction(&wave, origin);
        let sin_theta = along_width(kind, &element.normal, t);
        let cos_theta = cos_to_normal(kind, &element.normal, t);
        let time =
            wave.arrival_time_s([origin.x, origin.z], st.imaging_sound_speed) + edges.delay_s();
        let u_ray = edge_sampler.uniform(0, dim::EMIT_U1);
        for m in 0..n_sub {
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
                edge_sampler.branch(16 + m),
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
