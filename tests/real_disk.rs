//! Reality check: the measured Verasonics acquisition `real/PWI_disk.mat` (a 2-cm
//! rotating disk, 32 unsteered plane waves, band-pass undersampled at 4/3·f_c) is
//! imported, demodulated to IQ at f_c = 5 MHz with absolute time, beamformed, and
//! a circle fitted to the disk's edge must have radius 10 mm ± 0.3 mm.

use usray::signal::das::{linspace, Das};
use usray::signal::demod::IqDemod;
use usray::signal::{import_mat, Complex64};

/// Least-squares (Kåsa) circle through points: minimises Σ(x² + z² + Dx + Ez + F)².
fn fit_circle(pts: &[(f64, f64)]) -> (f64, f64, f64) {
    let mut m = [[0.0f64; 4]; 3];
    for &(x, z) in pts {
        let row = [x, z, 1.0];
        let rhs = -(x * x + z * z);
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += row[i] * row[j];
            }
            m[i][3] += row[i] * rhs;
        }
    }
    // Gaussian elimination with partial pivoting.
    for c in 0..3 {
        let p = (c..3)
            .max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs()))
            .unwrap();
        m.swap(c, p);
        for r in 0..3 {
            if r != c {
                let f = m[r][c] / m[c][c];
                for k in c..4 {
                    m[r][k] -= f * m[c][k];
                }
            }
        }
    }
    let (d, e, f) = (m[0][3] / m[0][0], m[1][3] / m[1][1], m[2][3] / m[2][2]);
    let (xc, zc) = (-d / 2.0, -e / 2.0);
    (xc, zc, (xc * xc + zc * zc - f).sqrt())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Fit the disk in an envelope image `mean` (`[z.len(), x.len()]`): smooth with a
/// 5×5 box, threshold midway between inside (< 6 mm from the centre) and outside
/// (> 13 mm) medians, fit a circle to the boundary pixels (6–14 mm); three rounds,
/// re-centring each time. Returns (radius m, inside/outside contrast dB).
fn fit_disk(mean: &[f64], x: &[f64], z: &[f64]) -> (f64, f64) {
    let (nx, nz) = (x.len(), z.len());
    // Smooth with a 5×5 box (1 mm).
    let mut sm = vec![0.0; nx * nz];
    for iz in 0..nz {
        for ix in 0..nx {
            let (mut s, mut n) = (0.0, 0.0);
            for dz in -2i64..=2 {
                for dx in -2i64..=2 {
                    let (a, b) = (iz as i64 + dz, ix as i64 + dx);
                    if a >= 0 && b >= 0 && (a as usize) < nz && (b as usize) < nx {
                        s += mean[a as usize * nx + b as usize];
                        n += 1.0;
                    }
                }
            }
            sm[iz * nx + ix] = s / n;
        }
    }
    // Centre: centroid of the pixels above the mean level; then inside/outside levels.
    let avg = sm.iter().sum::<f64>() / sm.len() as f64;
    let (mut cx, mut cz, mut w) = (0.0, 0.0, 0.0);
    for iz in 0..nz {
        for ix in 0..nx {
            if sm[iz * nx + ix] > avg {
                cx += x[ix];
                cz += z[iz];
                w += 1.0;
            }
        }
    }
    let (mut xc, mut zc) = (cx / w, cz / w);
    let mut radius = 0.0;
    let mut contrast = 0.0;
    for _ in 0..3 {
        let r_of = |ix: usize, iz: usize| ((x[ix] - xc).powi(2) + (z[iz] - zc).powi(2)).sqrt();
        let (mut inside, mut outside) = (vec![], vec![]);
        for iz in 0..nz {
            for ix in 0..nx {
                let r = r_of(ix, iz);
                if r < 6e-3 {
                    inside.push(sm[iz * nx + ix]);
                } else if r > 13e-3 {
                    outside.push(sm[iz * nx + ix]);
                }
            }
        }
        let (lin, lout) = (median(inside), median(outside));
        let thr = 0.5 * (lin + lout);
        // Boundary: above-threshold pixels with a below-threshold 4-neighbour, in 6–14 mm.
        let above = |ix: usize, iz: usize| sm[iz * nx + ix] > thr;
        let mut pts = vec![];
        for iz in 1..nz - 1 {
            for ix in 1..nx - 1 {
                let r = r_of(ix, iz);
                if above(ix, iz)
                    && (r > 6e-3 && r < 14e-3)
                    && (!above(ix - 1, iz)
                        || !above(ix + 1, iz)
                        || !above(ix, iz - 1)
                        || !above(ix, iz + 1))
                {
                    pts.push((x[ix], z[iz]));
                }
            }
        }
        let (a, b, r) = fit_circle(&pts);
        eprintln!(
            "inside {lin:.1}, outside {lout:.1} ({:.1} dB contrast); {} boundary px; circle centre ({:.2}, {:.2}) mm, radius {:.3} mm",
            20.0 * (lin / lout).log10(),
            pts.len(),
            a * 1e3,
            b * 1e3,
            r * 1e3
        );
        (xc, zc, radius) = (a, b, r);
        contrast = 20.0 * (lin / lout).log10();
    }
    (radius, contrast)
}

