//! A procedural heart-valve-like mesh: thin curved leaflets of a right
//! atrioventricular (tricuspid) valve whose closure is a parameter, after the
//! paper's open/closed valve example (its Fig. "heart_valve"; anatomy after
//! Skwarek et al. 2006, model after Mathur 2022). It is a geometric stand-in, not
//! an anatomical reconstruction.
//!
//! # Geometry (object frame, metres)
//! The annulus is the circle of radius `annulus_radius_m` in the plane `z = 0`
//! centred on the `z` axis; the valve opens towards `+z` (atrium at `z < 0`,
//! ventricle at `z > 0`). Leaflet `k` of `n` covers the annulus sector centred on
//! angle `2πk/n`. Along each meridian the leaflet's mid-surface is a straight
//! segment of length `L` from the annulus, tilted from the `+z` axis by the hinge
//! angle `φ = φ_open + closure·(φ_closed − φ_open)`:
//!
//! `ρ(s) = R − s sin φ`, `z(s) = s cos φ + bulge·(1 − u²)·sin(π s/L)`, `s ∈ [0, L]`,
//!
//! with `L = (R − ρ_min)/sin φ_closed`, so that when closed the free edges reach
//! radius `ρ_min` near the axis. Across the sector (`u ∈ [−1, 1]`) the angle is
//! `ψ = u·(π/n − asin(c/ρ))` with `c = gap_m/2 + thickness_m/2 + margin`, which keeps
//! neighbouring leaflets a constant distance ≥ `gap_m` apart at every radius (the
//! shells never intersect, even closed). Each leaflet is a **closed thin shell**:
//! the mid-surface offset by `±thickness_m/2` along its normal, joined by side
//! walls, wound outward, so it has an inside (leaflet tissue) and an outside.

use crate::{TriangleMesh, Vec3};
use usray_ad::Real;

/// Shape parameters of [`valve_leaflets`]. Lengths in metres, angles in degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValveParams {
    /// Number of leaflets (3 for the tricuspid valve).
    pub n_leaflets: usize,
    /// Annulus radius `R`, metres.
    pub annulus_radius_m: f64,
    /// Leaflet thickness, metres.
    pub thickness_m: f64,
    /// Minimum gap between neighbouring leaflets' surfaces, metres.
    pub gap_m: f64,
    /// Radius the free edges reach when closed, metres.
    pub min_radius_m: f64,
    /// Billowing of the leaflet belly towards `+z`, metres.
    pub bulge_m: f64,
    /// Hinge angle from the `+z` axis when open (`closure = 0`), degrees.
    pub open_angle_deg: f64,
    /// Hinge angle from the `+z` axis when closed (`closure = 1`), degrees.
    pub closed_angle_deg: f64,
    /// Mesh cells across each leaflet.
    pub cells_across: usize,
    /// Mesh cells from annulus to free edge.
    pub cells_along: usize,
}

impl Default for ValveParams {
    /// A tricuspid-sized valve: annulus radius 15 mm, leaflets 0.6 mm thick,
    /// 0.4 mm gaps, free edges reaching 2 mm from the axis when closed, 1.5 mm
    /// billowing, hinge 12° open / 80° closed, 24 × 16 cells per leaflet.
    fn default() -> Self {
        Self {
            n_leaflets: 3,
            annulus_radius_m: 0.015,
            thickness_m: 0.6e-3,
            gap_m: 0.4e-3,
            min_radius_m: 2.0e-3,
            bulge_m: 1.5e-3,
            open_angle_deg: 12.0,
            closed_angle_deg: 80.0,
            cells_across: 24,
            cells_along: 16,
        }
    }
}

/// The leaflets of a valve at closure state `openness ∈ [0, 1]`: **0 = fully
/// open, 1 = closed** (values outside are clamped; NaN counts as 0). Returns one
/// mesh holding all leaflets, each a closed, outward-wound thin shell (see the
/// module documentation), in the object frame (annulus in `z = 0`, opening to
/// `+z`), metres.
///
/// ```
/// use usray_geometry::valve::{valve_leaflets, ValveParams};
/// let open = valve_leaflets(0.0, &ValveParams::default());
/// let closed = valve_leaflets(1.0, &ValveParams::default());
/// open.assert_well_formed();
/// closed.assert_well_formed();
/// // Open leaflets hang deep into the ventricle; closed ones lie near the annulus.
/// assert!(open.bounds().1[2] > 2.0 * closed.bounds().1[2]);
/// ```
pub fn valve_leaflets(openness: f64, p: &ValveParams) -> TriangleMesh {
    let mut out = TriangleMesh::default();
    for m in valve_leaflet_meshes(openness, p) {
        out.append(&m);
    }
    out
}

