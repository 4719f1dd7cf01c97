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
//! let text = include_str!("../../../scenes/cylinder.toml");
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

use crate::{OptimError, L1L2};
use serde::Serialize;
use usray_transport::scene::{Object, ShapeKind};
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

/// A partition of the image into labelled regions.
#[derive(Clone, Debug, PartialEq)]
pub struct Partition {
    /// `"object"`, `"depth"` or `"lateral"`.
    pub name: String,
    /// Region labels.
    pub regions: Vec<String>,
    /// For each pixel (row-major `[nz, nx]`), the index of its region in `regions`.
    pub label: Vec<usize>,
}

/// One object's footprint in the image plane `y = 0`.
///
/// Surface distance `δ(x, z)` ≥ 0 (metres) and "inside" per shape, at `p = (x, 0, z)`:
///
/// | shape | inside | `δ` |
/// |---|---|---|
/// | cylinder (axis y), radius `r` | `ρ < r`, `ρ = √((x−c_x)² + (z−c_z)²)` | `|ρ − r|` |
/// | hollow cylinder, wall `t` | `ρ < r` (wall and lumen) | `min(|ρ − r|, |ρ − (r − t)|)` (both surfaces) |
/// | sphere, radius `r` | `ρ₃ < r`, `ρ₃ = |p − c|` (3-D, so `c_y` counts) | `|ρ₃ − r|` |
/// | slab `[z_top, z_bottom]` | `z_top < z < z_bottom` | `min(|z − z_top|, |z − z_bottom|)` |
/// | half-space, outward normal `n̂` through `c` | `n̂·(p − c) < 0` | `|n̂·(p − c)|` |
/// | mesh | ray parity (`MeshInstance::contains`) | approximated from the inside mask: distance to the nearest pixel centre on the other side, minus half a pixel (exact to half a pixel) |
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectMasks {
    /// The object's name (`objects.NAME`).
    pub name: String,
    /// Pixels with `δ ≤ b` (row-major `[nz, nx]`).
    pub band: Vec<bool>,
    /// Pixels inside the object (band included).
    pub inside: Vec<bool>,
    /// `δ` per pixel, metres (for meshes: `+∞` beyond `b` plus two pixels).
    pub surface_distance_m: Vec<f64>,
    /// Whether `δ` is the pixel-mask approximation (meshes) rather than exact.
    pub approximate: bool,
}

/// The image grid and the regions of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Regions {
    /// Rows (depth samples).
    pub nz: usize,
    /// Columns (lateral samples).
    pub nx: usize,
    /// Lateral pixel positions, metres.
    pub x_m: Vec<f64>,
    /// Depth pixel positions, metres.
    pub z_m: Vec<f64>,
    /// Boundary band half-width `b`, metres.
    pub band_m: f64,
    /// Each object's masks, in file order.
    pub objects: Vec<ObjectMasks>,
    /// The `"object"`, `"depth"` and `"lateral"` partitions, in that order.
    pub partitions: Vec<Partition>,
}

/// Axial echo position: simulated vs measured.
///
/// Template matching along `z`: over the pixels `W` of the region (a boundary band,
/// or the whole image), the zero-mean normalised cross-correlation
///
/// `ρ(k) = Σ_W (I − Ī)(R_k − R̄_k) / √(Σ_W (I − Ī)² · Σ_W (R_k − R̄_k)²)`,
/// `R_k(iz, ix) = R(iz + k, ix)`,
///
/// is the per-column cross-correlation of depth profiles summed over the columns
/// of `W` (pairs falling off the image are dropped), for integer lags
/// `|k| ≤ max_shift_m / Δz`. The peak `k*` is refined by a parabola through
/// `ρ(k*−1), ρ(k*), ρ(k*+1)` (offset clamped to ±½ pixel), and
/// `shift_m = (k* + offset) · Δz`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EchoPosition {
    /// `"boundary of objects.NAME"` or `"whole image"`.
    pub region: String,
    /// `z_measured − z_simulated`, metres: positive = the measured echo lies
    /// deeper. `None` when it cannot be told (empty region, flat image in it).
    pub shift_m: Option<f64>,
    /// Peak `ρ(k*)` ∈ [−1, 1]: how alike the two are once aligned.
    pub correlation: Option<f64>,
    /// The peak is at the largest searched lag: the true shift may be larger.
    pub at_search_limit: bool,
}

/// Echo amplitude in a boundary band, simulated vs measured.
///
/// * `mean_db_difference = (1/|W|) Σ_W (dB(I) − dB(R)) = D · mean_W (I − R)`, dB:
///   positive = the simulated echo is brighter. Pixel by pixel, so a position
///   error also enters it.
/// * `energy_db_difference = 10 log10(Σ_W E(I)² / Σ_W E(R)²)`, dB: the ratio of
///   echo energies in the band, insensitive to shifts that keep the echo inside
///   the band. Both equal `D · δ` when `R = I − δ` without clipping.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EchoAmplitude {
    /// `"boundary of objects.NAME"`.
    pub region: String,
    /// Pixels in the band.
    pub pixels: usize,
    /// Mean level difference, dB (`None` for an empty band).
    pub mean_db_difference: Option<f64>,
    /// Echo energy ratio, dB (`None` for an empty band).
    pub energy_db_difference: Option<f64>,
}

