//! The receive-delay lattice of flat arrays on uniform Cartesian grids: the
//! fast path of [`Das`] (same formula as [`Das::forward`]'s per-pixel delays,
//! tabulated once per distinct `x − x_e`).

use rayon::prelude::*;
use rustfft::num_complex::Complex64;

use super::{Das, TAU};

/// Receive delays and phases on a lattice: when the pixel grid is uniform in `x`
/// and the pitch is an integer multiple `k` of its step `h` (e.g. 0.1 mm pixels,
/// 0.3 mm pitch), `x − x_e` only takes `nx + k(N−1)` distinct values per row, so
/// the square root and the phase are computed once per value rather than once per
/// (pixel, element). Index `j = ix + k(N − 1 − e)`.
pub(super) struct RxTable {
    pub(super) k: usize,
    pub(super) len: usize,
    pub(super) trx: Vec<f64>,
    pub(super) rrx: Vec<Complex64>,
    pub(super) ok: Vec<bool>,
}

impl Das {
    /// `k` if the x grid is uniform with step `h` and `pitch = k·h` (to 1e-12).
    fn lattice_step(&self) -> Option<usize> {
        let nx = self.x_m.len();
        if nx < 2 || self.polar.is_some() || !self.kind.is_flat() {
            return None;
        }
        let (x0, x1) = (self.x_m[0], self.x_m[nx - 1]);
        let h = (x1 - x0) / (nx - 1) as f64;
        if h.is_nan() || h <= 0.0 {
            return None;
        }
        let scale = x0.abs().max(x1.abs()).max(h);
        if self
            .x_m
            .iter()
            .enumerate()
            .any(|(i, &x)| (x - (x0 + i as f64 * h)).abs() > 1e-12 * scale)
        {
            return None;
        }
        let r = self.pitch_m / h;
        let k = r.round();
        ((1.0..=64.0).contains(&k) && (r - k).abs() <= 1e-12 * r).then_some(k as usize)
    }

    pub(super) fn rx_table(&self) -> Option<RxTable> {
        let k = self.lattice_step()?;
        let (nx, ne) = (self.x_m.len(), self.n_elements);
        let len = nx + k * (ne - 1);
        let h = (self.x_m[nx - 1] - self.x_m[0]) / (nx - 1) as f64;
        let mid = (ne as f64 - 1.0) / 2.0;
        let (c, w) = (self.sound_speed_m_s, TAU * self.fc_hz);
        let n = len * self.z_m.len();
        let mut trx = vec![0.0; n];
        let mut rrx = vec![Complex64::new(1.0, 0.0); n];
        let mut ok = vec![false; n];
        trx.par_chunks_mut(len)
            .zip(rrx.par_chunks_mut(len))
            .zip(ok.par_chunks_mut(len))
            .enumerate()
            .for_each(|(iz, ((tr, rr), okr))| {
                let z = self.z_m[iz];
                for j in 0..len {
                    let dx =
                        self.x_m[0] + (j as f64 - (k * (ne - 1)) as f64) * h + mid * self.pitch_m;
                    okr[j] = self.in_aperture(dx, z, [0.0, 1.0]);
                    tr[j] = (dx * dx + z * z).sqrt() / c;
                    if self.rotate {
                        let (sn, co) = (w * tr[j]).sin_cos();
                        rr[j] = Complex64::new(co, sn);
                    }
                }
            });
        Some(RxTable {
            k,
            len,
            trx,
            rrx,
            ok,
        })
    }
}