/// The leaflets of [`valve_leaflets`] as separate meshes (one closed shell each),
/// e.g. to make each leaflet its own object.
pub fn valve_leaflet_meshes(openness: f64, p: &ValveParams) -> Vec<TriangleMesh> {
    let n = p.n_leaflets.max(1);
    (0..n)
        .map(|k| {
            let positions = leaflet_positions(theta_mid(k, n), closure_of(openness), p);
            let mut m = TriangleMesh {
                positions: positions.iter().map(|v| v.value()).collect(),
                triangles: leaflet_triangles(p),
            };
            m.orient_outward();
            m
        })
        .collect()
}

/// The vertex positions of [`valve_leaflets`] as differentiable functions of the
/// closure state, in the same order as `valve_leaflets(openness.value(), p)
/// .positions` (object frame, metres). Pair them with that mesh in
/// [`crate::MeshInstance::with_vertices`] so hit distances carry
/// `∂t/∂openness`. Inside `[0, 1]` the derivative flows (one-sided at the ends);
/// outside, the clamped value is a constant.
///
/// ```
/// use usray_ad::{Dual, Real};
/// use usray_geometry::valve::{valve_leaflet_positions, valve_leaflets, ValveParams};
/// let p = ValveParams::default();
/// let pos = valve_leaflet_positions(Dual::<1>::variable(0.5, 0), &p);
/// let mesh = valve_leaflets(0.5, &p);
/// assert_eq!(pos.len(), mesh.positions.len());
/// assert_eq!(pos[7].value(), mesh.positions[7]);
/// assert!(pos[7].z.eps[0] != 0.0); // vertices move as the valve closes
/// ```
pub fn valve_leaflet_positions<T: Real>(openness: T, p: &ValveParams) -> Vec<Vec3<T>> {
    let n = p.n_leaflets.max(1);
    let v = openness.value();
    let closure = if v.is_nan() || v < 0.0 {
        T::zero()
    } else if v > 1.0 {
        T::one()
    } else {
        openness
    };
    (0..n)
        .flat_map(|k| leaflet_positions(theta_mid(k, n), closure, p))
        .collect()
}

fn closure_of(openness: f64) -> f64 {
    if openness.is_nan() {
        0.0
    } else {
        openness.clamp(0.0, 1.0)
    }
}

fn theta_mid(k: usize, n: usize) -> f64 {
    2.0 * core::f64::consts::PI * k as f64 / n as f64
}

/// Mid-surface point of one leaflet at `(u ∈ [−1,1], v ∈ [0,1])`.
fn mid_surface<T: Real>(theta_mid: f64, closure: T, p: &ValveParams, u: f64, v: f64) -> Vec3<T> {
    let n = p.n_leaflets.max(1) as f64;
    let r = p.annulus_radius_m;
    let phi_o = p.open_angle_deg.to_radians();
    let phi_c = p.closed_angle_deg.to_radians();
    let phi = closure.scale(phi_c - phi_o) + T::from_f64(phi_o);
    let len = (r - p.min_radius_m) / phi_c.sin();
    let s = v * len;
    let rho = T::from_f64(r) - phi.sin().scale(s);
    let z = phi.cos().scale(s)
        + T::from_f64(p.bulge_m * (1.0 - u * u) * (core::f64::consts::PI * v).sin());
    let c = 0.5 * p.gap_m + 0.5 * p.thickness_m + 0.1 * p.thickness_m;
    let half = T::from_f64(core::f64::consts::PI / n) - (T::from_f64(c) / rho).min(T::one()).asin();
    let psi = half.max(T::zero()).scale(u) + T::from_f64(theta_mid);
    Vec3::new(rho * psi.cos(), rho * psi.sin(), z)
}

