//! The regions the residual's loss is shared among: each object's boundary
//! band and inside, depth bands and lateral bands (module docs of
//! [`super`]), and the shares themselves.

use super::{check_options, RegionShare, ResidualOptions};
use crate::{OptimError, L1L2};
use usray_transport::scene::{Object, ShapeKind};
use usray_transport::Scene;

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
/// If the slices differ in length (checked by [`super::analyse_residual`]).
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

pub(super) fn axis_spacing(v: &[f64], fallback: f64) -> f64 {
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
