//! Tunnelling through a thin wall beyond its critical angle (`thin_layer`),
//! seen in the rays a render casts.
//!
//! A plane wave at 0° sends vertical rays at a ring; a ray at lateral offset
//! `b` from the ring's axis meets the outer surface at `sin θ = b/R`. With
//! concentric circles and the same water inside and out, the ray model keeps
//! `b` (Bouguer's invariant `r·sin θ/c`) through every refraction, so a ray
//! refracted into the lumen has `b < (c_water/c_wall)·R`, the critical
//! offset: beyond it the outer surface reflects totally. Only a ray that
//! tunnels through the wall reaches the lumen from further out, and it keeps
//! its direction where a refracted one bends.

mod common;
use common::{for_each_cast, plane_wave_scene};

const R_OUT: f64 = 3.0e-3;
const WALL: f64 = 0.15e-3;
const Z_CENTRE: f64 = 12.0e-3;

/// Every ray cast inside the lumen of a smooth thin ring (0.15 mm thick,
/// 1700 m/s in 1540 m/s water, at 5 MHz), 2-D, as (impact parameter `b`,
/// direction), with `acquisition.thin_layer_tunnelling` as given.
fn lumen_rays(tunnelling: bool) -> Vec<(f64, [f64; 3])> {
    let body = format!(
        "[materials.wall]\nimpedance_mrayl = 1.8\nsound_speed_m_s = 1700.0\nroughness = 0.0\n\n\
         [[objects]]\nname = \"tube\"\nshape = \"cylinder\"\ncenter_m = [0.0, 0.0, {Z_CENTRE}]\n\
         radius_m = {R_OUT}\nthickness_m = {WALL}\nmaterial = \"wall\"\n"
    );
    let mut s = plane_wave_scene(true, 64, &body);
    s.acquisition.thin_layer_tunnelling = tunnelling;
    let r_in = R_OUT - WALL;
    let mut out = Vec::new();
    for_each_cast(&s, |r| {
        let (x, z) = (r.origin.x, r.origin.z - Z_CENTRE);
        if (x * x + z * z).sqrt() < r_in + 1e-9 {
            let b = (x * r.dir.z - z * r.dir.x).abs();
            out.push((b, [r.dir.x, r.dir.y, r.dir.z]));
        }
    });
    out
}

#[test]
fn rays_beyond_the_critical_offset_tunnel_into_a_thin_lumen() {
    let r_in = R_OUT - WALL;
    let critical = 1540.0 / 1700.0 * R_OUT;
    let rays = lumen_rays(true);
    // Refraction bends every ray off the axis; a tunnelled ray keeps its
    // direction and resumes on the inner surface on the radius through its
    // hit, at offset `b·r_in/R`.
    let (vertical, bent): (Vec<_>, Vec<_>) = rays
        .iter()
        .filter(|(b, _)| *b > 1e-6)
        .partition(|(_, d)| (d[2] - 1.0).abs() < 1e-12);
    eprintln!(
        "{} bent, {} vertical lumen rays",
        bent.len(),
        vertical.len()
    );
    assert!(bent.len() > 100, "{} bent lumen rays", bent.len());
    assert!(
        vertical.len() > 10,
        "{} vertical lumen rays",
        vertical.len()
    );
    for (b, _) in &vertical {
        let at_outer = b * R_OUT / r_in;
        assert!(at_outer > critical && at_outer < R_OUT, "offset {at_outer}");
    }
    // Up to near grazing: at b = 0.99 R (82°) a sixth of the energy crosses.
    let widest = vertical
        .iter()
        .map(|(b, _)| b * R_OUT / r_in)
        .fold(0.0, f64::max);
    assert!(widest > 0.99 * R_OUT, "widest {widest}");
}

#[test]
fn without_tunnelling_every_lumen_ray_is_refracted() {
    // The default: the wall reflects totally beyond its critical angle, so no
    // ray reaches the lumen unbent off the axis.
    let vertical = lumen_rays(false)
        .iter()
        .filter(|(b, d)| *b > 1e-6 && (d[2] - 1.0).abs() < 1e-12)
        .count();
    assert_eq!(vertical, 0);
}
