//! Variance and cost of the two samplers (`acquisition.sampler`), side by side
//! in one run (`harness = false`).
//!
//! For each shipped cylinder scene, `SEEDS` renders with each sampler at the
//! scene's rays per element, interleaved seed by seed:
//! - **far/near wall energy ratio** (dB): channel energy, over every transmit
//!   and element, in a two-way time window of ±1.5 mm around the far wall's echo
//!   (depth `z_c + r`) over the same around the near wall's (`z_c − r`); its
//!   standard deviation over seeds is the Monte Carlo noise of the quantity a
//!   depth gain or an attenuation changes;
//! - **relative channel noise**: `Σ‖P_i − P_j‖² / (2 Σ‖P‖²)` over seed pairs,
//!   the per-render variance of the channel data per unit signal energy;
//! - median seconds per render.
//!
//! The *efficiency* gain is variance ratio × time ratio (independent over
//! stratified): how many times more rays the independent sampler needs for the
//! same noise.
//!
//! The two samplers' mean *energy* ratios differ by a few standard errors
//! because a render's energy is the signal's plus its noise variance, which the
//! samplers do not share. The ratio of the energies of the *expected* data,
//! estimated without that bias from cross products of distinct renders,
//! `Σ_{i≠j} ⟨P_i, P_j⟩ / (n(n−1))` in each window, with a jackknife standard
//! error, must agree between the samplers (and `tests/sampler.rs` checks a
//! linear functional of the data).
//!
//! Run: `cargo bench -p usray-transport --bench sampler`

use std::time::Instant;
use usray_transport::scene::{Sampler, ShapeKind};
use usray_transport::{render, RenderOptions, Scene};

/// Seeds per sampler.
const SEEDS: u64 = 16;

/// Half-width of each wall's depth window, m.
const WINDOW_M: f64 = 1.5e-3;

include!("common/bench_util.rs");

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
    (m, var.sqrt())
}

/// Per sampler: (far/near ratios in dB, channel data, seconds) of every seed.
struct Runs {
    ratios_db: Vec<f64>,
    data: Vec<Vec<f64>>,
    seconds: Vec<f64>,
    /// Each render's samples in the near and the far wall's window.
    windows: Vec<[Vec<f64>; 2]>,
}

impl Runs {
    /// Far/near energy ratio (dB) of the expected data over the renders `keep`:
    /// each window's `Σ_{i≠j} ⟨P_i, P_j⟩` (unbiased for `‖E P‖²`).
    fn expected_ratio_db(&self, keep: &[usize]) -> f64 {
        let cross = |w: usize| -> f64 {
            let n = self.windows[0][w].len();
            let mut sum = vec![0.0; n];
            let mut squares = 0.0;
            for &i in keep {
                for (s, x) in sum.iter_mut().zip(&self.windows[i][w]) {
                    *s += x;
                    squares += x * x;
                }
            }
            sum.iter().map(|s| s * s).sum::<f64>() - squares
        };
        10.0 * (cross(1) / cross(0)).log10()
    }

    /// [`Runs::expected_ratio_db`] over every render and its jackknife
    /// standard error.
    fn expected_ratio_with_se(&self) -> (f64, f64) {
        let n = self.windows.len();
        let all: Vec<usize> = (0..n).collect();
        let leave_one: Vec<f64> = (0..n)
            .map(|i| {
                let keep: Vec<usize> = (0..n).filter(|&j| j != i).collect();
                self.expected_ratio_db(&keep)
            })
            .collect();
        let m = leave_one.iter().sum::<f64>() / n as f64;
        let var =
            (n - 1) as f64 / n as f64 * leave_one.iter().map(|x| (x - m).powi(2)).sum::<f64>();
        (self.expected_ratio_db(&all), var.sqrt())
    }

