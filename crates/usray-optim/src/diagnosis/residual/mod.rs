//! Where the residual of a calibrated fit lies (`usray diagnose`, step 2 "Where").
//!
//! Inputs: the calibrated simulated B-mode `I` and the measured B-mode `R`, both
//! `[nz, nx]` row-major grey levels in `[0, 1]` on the scene's `[imaging]` grid
//! ([`crate::grid_shape`]; pixel `(iz, ix)` is at `x_m[ix]`, `z_m[iz]` of
//! `scene.imaging_settings().grid()`), and the scene itself.
//!
//! ## Per-pixel loss
//! Under the fit's loss ([`L1L2`]) pixel `u` contributes
//!
//! `c_u = (λ₁ |d_u| + λ₂ d_u²) / N_pix`, `d_u = I_u − R_u` (dimensionless),
//!
//! so that `Σ_u c_u = L` exactly. The share of a region `A` is
//! `s_A = Σ_{u∈A} c_u / L`; regions of one partition are disjoint and cover the
//! image, so their shares sum to 1 (all shares are 0 when `L = 0`: there is no
//! residual to place).
//!
//! ## Regions (three partitions)
//! * `"object"`: for each object `objects.NAME`, `"boundary of objects.NAME"` =
//!   pixels whose distance to the object's surface is at most the band half-width
//!   `b` (default one pulse length `b = cycles · c / (2 f_c)`, `c` the speed the
//!   beamformer assumes, metres), `"inside objects.NAME"` = pixels inside the
//!   object beyond the band, and `"outside all objects"` = the rest. Geometry is
//!   evaluated at the image plane `y = 0`, at pixel positions `(x_m, 0, z_m)`
//!   taken as scene coordinates (see [`ObjectMasks`] for each shape). A pixel in
//!   several bands belongs to the boundary of the nearest surface; a pixel inside
//!   several objects (and in no band) belongs to the one with the fewest inside
//!   pixels in the image (the most specific: a cylinder within a half-space);
//!   ties go to the first object in file order.
//! * `"depth"`: bands `[k w, (k+1) w)` of depth `z` (default `w = 5 mm`), aligned
//!   to multiples of `w`, labelled by the part the image covers, e.g.
//!   `"depth 10.0–15.0 mm"`.
//! * `"lateral"`: the same in `x` (aligned to multiples of `w` from `x = 0`),
//!   e.g. `"lateral -5.0–0.0 mm"`.
//!
//! ## Kinds of residual
//! Grey level `g ∈ [0, 1]` maps to level `dB(g) = (g − 1) · D` (dB re the image
//! maximum; `D = imaging.dynamic_range_db`) and envelope amplitude
//! `E(g) = 10^{(g − 1) D / 20}` (relative, `E ∈ [10^{−D/20}, 1]`), inverting the
//! log compression of `usray_signal::post` (clipped pixels, `g = 0`, are at the
//! floor: their true level is lower). See [`EchoPosition`], [`EchoAmplitude`],
//! [`Texture`] and [`BoundaryWidth`] for the formulas. Lengths are in metres
//! (CONTRACT: SI everywhere; region labels show millimetres for reading).
//!
//! ```
//! use usray_optim::residual::{analyse_residual, ResidualOptions};
//! let text = include_str!("../../../../../scenes/cylinder.toml");
//! let scene = usray_transport::Scene::from_toml_str(text, "cylinder.toml", ".").unwrap();
//! let (nz, nx) = usray_optim::grid_shape(&scene).unwrap();
//! let measured = vec![0.2; nz * nx];
//! let mut simulated = measured.clone();
//! simulated[(nz / 2) * nx + nx / 2] = 0.9; // one pixel at the cylinder's centre
//! let report = analyse_residual(&scene, &simulated, &measured, &ResidualOptions::default()).unwrap();
//! let top = report.shares.iter().find(|s| s.partition == "object").unwrap();
//! assert_eq!(top.region, "inside objects.cylinder");
//! assert!((top.share - 1.0).abs() < 1e-12);
//! ```

mod kinds;
mod map;
mod regions;

pub use kinds::{BoundaryWidth, EchoAmplitude, EchoPosition, GreyStats, Texture};
pub use map::{residual_scale, signed_residual_rgb, SignedResidualMap};
pub use regions::{
    default_band_m, pixel_contributions, region_shares, scene_regions, ObjectMasks, Partition,
    Regions,
};

use crate::{OptimError, L1L2};
use kinds::{axial_shift, boundary_fwhm, envelope, grey_stats};
use regions::axis_spacing;
use serde::Serialize;
use usray_transport::Scene;