#[test]
fn pwi_disk_radius() {
    let Some(path) = usray_testdata::data_file("real/PWI_disk.mat") else {
        return;
    };
    let ch = import_mat(&path).unwrap();
    assert_eq!(
        (ch.n_transmits(), ch.n_elements(), ch.n_samples),
        (32, 128, 334)
    );
    assert_eq!(ch.meta.t0_s, 9.95e-6);
    let (fs, fc) = (ch.meta.sampling_frequency_hz, ch.meta.center_frequency_hz);
    assert_eq!(fc, 5e6);
    let bw = ch.meta.probe.extra["bandwidth_percent"].as_f64().unwrap() / 100.0;
    let ns = ch.n_samples;
    let demod = IqDemod::new(fc, fs, bw * fc / 2.0, 5).unwrap();
    let mut iq = vec![Complex64::new(0.0, 0.0); ch.samples.len()];
    for (rec, out) in iq.chunks_mut(ns).enumerate() {
        demod.forward(&ch.samples[rec * ns..(rec + 1) * ns], ch.meta.t0_s, out);
    }
    // One frame at a time (the disk moves between frames): mean envelope, F# 1.
    let (x, z) = (linspace(-15e-3, 15e-3, 151), linspace(5e-3, 40e-3, 176));
    let (nx, nz) = (x.len(), z.len());
    let mut meta1 = ch.meta.clone();
    meta1.transmits.truncate(1);
    let das = Das::new(
        &meta1,
        ns,
        x.clone(),
        z.clone(),
        ch.meta.sound_speed_m_s,
        1.0,
        true,
    )
    .unwrap();
    let mut mean = vec![0.0; nx * nz];
    let mut out = vec![Complex64::new(0.0, 0.0); nx * nz];
    let per = 128 * ns;
    for f in 0..32 {
        das.forward(&iq[f * per..(f + 1) * per], &mut out);
        for (m, v) in mean.iter_mut().zip(&out) {
            *m += v.norm() / 32.0;
        }
    }
    let (radius, contrast) = fit_disk(&mean, &x, &z);
    eprintln!(
        "hand-made frame average: radius {:.3} mm, contrast {contrast:.1} dB",
        radius * 1e3
    );
    assert!(
        (radius - 10e-3).abs() <= 0.3e-3,
        "fitted radius {} mm",
        radius * 1e3
    );
}