/// Vertices of one leaflet shell: the top grid (mid-surface + normal·t/2), then
/// the bottom grid (mid-surface − normal·t/2), each `(cells_across+1) ×
/// (cells_along+1)`, row-major in `v`.
fn leaflet_positions<T: Real>(theta_mid: f64, closure: T, p: &ValveParams) -> Vec<Vec3<T>> {
    let nu = p.cells_across.max(1);
    let nv = p.cells_along.max(1);
    let f = |u: f64, v: f64| mid_surface(theta_mid, closure, p, u, v);
    let (du, dv) = (1e-6, 1e-6);
    let n_grid = (nu + 1) * (nv + 1);
    let mut positions = vec![Vec3::zero(); 2 * n_grid];
    for j in 0..=nv {
        for i in 0..=nu {
            let u = -1.0 + 2.0 * i as f64 / nu as f64;
            let v = j as f64 / nv as f64;
            let pm = f(u, v);
            // Surface normal from central (one-sided at the border) differences.
            let (u0, u1) = ((u - du).max(-1.0), (u + du).min(1.0));
            let (v0, v1) = ((v - dv).max(0.0), (v + dv).min(1.0));
            let pu = f(u1, v) - f(u0, v);
            let pv = f(u, v1) - f(u, v0);
            let offset = pu.cross(pv).normalize().scale(0.5 * p.thickness_m);
            let id = j * (nu + 1) + i;
            positions[id] = pm + offset;
            positions[n_grid + id] = pm - offset;
        }
    }
    positions
}

/// Triangles of one leaflet shell (top, bottom, side walls), top wound along
/// `∂u × ∂v`.
fn leaflet_triangles(p: &ValveParams) -> Vec<[u32; 3]> {
    let nu = p.cells_across.max(1);
    let nv = p.cells_along.max(1);
    let idx = |i: usize, j: usize| (j * (nu + 1) + i) as u32;
    let n_grid = (nu + 1) * (nv + 1);
    let top = |i, j| idx(i, j);
    let bot = |i, j| idx(i, j) + n_grid as u32;
    let mut triangles = Vec::with_capacity(4 * nu * nv + 4 * (nu + nv));
    for j in 0..nv {
        for i in 0..nu {
            let (a, b, c, d) = (top(i, j), top(i + 1, j), top(i + 1, j + 1), top(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
            let (a, b, c, d) = (bot(i, j), bot(i + 1, j), bot(i + 1, j + 1), bot(i, j + 1));
            triangles.push([a, c, b]);
            triangles.push([a, d, c]);
        }
    }
    // Boundary loop in the top surface's orientation: v = 0 (u up), u = 1 (v up),
    // v = 1 (u down), u = −1 (v down).
    let mut loop_ij = Vec::with_capacity(2 * (nu + nv));
    loop_ij.extend((0..nu).map(|i| (i, 0)));
    loop_ij.extend((0..nv).map(|j| (nu, j)));
    loop_ij.extend((1..=nu).rev().map(|i| (i, nv)));
    loop_ij.extend((1..=nv).rev().map(|j| (0, j)));
    for e in 0..loop_ij.len() {
        let (ia, ja) = loop_ij[e];
        let (ib, jb) = loop_ij[(e + 1) % loop_ij.len()];
        let (ta, tb, ba, bb) = (top(ia, ja), top(ib, jb), bot(ia, ja), bot(ib, jb));
        triangles.push([tb, ta, ba]);
        triangles.push([tb, ba, bb]);
    }
    triangles
}

/// The valve meshes shipped in `scenes/meshes/` (file stem, closure state), all
/// with [`ValveParams::default`]; regenerate with
/// `cargo run -p usray-geometry --example write_valve_meshes`.
pub const SCENE_VALVES: [(&str, f64); 3] = [
    ("valve_open", 0.0),
    ("valve_half", 0.5),
    ("valve_closed", 1.0),
];

/// The header comment written into a shipped valve OBJ.
pub fn scene_valve_comment(closure: f64) -> String {
    format!(
        "usray procedural tricuspid-valve leaflets (usray_geometry::valve::valve_leaflets)\n\
         openness (closure) = {closure} (0 open, 1 closed), ValveParams::default()\n\
         units: metres; annulus radius 15 mm in the plane z = 0, centred on the z axis; opens towards +z\n\
         three closed thin shells (0.6 mm thick), wound outward"
    )
}