/// Settings of [`analyse_residual`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResidualOptions {
    /// The image loss whose per-pixel terms are shared out (the fit's loss).
    pub loss: L1L2,
    /// Half-width `b` of a boundary band, metres; `None` = one pulse length
    /// `cycles · c / (2 f_c)` of the scene's probe at the beamformer's speed `c`.
    pub band_m: Option<f64>,
    /// Width of a depth band, metres (default 5 mm).
    pub depth_band_m: f64,
    /// Width of a lateral band, metres (default 5 mm).
    pub lateral_band_m: f64,
    /// Largest axial shift searched by the echo-position estimate, metres
    /// (default 2 mm).
    pub max_shift_m: f64,
}

impl Default for ResidualOptions {
    fn default() -> Self {
        Self {
            loss: L1L2::default(),
            band_m: None,
            depth_band_m: 5e-3,
            lateral_band_m: 5e-3,
            max_shift_m: 2e-3,
        }
    }
}

/// A region's share of the loss.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RegionShare {
    /// Region label, e.g. `"inside objects.cylinder"`, `"depth 10.0–15.0 mm"`.
    pub region: String,
    /// The partition it belongs to: `"object"`, `"depth"` or `"lateral"`.
    pub partition: String,
    /// `s_A = Σ_{u∈A} c_u / L` (dimensionless, in `[0, 1]`; 0 when `L = 0`).
    pub share: f64,
    /// Number of pixels in the region.
    pub pixels: usize,
}

/// Everything [`analyse_residual`] finds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ResidualReport {
    /// The loss `L = Σ_u c_u` (equal to [`L1L2::value`] up to rounding).
    pub loss: f64,
    /// Boundary band half-width `b` used, metres.
    pub band_m: f64,
    /// Region shares: partition `"object"`, then `"depth"`, then `"lateral"`,
    /// largest share first within each.
    pub shares: Vec<RegionShare>,
    /// Axial echo shift per object boundary band, then over the whole image.
    pub echo_position: Vec<EchoPosition>,
    /// Echo amplitude per object boundary band.
    pub echo_amplitude: Vec<EchoAmplitude>,
    /// Texture inside each object, then outside all objects.
    pub texture: Vec<Texture>,
    /// Boundary echo width per object.
    pub boundary_width: Vec<BoundaryWidth>,
    /// Caveats (approximate geometry, objects absent from the image, …).
    pub notes: Vec<String>,
}

fn invalid(msg: String) -> OptimError {
    OptimError::Diagnosis(msg)
}

fn check_options(o: &ResidualOptions) -> Result<(), OptimError> {
    let pos = |name: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(invalid(format!(
                "{name} must be a positive number of metres, found {v}"
            )))
        }
    };
    if let Some(b) = o.band_m {
        pos("band_m", b)?;
    }
    pos("depth_band_m", o.depth_band_m)?;
    pos("lateral_band_m", o.lateral_band_m)?;
    pos("max_shift_m", o.max_shift_m)?;
    let (l1, l2) = (o.loss.lambda1, o.loss.lambda2);
    if !(l1.is_finite() && l2.is_finite() && l1 >= 0.0 && l2 >= 0.0) {
        return Err(invalid(format!(
            "loss weights must be finite and ≥ 0, found λ₁ = {l1}, λ₂ = {l2}"
        )));
    }
    Ok(())
}

/// Checks that both images have the grid's `nz · nx` pixels and finite values in
/// `[0, 1]`.
///
/// # Errors
/// [`OptimError::Diagnosis`] naming the image, the shapes, or the first bad pixel.
pub fn check_images(
    simulated: &[f64],
    measured: &[f64],
    nz: usize,
    nx: usize,
) -> Result<(), OptimError> {
    for (name, img) in [("simulated", simulated), ("measured", measured)] {
        if img.len() != nz * nx {
            return Err(invalid(format!(
                "the {name} B-mode has {} pixels; the imaging grid [nz, nx] = [{nz}, {nx}] has {}",
                img.len(),
                nz * nx
            )));
        }
        if let Some(u) = img
            .iter()
            .position(|v| !(v.is_finite() && (0.0..=1.0).contains(v)))
        {
            return Err(invalid(format!(
                "the {name} B-mode has {} at pixel (iz, ix) = ({}, {}); grey levels must be finite and in [0, 1]",
                img[u],
                u / nx.max(1),
                u % nx.max(1)
            )));
        }
    }
    Ok(())
}