/// The user's path: `import` (each of the 32 frames is a transmit tagged with its
/// `frame`), write and read back CONTRACT §2 files, then the ordinary `BMode`
/// (no hand-made averaging): the transmits of each frame are compounded
/// coherently, the 32 frames incoherently (README pitfall 5). The disk must come
/// out with radius 10 mm ± 0.3 mm and more than 15 dB disk/background contrast.
/// With `USRAY_WRITE_PNG=DIR` the B-mode is also written to `DIR/pwi_disk_bmode.png`.
#[test]
fn pwi_disk_import_then_bmode() {
    let Some(path) = usray_testdata::data_file("real/PWI_disk.mat") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let stem = dir.path().join("PWI_disk");
    usray::signal::write_channels(&stem, &import_mat(&path).unwrap()).unwrap();
    let ch = usray::signal::read_channels(stem.with_extension("json")).unwrap();
    let frames = ch.meta.frames().unwrap();
    assert_eq!(frames.len(), 32);
    assert!(frames.iter().enumerate().all(|(k, g)| g == &vec![k]));
    let mut s = usray::signal::ImagingSettings::new([-15e-3, 15e-3], [5e-3, 40e-3], 0.2e-3);
    s.f_number = 1.0;
    let b = usray::signal::BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
    assert_eq!(b.n_frames(), 32);
    let mut ws = b.workspace();
    let img = b.forward(&ch, &mut ws).unwrap();
    if let Some(d) = std::env::var_os("USRAY_WRITE_PNG") {
        img.write_png(std::path::Path::new(&d).join("pwi_disk_bmode.png"))
            .unwrap();
    }
    let (radius, contrast) = fit_disk(ws.envelope(), &img.x_m, &img.z_m);
    eprintln!(
        "import + BMode (32 frames): radius {:.3} mm, contrast {contrast:.1} dB",
        radius * 1e3
    );
    assert!(
        (radius - 10e-3).abs() <= 0.3e-3,
        "fitted radius {} mm",
        radius * 1e3
    );
    assert!(contrast > 15.0, "disk/background contrast {contrast} dB");
}

/// Full-matrix capture `real/ArraySteelPins.mat` summed to a 0° plane wave (pitch
/// 1 mm and f_c 3.5 MHz supplied: the file stores neither). The README's TFM puts
/// two pins at (+10.6, 38.2) mm and (−9.6, 43.2) mm (t0 = MWB, no pulse-delay
/// correction); the two brightest separated peaks of the plane-wave image must lie
/// within 0.5 mm of them.
#[test]
fn steel_pins_fmc_as_plane_wave() {
    let Some(path) = usray_testdata::data_file("real/ArraySteelPins.mat") else {
        return;
    };
    // The file stores no centre frequency: estimated from the samples, it lands
    // between the measured spectrum's 3.09 MHz peak and 3.53 MHz centroid
    // (README §2), widened by the estimator's 3 % accuracy on a known pulse
    // (`import::samples` unit test).
    let pitch_only = usray::signal::ImportOptions {
        pitch_m: Some(1e-3),
        ..Default::default()
    };
    let fc = usray::signal::import_mat_with(&path, &pitch_only)
        .unwrap()
        .meta
        .center_frequency_hz;
    eprintln!("pins: centre frequency estimated at {:.3} MHz", fc / 1e6);
    assert!((0.97 * 3.09e6..=1.03 * 3.53e6).contains(&fc), "{fc} Hz");
    let opts = usray::signal::ImportOptions {
        pitch_m: Some(1e-3),
        center_frequency_hz: Some(3.5e6),
        ..Default::default()
    };
    let ch = usray::signal::import_mat_with(&path, &opts).unwrap();
    assert_eq!(
        (ch.n_transmits(), ch.n_elements(), ch.n_samples),
        (1, 32, 1750)
    );
    assert_eq!(
        (
            ch.meta.t0_s,
            ch.meta.sampling_frequency_hz,
            ch.meta.sound_speed_m_s
        ),
        (40e-6, 50e6, 1480.0)
    );
    let mut s = usray::signal::ImagingSettings::new([-15e-3, 15e-3], [30e-3, 50e-3], 0.05e-3);
    s.f_number = 0.0;
    let b = usray::signal::BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
    let mut ws = b.workspace();
    let img = b.forward(&ch, &mut ws).unwrap();
    let env = ws.envelope().to_vec();
    let k1 = usray::signal::post::argmax(&env);
    let p1 = (img.x_m[k1 % img.nx], img.z_m[k1 / img.nx]);
    // Second peak: brightest pixel more than 5 mm from the first.
    let mut k2 = 0;
    for (k, &e) in env.iter().enumerate() {
        let p = (img.x_m[k % img.nx], img.z_m[k / img.nx]);
        if ((p.0 - p1.0).powi(2) + (p.1 - p1.1).powi(2)).sqrt() > 5e-3 && e > env[k2] {
            k2 = k;
        }
    }
    let p2 = (img.x_m[k2 % img.nx], img.z_m[k2 / img.nx]);
    eprintln!(
        "pins found at ({:.2}, {:.2}) mm and ({:.2}, {:.2}) mm, ratio {:.1} dB",
        p1.0 * 1e3,
        p1.1 * 1e3,
        p2.0 * 1e3,
        p2.1 * 1e3,
        20.0 * (env[k1] / env[k2]).log10()
    );
    let truth = [(10.6e-3, 38.2e-3), (-9.6e-3, 43.2e-3)];
    for t in truth {
        let d = [p1, p2]
            .iter()
            .map(|p| ((p.0 - t.0).powi(2) + (p.1 - t.1).powi(2)).sqrt())
            .fold(f64::MAX, f64::min);
        assert!(
            d < 0.5e-3,
            "pin at {t:?}: nearest peak {:.2} mm away",
            d * 1e3
        );
    }
}