/// Grey-level statistics of one image in one region.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GreyStats {
    /// `ḡ = mean_A g` (grey, dimensionless).
    pub mean_grey: f64,
    /// `√(mean_A (g − ḡ)²)` (grey, dimensionless; population standard deviation).
    pub std_grey: f64,
    /// Speckle SNR `mean_A E / std_A E` of the envelope `E(g)` (dimensionless;
    /// 1.91 for fully developed speckle, larger for a smoother texture); `None`
    /// when `E` is constant. Biased upward by clipped pixels.
    pub speckle_snr: Option<f64>,
    /// Fraction of pixels at the floor `g = 0` (clipped below `−D` dB).
    pub clipped_fraction: f64,
}

/// Texture (speckle) inside an object, or outside all objects.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Texture {
    /// `"inside objects.NAME"` or `"outside all objects"` (the regions of the
    /// `"object"` partition).
    pub region: String,
    /// Pixels in the region.
    pub pixels: usize,
    /// Statistics of the simulated image (`None` for an empty region).
    pub simulated: Option<GreyStats>,
    /// Statistics of the measured image (`None` for an empty region).
    pub measured: Option<GreyStats>,
}

/// Axial width of an object's boundary echo.
///
/// For each column crossing the band, the brightest band pixel is the echo peak
/// `E_p`; its full width at half maximum of the envelope (`E ≥ E_p/2`, i.e.
/// −6.02 dB) is measured along the column from the peak outwards, crossings
/// placed by linear interpolation of `E`. Columns whose peak is clipped, whose
/// peak is more than 20 dB below the band's brightest column, or whose half-maximum
/// runs off the image are dropped; the width is the median over the rest, metres.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BoundaryWidth {
    /// `"boundary of objects.NAME"`.
    pub region: String,
    /// Simulated FWHM, metres (`None` when no column qualifies).
    pub simulated_fwhm_m: Option<f64>,
    /// Measured FWHM, metres (`None` when no column qualifies).
    pub measured_fwhm_m: Option<f64>,
    /// Columns the simulated median is over.
    pub simulated_columns: usize,
    /// Columns the measured median is over.
    pub measured_columns: usize,
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

/// Per-pixel loss terms `c_u = (λ₁ |I_u − R_u| + λ₂ (I_u − R_u)²) / N_pix`, whose sum
/// is the loss ([`L1L2::value`]).
///
/// ```
/// use usray_optim::{residual::pixel_contributions, L1L2};
/// let c = pixel_contributions(&L1L2::default(), &[0.5, 0.0], &[0.0, 0.0]);
/// assert_eq!(c, vec![0.75 / 2.0, 0.0]);
/// ```
///
/// # Panics
/// If the slices differ in length (checked by [`analyse_residual`]).
pub fn pixel_contributions(loss: &L1L2, simulated: &[f64], measured: &[f64]) -> Vec<f64> {
    assert_eq!(simulated.len(), measured.len(), "image sizes differ");
    let n = simulated.len().max(1) as f64;
    simulated
        .iter()
        .zip(measured)
        .map(|(&i, &r)| {
            let d = i - r;
            (loss.lambda1 * d.abs() + loss.lambda2 * d * d) / n
        })
        .collect()
}

/// The share of `Σ contributions` in each region of each partition, sorted by
/// share (largest first, ties in region order) within each partition; partitions
/// keep their order. All shares are 0 when the total is 0.
///
/// # Panics
/// If a partition's labels do not match `contributions` in length.
pub fn region_shares(contributions: &[f64], partitions: &[Partition]) -> Vec<RegionShare> {
    let total: f64 = contributions.iter().sum();
    let mut out = Vec::new();
    for p in partitions {
        assert_eq!(p.label.len(), contributions.len(), "partition size");
        let mut sum = vec![0.0; p.regions.len()];
        let mut count = vec![0usize; p.regions.len()];
        for (&l, &c) in p.label.iter().zip(contributions) {
            sum[l] += c;
            count[l] += 1;
        }
        let mut shares: Vec<RegionShare> = p
            .regions
            .iter()
            .enumerate()
            .map(|(k, r)| RegionShare {
                region: r.clone(),
                partition: p.name.clone(),
                share: if total > 0.0 { sum[k] / total } else { 0.0 },
                pixels: count[k],
            })
            .collect();
        shares.sort_by(|a, b| b.share.total_cmp(&a.share));
        out.extend(shares);
    }
    out
}

