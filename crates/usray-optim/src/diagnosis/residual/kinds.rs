//! The kinds of residual: echo position, echo amplitude, texture and
//! boundary width (module docs of [`super`]), each simulated against measured.

use serde::Serialize;

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

/// Grey level → envelope amplitude `E(g) = 10^{(g − 1) D / 20}`.
pub(super) fn envelope(g: f64, d: f64) -> f64 {
    10f64.powf((g - 1.0) * d / 20.0)
}

/// Integer-lag NCC template match along rows (see [`EchoPosition`]): returns
/// `(shift in pixels, peak correlation, at search limit)`.
pub(super) fn axial_shift(
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

pub(super) fn grey_stats(img: &[f64], idx: &[usize], d: f64) -> Option<GreyStats> {
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
pub(super) fn boundary_fwhm(
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