/// `ArrayCuBlockStationary.mat` (full-matrix capture; only the pitch, 1 mm, is
/// not in the file) imports and its B-mode puts the copper block's front surface
/// where the data's description says: the pulse-echo surface echo peaks at
/// 32.44 µs, 24.0 mm at 1480 m/s (shared/data/real/README.md §3; 23.5 mm after the
/// repository's 0.7 µs pulse delay, which the import does not correct).
#[test]
fn copper_block_surface_at_its_stated_depth() {
    let Some(path) = usray_testdata::data_file("real/ArrayCuBlockStationary.mat") else {
        return;
    };
    let e = import_mat(&path).unwrap_err().to_string();
    assert!(e.contains("pitch"), "{e}");
    let opts = usray::signal::ImportOptions {
        pitch_m: Some(1e-3),
        ..Default::default()
    };
    let ch = usray::signal::import_mat_with(&path, &opts).unwrap();
    assert_eq!(ch.meta.center_frequency_hz, 3.5e6);
    let mut s = usray::signal::ImagingSettings::new([-5e-3, 5e-3], [18e-3, 30e-3], 0.05e-3);
    s.f_number = 0.0;
    let b = usray::signal::BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
    let mut ws = b.workspace();
    let img = b.forward(&ch, &mut ws).unwrap();
    // The surface echo: the rows (envelope summed across x) within 6 dB of the
    // brightest. The clipped, three-cycle echo has several envelope lobes, so its
    // extent is tested, not its brightest row: it must hold the stated depth and
    // be no longer than the pulse and its clipping make it — the clipped span
    // 31.9–33.5 µs (README §3 pitfall 2; 1.2 mm at 1480 m/s, two-way), plus the
    // three-cycle pulse (0.86 µs, 0.64 mm), plus the IQ low-pass's spread (its
    // cut-off fc/2 = 1.75 MHz, about 1 µs, 0.7 mm, forward and backward): 2.5 mm,
    // rounded up to 3 mm.
    let env = ws.envelope();
    let rows: Vec<f64> = (0..img.nz)
        .map(|iz| env[iz * img.nx..(iz + 1) * img.nx].iter().sum::<f64>())
        .collect();
    let top = rows.iter().cloned().fold(0.0, f64::max);
    let loud: Vec<f64> = (0..img.nz)
        .filter(|&iz| rows[iz] >= top / 2.0)
        .map(|iz| img.z_m[iz])
        .collect();
    let (first, last) = (loud[0], loud[loud.len() - 1]);
    eprintln!(
        "copper block surface echo from z = {:.2} to {:.2} mm",
        first * 1e3,
        last * 1e3
    );
    assert!(
        first <= 24.0e-3 && 24.0e-3 <= last && last - first < 3e-3,
        "surface echo from {first} to {last} m"
    );
}