/// Where the residual between the calibrated `simulated` B-mode and the `measured`
/// one lies, and what kind it is (see the module docs).
///
/// # Errors
/// [`OptimError::Diagnosis`] for images that do not match the scene's grid or hold
/// values outside `[0, 1]` (NaN included) and for bad options; scene errors for an
/// invalid imaging grid or an unreadable mesh.
pub fn analyse_residual(
    scene: &Scene,
    simulated: &[f64],
    measured: &[f64],
    opts: &ResidualOptions,
) -> Result<ResidualReport, OptimError> {
    check_options(opts)?;
    let (nz, nx) = crate::grid_shape(scene)?;
    check_images(simulated, measured, nz, nx)?;
    let reg = scene_regions(scene, opts)?;
    let contrib = pixel_contributions(&opts.loss, simulated, measured);
    let loss: f64 = contrib.iter().sum();
    let shares = region_shares(&contrib, &reg.partitions);
    let d = scene.imaging.dynamic_range_db;
    let pixel = scene.imaging.pixel_m;
    let dz = axis_spacing(&reg.z_m, pixel);
    let max_lag = (opts.max_shift_m / dz).round().max(1.0) as usize;
    let mut notes = Vec::new();
    if (scene.imaging_sound_speed() - scene.medium.sound_speed_m_s).abs() > 1e-9 {
        notes.push(format!(
            "the beamformer assumes c = {} m/s, the medium has {} m/s: objects are placed at their scene coordinates, so echoes are expected displaced from their bands",
            scene.imaging_sound_speed(),
            scene.medium.sound_speed_m_s
        ));
    }
    let mut echo_position = Vec::new();
    let mut echo_amplitude = Vec::new();
    let mut boundary_width = Vec::new();
    for o in &reg.objects {
        let region = format!("boundary of objects.{}", o.name);
        if o.approximate {
            notes.push(format!(
                "objects.{} is a mesh: its band and inside come from the inside mask at y = 0 (surface distance to half a pixel)",
                o.name
            ));
        }
        let idx: Vec<usize> = (0..nz * nx).filter(|&u| o.band[u]).collect();
        if idx.is_empty() && !o.inside.iter().any(|&b| b) {
            notes.push(format!(
                "objects.{} does not reach the image plane y = 0 within the imaging grid",
                o.name
            ));
        }
        let sh = axial_shift(simulated, measured, nz, nx, Some(&o.band), max_lag);
        echo_position.push(EchoPosition {
            region: region.clone(),
            shift_m: sh.map(|s| s.0 * dz),
            correlation: sh.map(|s| s.1),
            at_search_limit: sh.is_some_and(|s| s.2),
        });
        let (mean_db, energy_db) = if idx.is_empty() {
            (None, None)
        } else {
            let n = idx.len() as f64;
            let mean = idx.iter().map(|&u| simulated[u] - measured[u]).sum::<f64>() / n;
            let es: f64 = idx.iter().map(|&u| envelope(simulated[u], d).powi(2)).sum();
            let em: f64 = idx.iter().map(|&u| envelope(measured[u], d).powi(2)).sum();
            (Some(d * mean), Some(10.0 * (es / em).log10()))
        };
        echo_amplitude.push(EchoAmplitude {
            region: region.clone(),
            pixels: idx.len(),
            mean_db_difference: mean_db,
            energy_db_difference: energy_db,
        });
        let (sw, sc) = boundary_fwhm(simulated, &o.band, nz, nx, dz, d);
        let (mw, mc) = boundary_fwhm(measured, &o.band, nz, nx, dz, d);
        boundary_width.push(BoundaryWidth {
            region,
            simulated_fwhm_m: sw,
            measured_fwhm_m: mw,
            simulated_columns: sc,
            measured_columns: mc,
        });
    }
    let sh = axial_shift(simulated, measured, nz, nx, None, max_lag);
    echo_position.push(EchoPosition {
        region: "whole image".into(),
        shift_m: sh.map(|s| s.0 * dz),
        correlation: sh.map(|s| s.1),
        at_search_limit: sh.is_some_and(|s| s.2),
    });
    // Texture: the inside regions of the object partition, then the outside.
    let part = &reg.partitions[0];
    let texture = (0..part.regions.len())
        .filter(|k| k % 2 == 1 || *k == part.regions.len() - 1)
        .map(|k| {
            let idx: Vec<usize> = (0..nz * nx).filter(|&u| part.label[u] == k).collect();
            Texture {
                region: part.regions[k].clone(),
                pixels: idx.len(),
                simulated: grey_stats(simulated, &idx, d),
                measured: grey_stats(measured, &idx, d),
            }
        })
        .collect();
    Ok(ResidualReport {
        loss,
        band_m: reg.band_m,
        shares,
        echo_position,
        echo_amplitude,
        texture,
        boundary_width,
        notes,
    })
}

#[cfg(test)]
mod tests;