/// The default boundary band half-width: one pulse length
/// `cycles · c / (2 f_c)`, metres (`c` = [`Scene::imaging_sound_speed`]).
pub fn default_band_m(scene: &Scene) -> f64 {
    scene.probe.cycles * scene.imaging_sound_speed() / (2.0 * scene.probe.center_frequency_hz)
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

/// Surface distance (metres) and inside flag of an analytic shape at `(x, 0, z)`;
/// `None` for meshes.
fn analytic(o: &Object, x: f64, z: f64) -> Option<(f64, bool)> {
    let c = o.center_m;
    match o.shape {
        ShapeKind::Cylinder => {
            let r = o.radius_m.unwrap_or(0.0);
            let rho = (x - c[0]).hypot(z - c[2]);
            let mut d = (rho - r).abs();
            if let Some(t) = o.thickness_m {
                d = d.min((rho - (r - t)).abs());
            }
            Some((d, rho < r))
        }
        ShapeKind::Sphere => {
            let r = o.radius_m.unwrap_or(0.0);
            let rho = ((x - c[0]).powi(2) + c[1].powi(2) + (z - c[2]).powi(2)).sqrt();
            Some(((rho - r).abs(), rho < r))
        }
        ShapeKind::Slab => {
            let (top, bot) = (o.z_top_m.unwrap_or(0.0), o.z_bottom_m.unwrap_or(0.0));
            Some(((z - top).abs().min((z - bot).abs()), z > top && z < bot))
        }
        ShapeKind::Plane => {
            let n = o.normal.unwrap_or([0.0, 0.0, -1.0]);
            let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let s = (n[0] * (x - c[0]) + n[1] * (0.0 - c[1]) + n[2] * (z - c[2])) / norm;
            Some((s.abs(), s < 0.0))
        }
        ShapeKind::Mesh => None,
    }
}

/// Mask-based surface distance: for each pixel, the distance to the nearest pixel
/// centre on the other side of the mask, minus half a pixel (≥ 0), searched up to
/// `radius` pixels (`+∞` beyond).
fn mask_distance(
    inside: &[bool],
    nz: usize,
    nx: usize,
    dz: f64,
    dx: f64,
    radius: usize,
) -> Vec<f64> {
    let half = 0.5 * dz.min(dx);
    let r = radius as isize;
    let mut out = vec![f64::INFINITY; nz * nx];
    for iz in 0..nz {
        for ix in 0..nx {
            let me = inside[iz * nx + ix];
            let mut best = f64::INFINITY;
            for oz in -r..=r {
                let jz = iz as isize + oz;
                if jz < 0 || jz >= nz as isize {
                    continue;
                }
                for ox in -r..=r {
                    let jx = ix as isize + ox;
                    if jx < 0 || jx >= nx as isize {
                        continue;
                    }
                    if inside[jz as usize * nx + jx as usize] != me {
                        let d = (oz as f64 * dz).hypot(ox as f64 * dx);
                        best = best.min(d);
                    }
                }
            }
            if best.is_finite() {
                out[iz * nx + ix] = (best - half).max(0.0);
            }
        }
    }
    out
}

fn axis_spacing(v: &[f64], fallback: f64) -> f64 {
    if v.len() > 1 {
        (v[v.len() - 1] - v[0]) / (v.len() - 1) as f64
    } else {
        fallback
    }
}

/// Bands `[k w, (k+1) w)` of the coordinates `v` (metres): per-sample band
/// index and labels `"{prefix} {lo}–{hi} mm"` clipped to the covered range.
fn bands(v: &[f64], w: f64, prefix: &str) -> (Vec<usize>, Vec<String>) {
    let key = |t: f64| (t / w + 1e-9).floor() as i64;
    let (lo_v, hi_v) = (v[0], v[v.len() - 1]);
    let k0 = key(lo_v);
    let k1 = key(hi_v);
    let labels = (k0..=k1)
        .map(|k| {
            let lo = (k as f64 * w).max(lo_v) * 1e3 + 0.0;
            let hi = ((k + 1) as f64 * w).min(hi_v) * 1e3 + 0.0;
            format!("{prefix} {lo:.1}–{hi:.1} mm")
        })
        .collect();
    let idx = v.iter().map(|&t| (key(t) - k0) as usize).collect();
    (idx, labels)
}

/// The grid, each object's masks and the three partitions of `scene`'s image
/// (see the module docs for the rules).
///
/// # Errors
/// Bad options, an invalid imaging grid, or an unreadable mesh.
pub fn scene_regions(scene: &Scene, opts: &ResidualOptions) -> Result<Regions, OptimError> {
    check_options(opts)?;
    let (x_m, z_m) = scene.imaging_settings().grid()?;
    let (nz, nx) = (z_m.len(), x_m.len());
    let band_m = opts.band_m.unwrap_or_else(|| default_band_m(scene));
    let pixel = scene.imaging.pixel_m;
    let (dx, dz) = (axis_spacing(&x_m, pixel), axis_spacing(&z_m, pixel));
    let has_mesh = scene.objects.iter().any(|o| o.shape == ShapeKind::Mesh);
    let meshes = if has_mesh {
        scene.mesh_instances()?
    } else {
        Vec::new()
    };
    let mut objects = Vec::with_capacity(scene.objects.len());
    for (k, o) in scene.objects.iter().enumerate() {
        let n = nz * nx;
        let mut dist = vec![0.0; n];
        let mut inside = vec![false; n];
        let approximate = o.shape == ShapeKind::Mesh;
        if let Some(Some(mesh)) = meshes.get(k).filter(|_| approximate) {
            for iz in 0..nz {
                for ix in 0..nx {
                    inside[iz * nx + ix] = mesh.contains([x_m[ix], 0.0, z_m[iz]]);
                }
            }
            let radius = (band_m / dz.min(dx)).ceil() as usize + 2;
            dist = mask_distance(&inside, nz, nx, dz, dx, radius);
        } else {
            for iz in 0..nz {
                for ix in 0..nx {
                    let (d, i) = analytic(o, x_m[ix], z_m[iz]).unwrap_or((f64::INFINITY, false));
                    dist[iz * nx + ix] = d;
                    inside[iz * nx + ix] = i;
                }
            }
        }
        objects.push(ObjectMasks {
            name: o.name.clone(),
            band: dist.iter().map(|&d| d <= band_m).collect(),
            inside,
            surface_distance_m: dist,
            approximate,
        });
    }
    // Partition "object".
    let n_obj = objects.len();
    let mut regions: Vec<String> = Vec::with_capacity(2 * n_obj + 1);
    for o in &objects {
        regions.push(format!("boundary of objects.{}", o.name));
        regions.push(format!("inside objects.{}", o.name));
    }
    regions.push("outside all objects".to_string());
    let inside_count: Vec<usize> = objects
        .iter()
        .map(|o| o.inside.iter().filter(|&&b| b).count())
        .collect();
    let label = (0..nz * nx)
        .map(|u| {
            let mut nearest: Option<(usize, f64)> = None;
            for (k, o) in objects.iter().enumerate() {
                let d = o.surface_distance_m[u];
                if o.band[u] && nearest.is_none_or(|(_, b)| d < b) {
                    nearest = Some((k, d));
                }
            }
            if let Some((k, _)) = nearest {
                return 2 * k;
            }
            let mut specific: Option<usize> = None;
            for (k, o) in objects.iter().enumerate() {
                if o.inside[u] && specific.is_none_or(|s| inside_count[k] < inside_count[s]) {
                    specific = Some(k);
                }
            }
            specific.map_or(2 * n_obj, |k| 2 * k + 1)
        })
        .collect();
    let mut partitions = vec![Partition {
        name: "object".into(),
        regions,
        label,
    }];
    // Partitions "depth" and "lateral".
    let (zi, zl) = bands(&z_m, opts.depth_band_m, "depth");
    let (xi, xl) = bands(&x_m, opts.lateral_band_m, "lateral");
    partitions.push(Partition {
        name: "depth".into(),
        regions: zl,
        label: (0..nz * nx).map(|u| zi[u / nx]).collect(),
    });
    partitions.push(Partition {
        name: "lateral".into(),
        regions: xl,
        label: (0..nz * nx).map(|u| xi[u % nx]).collect(),
    });
    Ok(Regions {
        nz,
        nx,
        x_m,
        z_m,
        band_m,
        objects,
        partitions,
    })
}

/// Grey level → envelope amplitude `E(g) = 10^{(g − 1) D / 20}`.
fn envelope(g: f64, d: f64) -> f64 {
    10f64.powf((g - 1.0) * d / 20.0)
}

/// Integer-lag NCC template match along rows (see [`EchoPosition`]): returns
/// `(shift in pixels, peak correlation, at search limit)`.
fn axial_shift(
    sim: &[f64],
    meas: &[f64],
    nz: usize,
    nx: usize,
    mask: Option<&[bool]>,
    max_lag: usize,
) -> Option<(f64, f64, bool)> {
    let lags: Vec<isize> = (-(max_lag as isize)..=max_lag as isize).collect();
    let mut ncc = vec![f64::NAN; lags.len()];
    for (j, &k) in lags.iter().enumerate() {
        let (mut n, mut ss, mut sm, mut sss, mut smm, mut ssm) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for iz in 0..nz {
            let jz = iz as isize + k;
            if jz < 0 || jz >= nz as isize {
                continue;
            }
            let (row, mrow) = (iz * nx, jz as usize * nx);
            for ix in 0..nx {
                if mask.is_some_and(|m| !m[row + ix]) {
                    continue;
                }
                let (s, m) = (sim[row + ix], meas[mrow + ix]);
                n += 1.0;
                ss += s;
                sm += m;
                sss += s * s;
                smm += m * m;
                ssm += s * m;
            }
        }
        if n < 2.0 {
            continue;
        }
        let vs = sss - ss * ss / n;
        let vm = smm - sm * sm / n;
        if vs > 1e-12 * n && vm > 1e-12 * n {
            ncc[j] = (ssm - ss * sm / n) / (vs * vm).sqrt();
        }
    }
    let (best, &peak) = ncc
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    let mut offset = 0.0;
    if best > 0 && best + 1 < ncc.len() {
        let (a, c) = (ncc[best - 1], ncc[best + 1]);
        let denom = a - 2.0 * peak + c;
        if a.is_finite() && c.is_finite() && denom < 0.0 {
            offset = (0.5 * (a - c) / denom).clamp(-0.5, 0.5);
        }
    }
    let at_limit = best == 0 || best + 1 == ncc.len();
    Some((lags[best] as f64 + offset, peak, at_limit))
}

fn grey_stats(img: &[f64], idx: &[usize], d: f64) -> Option<GreyStats> {
    if idx.is_empty() {
        return None;
    }
    let n = idx.len() as f64;
    let mean = idx.iter().map(|&u| img[u]).sum::<f64>() / n;
    let var = idx.iter().map(|&u| (img[u] - mean).powi(2)).sum::<f64>() / n;
    let e: Vec<f64> = idx.iter().map(|&u| envelope(img[u], d)).collect();
    let em = e.iter().sum::<f64>() / n;
    let es = (e.iter().map(|v| (v - em).powi(2)).sum::<f64>() / n).sqrt();
    Some(GreyStats {
        mean_grey: mean,
        std_grey: var.sqrt(),
        speckle_snr: (es > 1e-12 * em).then(|| em / es),
        clipped_fraction: idx.iter().filter(|&&u| img[u] <= 0.0).count() as f64 / n,
    })
}

/// Per-column FWHM of the brightest band pixel's echo (see [`BoundaryWidth`]):
/// `(median FWHM in metres, columns used)`.
fn boundary_fwhm(
    img: &[f64],
    band: &[bool],
    nz: usize,
    nx: usize,
    dz: f64,
    d: f64,
) -> (Option<f64>, usize) {
    // Peak per column.
    let mut peaks: Vec<(usize, usize, f64)> = Vec::new(); // (ix, iz, E)
    for ix in 0..nx {
        let best = (0..nz)
            .filter(|&iz| band[iz * nx + ix])
            .max_by(|&a, &b| img[a * nx + ix].total_cmp(&img[b * nx + ix]));
        if let Some(iz) = best {
            let g = img[iz * nx + ix];
            if g > 0.0 {
                peaks.push((ix, iz, envelope(g, d)));
            }
        }
    }
    let top = peaks.iter().map(|p| p.2).fold(0.0, f64::max);
    let mut widths: Vec<f64> = Vec::new();
    for &(ix, iz, ep) in &peaks {
        if ep < 0.1 * top {
            continue;
        }
        let half = 0.5 * ep;
        let e = |i: usize| envelope(img[i * nx + ix], d);
        // Crossing above (smaller iz).
        let mut up = None;
        let mut i = iz;
        while i > 0 {
            let (a, b) = (e(i), e(i - 1));
            if b < half {
                up = Some(i as f64 - (a - half) / (a - b));
                break;
            }
            i -= 1;
        }
        let mut down = None;
        let mut i = iz;
        while i + 1 < nz {
            let (a, b) = (e(i), e(i + 1));
            if b < half {
                down = Some(i as f64 + (a - half) / (a - b));
                break;
            }
            i += 1;
        }
        if let (Some(u), Some(w)) = (up, down) {
            widths.push((w - u) * dz);
        }
    }
    let n = widths.len();
    if n == 0 {
        return (None, 0);
    }
    widths.sort_by(f64::total_cmp);
    let median = if n % 2 == 1 {
        widths[n / 2]
    } else {
        0.5 * (widths[n / 2 - 1] + widths[n / 2])
    };
    (Some(median), n)
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

/// A signed residual map as RGB pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct SignedResidualMap {
    /// Image width = `nx`.
    pub width: usize,
    /// Image height = `nz`.
    pub height: usize,
    /// `height · width · 3` bytes, row-major RGB.
    pub rgb: Vec<u8>,
    /// The residual `d = I − R` (grey levels) drawn at full colour.
    pub scale: f64,
}

/// The signed residual `d = I − R` as a diverging colour map: with
/// `t = clamp(d / scale, −1, 1)`, `t ≥ 0` is `(255, 255(1−t), 255(1−t))` (white to
/// red: simulation brighter than measurement) and `t < 0` is
/// `(255(1+t), 255(1+t), 255)` (white to blue: simulation darker); `d = 0` is
/// white. `scale` (grey levels; `1` grey level = `D` dB) defaults to the 99th
/// percentile of `|d|` (nearest rank), or 1 when that is 0, so a few outliers do
/// not wash out the map; the value used is returned for the colour bar.
///
/// ```
/// use usray_optim::residual::signed_residual_rgb;
/// let m = signed_residual_rgb(&[0.5, 0.0, 0.2], &[0.0, 0.5, 0.2], 1, 3, Some(0.5)).unwrap();
/// assert_eq!(m.rgb, vec![255, 0, 0, 0, 0, 255, 255, 255, 255]);
/// ```
///
/// # Errors
/// [`OptimError::Diagnosis`] for images not of `nz · nx` pixels in `[0, 1]`, or a
/// scale that is not a positive number.
pub fn signed_residual_rgb(
    simulated: &[f64],
    measured: &[f64],
    nz: usize,
    nx: usize,
    scale: Option<f64>,
) -> Result<SignedResidualMap, OptimError> {
    check_images(simulated, measured, nz, nx)?;
    let d: Vec<f64> = simulated.iter().zip(measured).map(|(i, r)| i - r).collect();
    let scale = match scale {
        Some(s) if s.is_finite() && s > 0.0 => s,
        Some(s) => {
            return Err(invalid(format!(
                "residual map scale must be a positive number, found {s}"
            )))
        }
        None => {
            let mut a: Vec<f64> = d.iter().map(|v| v.abs()).collect();
            a.sort_by(f64::total_cmp);
            let p = if a.is_empty() {
                0.0
            } else {
                a[((0.99 * a.len() as f64).ceil() as usize).clamp(1, a.len()) - 1]
            };
            if p > 0.0 {
                p
            } else {
                1.0
            }
        }
    };
    let mut rgb = Vec::with_capacity(3 * d.len());
    for v in d {
        let t = (v / scale).clamp(-1.0, 1.0);
        let fade = |t: f64| (255.0 * (1.0 - t.abs())).round() as u8;
        if t >= 0.0 {
            rgb.extend_from_slice(&[255, fade(t), fade(t)]);
        } else {
            rgb.extend_from_slice(&[fade(t), fade(t), 255]);
        }
    }
    Ok(SignedResidualMap {
        width: nx,
        height: nz,
        rgb,
        scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 121 × 181 pixels of 0.1 mm: x ∈ [−6, 6] mm, z ∈ [2, 20] mm; D = 60 dB;
    /// 5 MHz, 3 cycles at 1540 m/s: b = 0.462 mm.
    fn scene_with(objects: &str) -> Scene {
        scene_in(objects, &std::env::temp_dir())
    }

    fn scene_in(objects: &str, base: &std::path::Path) -> Scene {
        let text = format!(
            r#"
[medium]
sound_speed_m_s = 1540.0
impedance_mrayl = 1.54
[probe]
kind = "linear"
n_elements = 64
pitch_m = 0.3e-3
element_width_m = 0.27e-3
center_frequency_hz = 5.0e6
cycles = 3.0
main_lobe_deg = 5.0
cutoff_deg = 60.0
[acquisition]
angles_deg = [0.0]
sampling_frequency_hz = 40.0e6
max_depth_m = 0.03
rays_per_element = 10
max_bounces = 2
seed = 1
[imaging]
x_range_m = [-0.006, 0.006]
z_range_m = [0.002, 0.020]
pixel_m = 0.1e-3
f_number = 1.5
dynamic_range_db = 60.0
[materials.target]
impedance_mrayl = 1.99
sound_speed_m_s = 1570.0
{objects}
"#
        );
        Scene::from_toml_str(&text, "test.toml", base).unwrap()
    }

    const CYLINDER: &str = r#"
[[objects]]
name = "cylinder"
shape = "cylinder"
center_m = [0.0, 0.0, 0.010]
radius_m = 0.003
material = "target"
"#;

    fn grid(scene: &Scene) -> (usize, usize, Vec<f64>, Vec<f64>) {
        let (x, z) = scene.imaging_settings().grid().unwrap();
        (z.len(), x.len(), x, z)
    }

    /// A bright ring of Gaussian profile (σ = 0.15 mm) on the cylinder's surface,
    /// on a dark background.
    fn ring_echo(scene: &Scene, level: f64) -> Vec<f64> {
        let (nz, nx, x, z) = grid(scene);
        let mut img = vec![0.0; nz * nx];
        for iz in 0..nz {
            for ix in 0..nx {
                let rho = x[ix].hypot(z[iz] - 0.010);
                img[iz * nx + ix] = level * (-((rho - 0.003) / 0.15e-3).powi(2)).exp();
            }
        }
        img
    }

    fn by_partition<'a>(r: &'a ResidualReport, p: &str) -> Vec<&'a RegionShare> {
        r.shares.iter().filter(|s| s.partition == p).collect()
    }

    fn share(r: &ResidualReport, region: &str) -> f64 {
        r.shares.iter().find(|s| s.region == region).unwrap().share
    }

    #[test]
    fn residual_inside_a_disk_is_all_inside_the_cylinder() {
        let scene = scene_with(CYLINDER);
        let (nz, nx, x, z) = grid(&scene);
        let measured = vec![0.3; nz * nx];
        let mut simulated = measured.clone();
        for iz in 0..nz {
            for ix in 0..nx {
                if x[ix].hypot(z[iz] - 0.010) < 0.002 {
                    simulated[iz * nx + ix] = 0.5;
                }
            }
        }
        let r =
            analyse_residual(&scene, &simulated, &measured, &ResidualOptions::default()).unwrap();
        assert!((r.band_m - 3.0 * 1540.0 / 1e7).abs() < 1e-15);
        let obj = by_partition(&r, "object");
        assert_eq!(obj[0].region, "inside objects.cylinder");
        assert!((obj[0].share - 1.0).abs() < 1e-12, "{obj:?}");
        assert_eq!(share(&r, "boundary of objects.cylinder"), 0.0);
        assert_eq!(share(&r, "outside all objects"), 0.0);
        let expected = L1L2::default().value(&simulated, &measured);
        assert!((r.loss - expected).abs() < 1e-12 * expected);
        // The disk spans depths 8–12 mm, laterally −2–2 mm.
        assert!((share(&r, "depth 5.0–10.0 mm") - 0.5).abs() < 0.05);
        assert!((share(&r, "depth 10.0–15.0 mm") - 0.5).abs() < 0.05);
        assert_eq!(share(&r, "depth 2.0–5.0 mm"), 0.0);
        assert!((share(&r, "lateral -5.0–0.0 mm") - 0.5).abs() < 0.05);
        assert_eq!(share(&r, "lateral -6.0–-5.0 mm"), 0.0);
        // Texture: the inside region holds the disk plus a flat margin.
        let t = &r.texture[0];
        assert_eq!(t.region, "inside objects.cylinder");
        let m = t.measured.as_ref().unwrap();
        assert!((m.mean_grey - 0.3).abs() < 1e-12 && m.std_grey < 1e-12);
        assert_eq!(m.speckle_snr, None);
        assert!(t.simulated.as_ref().unwrap().mean_grey > 0.3);
        assert_eq!(r.texture.last().unwrap().region, "outside all objects");
    }

    #[test]
    fn shares_sum_to_one_in_every_partition_with_overlapping_objects() {
        let objects = format!(
            "{CYLINDER}{}",
            r#"
[[objects]]
name = "deep"
shape = "plane"
center_m = [0.0, 0.0, 0.008]
material = "target"
[[objects]]
name = "layer"
shape = "slab"
z_top_m = 0.003
z_bottom_m = 0.005
material = "target"
[[objects]]
name = "ball"
shape = "sphere"
center_m = [0.004, 0.001, 0.016]
radius_m = 0.0015
material = "target"
"#
        );
        let scene = scene_with(&objects);
        let (nz, nx, _, _) = grid(&scene);
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let simulated: Vec<f64> = (0..nz * nx).map(|_| next()).collect();
        let measured: Vec<f64> = (0..nz * nx).map(|_| next()).collect();
        let r =
            analyse_residual(&scene, &simulated, &measured, &ResidualOptions::default()).unwrap();
        for p in ["object", "depth", "lateral"] {
            let s = by_partition(&r, p);
            let total: f64 = s.iter().map(|s| s.share).sum();
            assert!((total - 1.0).abs() < 1e-12, "{p}: {total}");
            assert_eq!(s.iter().map(|s| s.pixels).sum::<usize>(), nz * nx);
            assert!(s.windows(2).all(|w| w[0].share >= w[1].share), "{p} sorted");
        }
        assert_eq!(by_partition(&r, "object").len(), 9);
        let reg = scene_regions(&scene, &ResidualOptions::default()).unwrap();
        let obj = &reg.partitions[0];
        let at = |x: f64, z: f64| {
            let ix = ((x + 0.006) / 1e-4).round() as usize;
            let iz = ((z - 0.002) / 1e-4).round() as usize;
            obj.regions[obj.label[iz * nx + ix]].as_str()
        };
        // Inside both the cylinder and the half-space: the smaller one wins.
        assert_eq!(at(0.0, 0.010), "inside objects.cylinder");
        assert_eq!(at(-0.005, 0.015), "inside objects.deep");
        assert_eq!(at(0.0, 0.004), "inside objects.layer");
        assert_eq!(at(0.0, 0.0030), "boundary of objects.layer");
        assert_eq!(at(0.0, 0.0070), "boundary of objects.cylinder"); // top of the cylinder
        assert_eq!(at(-0.005, 0.0081), "boundary of objects.deep");
        assert_eq!(at(-0.005, 0.006), "outside all objects");
        // Sphere with c_y = 1 mm: section radius √(1.5² − 1²) mm ≈ 1.118 mm.
        assert_eq!(at(0.004, 0.016), "inside objects.ball");
        assert_eq!(at(0.004, 0.016 - 0.00112), "boundary of objects.ball");
    }

    #[test]
    fn hollow_cylinder_has_bands_at_both_surfaces() {
        let scene = scene_with(
            r#"
[[objects]]
name = "tube"
shape = "cylinder"
center_m = [0.0, 0.0, 0.010]
radius_m = 0.003
thickness_m = 0.001
material = "target"
"#,
        );
        let reg = scene_regions(&scene, &ResidualOptions::default()).unwrap();
        let nx = reg.nx;
        let row = |z: f64| ((z - 0.002) / 1e-4).round() as usize * nx + nx / 2;
        let o = &reg.objects[0];
        assert!(o.band[row(0.007)] && o.band[row(0.008)]); // outer and inner surface
        assert!(!o.band[row(0.0075)] && o.inside[row(0.0075)]); // mid-wall
        assert!(!o.band[row(0.010)] && o.inside[row(0.010)]); // lumen
    }

    #[test]
    fn axial_shift_of_a_boundary_echo_is_recovered() {
        let scene = scene_with(CYLINDER);
        let (nz, nx, _, _) = grid(&scene);
        let simulated = ring_echo(&scene, 0.8);
        for k in [3isize, -2] {
            let mut measured = vec![0.0; nz * nx];
            for iz in 0..nz as isize {
                let src = iz - k;
                if (0..nz as isize).contains(&src) {
                    let (d, s) = (iz as usize * nx, src as usize * nx);
                    measured[d..d + nx].copy_from_slice(&simulated[s..s + nx]);
                }
            }
            let r = analyse_residual(&scene, &simulated, &measured, &ResidualOptions::default())
                .unwrap();
            let want = k as f64 * 1e-4;
            for e in &r.echo_position {
                let got = e.shift_m.unwrap();
                assert!((got - want).abs() < 0.5e-4, "{e:?} vs {want}");
                assert!(e.correlation.unwrap() > 0.9 && !e.at_search_limit);
            }
        }
        let flat = vec![0.5; nz * nx];
        let r = analyse_residual(&scene, &flat, &flat, &ResidualOptions::default()).unwrap();
        assert_eq!(r.echo_position[0].shift_m, None);
        assert_eq!(r.loss, 0.0);
        assert!(r.shares.iter().all(|s| s.share == 0.0));
    }

    #[test]
    fn amplitude_offset_gives_its_db_difference() {
        let scene = scene_with(CYLINDER);
        let simulated: Vec<f64> = ring_echo(&scene, 0.3).iter().map(|g| 0.5 + g).collect();
        let measured: Vec<f64> = simulated.iter().map(|g| g - 0.1).collect();
        let r =
            analyse_residual(&scene, &simulated, &measured, &ResidualOptions::default()).unwrap();
        let a = &r.echo_amplitude[0];
        assert_eq!(a.region, "boundary of objects.cylinder");
        assert!(a.pixels > 500);
        assert!((a.mean_db_difference.unwrap() - 6.0).abs() < 1e-9, "{a:?}");
        assert!(
            (a.energy_db_difference.unwrap() - 6.0).abs() < 1e-9,
            "{a:?}"
        );
        // Texture: the same offset in the grey means, SNR unchanged (E scales).
        let t = &r.texture[0];
        let (s, m) = (t.simulated.as_ref().unwrap(), t.measured.as_ref().unwrap());
        assert!((s.mean_grey - m.mean_grey - 0.1).abs() < 1e-12);
    }

    #[test]
    fn boundary_width_is_the_fwhm_of_the_echo() {
        let scene = scene_with(
            r#"
[[objects]]
name = "layer"
shape = "slab"
z_top_m = 0.008
z_bottom_m = 0.018
material = "target"
"#,
        );
        let (nz, nx, _, z) = grid(&scene);
        // Envelope exp(−(z − 8 mm)²/2σ²) as grey: g = 1 + 20 log10(E) / 60, clipped.
        let echo = |sigma: f64| -> Vec<f64> {
            let mut img = vec![0.0; nz * nx];
            for iz in 0..nz {
                let e: f64 = (-(z[iz] - 0.008).powi(2) / (2.0 * sigma * sigma)).exp();
                let g = (1.0 + 20.0 * e.max(1e-300).log10() / 60.0).clamp(0.0, 1.0);
                img[iz * nx..(iz + 1) * nx].fill(g);
            }
            img
        };
        let (ss, sm) = (0.2e-3, 0.3e-3);
        let r =
            analyse_residual(&scene, &echo(ss), &echo(sm), &ResidualOptions::default()).unwrap();
        let w = &r.boundary_width[0];
        let k = 2.0 * (2.0 * 2f64.ln()).sqrt();
        assert!(
            (w.simulated_fwhm_m.unwrap() - k * ss).abs() < 0.3e-4,
            "{w:?}"
        );
        assert!(
            (w.measured_fwhm_m.unwrap() - k * sm).abs() < 0.3e-4,
            "{w:?}"
        );
        assert_eq!((w.simulated_columns, w.measured_columns), (nx, nx));
    }

    #[test]
    fn mesh_objects_use_their_inside_mask() {
        // A 4 mm cube centred at 10 mm depth.
        let dir = std::env::temp_dir().join(format!("usray-residual-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut obj = String::new();
        for i in 0..8 {
            let c = |b: usize| if i >> b & 1 == 1 { 0.002 } else { -0.002 };
            obj += &format!("v {} {} {}\n", c(0), c(1), c(2));
        }
        for f in [
            [1, 3, 4, 2],
            [5, 6, 8, 7],
            [1, 2, 6, 5],
            [3, 7, 8, 4],
            [1, 5, 7, 3],
            [2, 4, 8, 6],
        ] {
            obj += &format!(
                "f {} {} {}\nf {} {} {}\n",
                f[0], f[1], f[2], f[0], f[2], f[3]
            );
        }
        std::fs::write(dir.join("cube.obj"), obj).unwrap();
        let scene = scene_in(
            r#"
[[objects]]
name = "cube"
shape = "mesh"
path = "cube.obj"
center_m = [0.0, 0.0, 0.010]
material = "target"
"#,
            &dir,
        );
        let reg = scene_regions(&scene, &ResidualOptions::default());
        std::fs::remove_dir_all(&dir).ok();
        let reg = reg.unwrap();
        let nx = reg.nx;
        let at = |x: f64, z: f64| {
            let u =
                ((z - 0.002) / 1e-4).round() as usize * nx + ((x + 0.006) / 1e-4).round() as usize;
            reg.partitions[0].regions[reg.partitions[0].label[u]].as_str()
        };
        assert!(reg.objects[0].approximate);
        assert_eq!(at(0.0, 0.010), "inside objects.cube");
        assert_eq!(at(0.0, 0.0081), "boundary of objects.cube");
        assert_eq!(at(0.0019, 0.010), "boundary of objects.cube");
        assert_eq!(at(0.0, 0.0070), "outside all objects");
    }

    #[test]
    fn bad_inputs_are_reported() {
        let scene = scene_with(CYLINDER);
        let (nz, nx, _, _) = grid(&scene);
        let good = vec![0.5; nz * nx];
        let o = ResidualOptions::default();
        let msg = |e: OptimError| e.to_string();
        let e = msg(analyse_residual(&scene, &good[1..], &good, &o).unwrap_err());
        assert!(
            e.contains("simulated") && e.contains(&format!("[{nz}, {nx}]")),
            "{e}"
        );
        let mut nan = good.clone();
        nan[nx + 2] = f64::NAN;
        let e = msg(analyse_residual(&scene, &good, &nan, &o).unwrap_err());
        assert!(
            e.contains("measured") && e.contains("NaN") && e.contains("(1, 2)"),
            "{e}"
        );
        let mut big = good.clone();
        big[0] = 1.5;
        assert!(analyse_residual(&scene, &big, &good, &o).is_err());
        let bad = ResidualOptions {
            band_m: Some(-1.0),
            ..o
        };
        let e = msg(analyse_residual(&scene, &good, &good, &bad).unwrap_err());
        assert!(e.contains("band_m"), "{e}");
        assert!(signed_residual_rgb(&good, &good, nz, nx, Some(0.0)).is_err());
        assert!(signed_residual_rgb(&good, &good, nz + 1, nx, None).is_err());
    }

    #[test]
    fn signed_map_is_diverging_around_white() {
        let sim = [0.5, 0.5, 0.5, 0.4];
        let meas = [0.5, 0.3, 0.6, 0.5];
        let m = signed_residual_rgb(&sim, &meas, 2, 2, None).unwrap();
        assert!((m.scale - 0.2).abs() < 1e-12); // 99th percentile of |d| = max here
        assert_eq!((m.width, m.height), (2, 2));
        assert_eq!(&m.rgb[0..3], &[255, 255, 255]);
        assert_eq!(&m.rgb[3..6], &[255, 0, 0]);
        assert_eq!(&m.rgb[6..9], &[128, 128, 255]);
        let z = signed_residual_rgb(&sim, &sim, 2, 2, None).unwrap();
        assert_eq!(z.scale, 1.0);
        assert!(z.rgb.iter().all(|&b| b == 255));
    }
}