    fn relative_noise(&self) -> f64 {
        let energy: f64 = self
            .data
            .iter()
            .map(|d| d.iter().map(|x| x * x).sum::<f64>())
            .sum::<f64>()
            / self.data.len() as f64;
        let (mut sum, mut pairs) = (0.0, 0usize);
        for i in 0..self.data.len() {
            for j in i + 1..self.data.len() {
                let d: f64 = self.data[i]
                    .iter()
                    .zip(&self.data[j])
                    .map(|(a, b)| (a - b).powi(2))
                    .sum();
                sum += d;
                pairs += 1;
            }
        }
        sum / pairs as f64 / (2.0 * energy)
    }
}

fn main() {
    for name in ["diagnose/blind_base.toml", "cylinder.toml"] {
        let base = scene(name);
        let cyl = base
            .objects
            .iter()
            .find(|o| o.shape == ShapeKind::Cylinder)
            .expect("a cylinder");
        let (zc, r) = (cyl.center_m[2], cyl.radius_m.expect("radius"));
        let c = base.medium.sound_speed_m_s;
        let fs = base.acquisition.sampling_frequency_hz;
        // Sample index range of a two-way depth window (t0 = 0, CONTRACT §1).
        let window = |z: f64| {
            let k0 = (2.0 * (z - WINDOW_M) / c * fs).floor() as usize;
            let k1 = (2.0 * (z + WINDOW_M) / c * fs).ceil() as usize;
            k0..k1
        };
        let (near, far) = (window(zc - r), window(zc + r));
        let mut runs: Vec<Runs> = (0..2)
            .map(|_| Runs {
                ratios_db: vec![],
                data: vec![],
                seconds: vec![],
                windows: vec![],
            })
            .collect();
        for seed in 0..SEEDS {
            for (k, sampler) in [Sampler::Independent, Sampler::Stratified]
                .into_iter()
                .enumerate()
            {
                let mut s = base.clone();
                s.acquisition.sampler = sampler;
                let opts = RenderOptions {
                    seed: Some(1000 + seed),
                    ..Default::default()
                };
                let t = Instant::now();
                let (ch, _) = render(&s, &opts).expect("render");
                runs[k].seconds.push(t.elapsed().as_secs_f64());
                let window = |range: &std::ops::Range<usize>| -> Vec<f64> {
                    ch.samples
                        .chunks(ch.n_samples)
                        .flat_map(|rec| {
                            rec[range.start.min(rec.len())..range.end.min(rec.len())]
                                .iter()
                                .copied()
                        })
                        .collect()
                };
                let (near_w, far_w) = (window(&near), window(&far));
                let energy = |w: &[f64]| w.iter().map(|x| x * x).sum::<f64>();
                runs[k]
                    .ratios_db
                    .push(10.0 * (energy(&far_w) / energy(&near_w)).log10());
                runs[k].data.push(ch.samples);
                runs[k].windows.push([near_w, far_w]);
            }
        }
        println!(
            "{name}: {} rays/element, {SEEDS} seeds per sampler",
            base.acquisition.rays_per_element
        );
        println!(
            "| sampler | far/near ratio, dB (mean ± sd) | of the expected data (± SE) | relative channel noise | s/render |"
        );
        println!("|---|---|---|---|---|");
        for (k, label) in ["independent", "stratified"].iter().enumerate() {
            let (m, sd) = mean_sd(&runs[k].ratios_db);
            let (e, se) = runs[k].expected_ratio_with_se();
            println!(
                "| {label} | {m:+.3} ± {sd:.3} | {e:+.3} ± {se:.3} | {:.4e} | {:.3} |",
                runs[k].relative_noise(),
                median(runs[k].seconds.clone())
            );
        }
        let sd = |k: usize| mean_sd(&runs[k].ratios_db).1;
        let t = |k: usize| median(runs[k].seconds.clone());
        let var_ratio = runs[0].relative_noise() / runs[1].relative_noise();
        println!(
            "independent / stratified: ratio variance ×{:.1}, channel noise ×{var_ratio:.2}, time ×{:.2}; efficiency (channel noise × time) ×{:.2}\n",
            (sd(0) / sd(1)).powi(2),
            t(0) / t(1),
            var_ratio * t(0) / t(1)
        );
    }
}
