//! One primary path: the public entry points, and the path loop that traces
//! the emitted branch and every continuation it splits into, depth first.

use super::context::PathCtx;
use super::emission::emit;
use super::horizon::Horizon;
use super::responses::Responses;
use super::settings::TraceSettings;
use super::{Deposit, TraceCounters};
use crate::probe::centre3;
use crate::scene::SceneT;
use usray_ad::Real;
use usray_geometry::{MediumStack, Ray};

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
    let mut responses = Responses::new();
    trace(
        st,
        settings,
        tx,
        el,
        ray,
        start_stack,
        None,
        &mut responses,
        out,
        cast,
    )
}

/// [`trace_path_from`] for a caller that drops every deposit arriving from
/// `horizon` on (the renderer and the gradient replay: past the records' last
/// sample): the work that can only produce such deposits is skipped (branches
/// and connections that certainly arrive later, see `PathCtx::late`); the
/// deposits that arrive earlier are the same, bit for bit. The volume
/// scatterers' receiver responses are kept in `responses` for the caller's
/// next paths ([`super::responses`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_path_within<T: Real>(
    st: &SceneT<T>,
    settings: &TraceSettings,
    tx: usize,
    el: usize,
    ray: u32,
    start_stack: MediumStack,
    horizon: Option<Horizon>,
    responses: &mut Responses<T>,
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
        responses,
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
    responses: &mut Responses<T>,
    out: impl FnMut(Deposit<T>),
    cast: impl FnMut(&Ray<T>, f64, f64),
) -> TraceCounters {
    let mut ctx = PathCtx {
        st,
        settings,
        norm: T::from_f64(1.0 / settings.rays_per_element as f64),
        max_shift: st.max_shift,
        receiver: st.receiver,
        horizon,
        counters: TraceCounters::default(),
        responses,
        out,
        cast,
    };
    // Branches still to trace, depth first (at most one pending sibling per
    // vertex, so the stack stays shorter than `max_bounces + 2`; an end
    // element's edge-wave branches, emitted first, add their number).
    let mut pending = Vec::with_capacity(settings.max_bounces as usize + 2);
    emit(st, settings, tx, el, ray, start_stack, |b| pending.push(b));
    while let Some(b) = pending.pop() {
        ctx.trace_branch(b, &mut pending);
    }
    ctx.counters
}
