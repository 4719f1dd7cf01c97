//! [`TraceSettings`]: the fixed settings of a trace, and the receivers each
//! interaction connects to.

use crate::scene::Sampler;

/// Fixed settings of a trace.
#[derive(Clone, Copy, Debug)]
pub struct TraceSettings {
    /// Acquisition seed.
    pub seed: u64,
    /// Maximum interactions per path.
    pub max_bounces: u32,
    /// Rays per element (deposits are divided by it).
    pub rays_per_element: usize,
    /// Receivers each interaction connects to (`acquisition.receivers_per_event`):
    /// `K ≥ N_e` (or 0) = every element, deterministically, weight 1; `K < N_e` =
    /// one element drawn uniformly in each of `K` contiguous strata, weight = the
    /// stratum's size (`N_e/K`); `K = 1` is the paper's uniform choice.
    pub receivers_per_event: usize,
    /// How an element's rays draw their random numbers (`acquisition.sampler`).
    pub sampler: Sampler,
}

impl TraceSettings {
    /// The receiving elements of one interaction and their estimator weights,
    /// from the interaction's uniform `u` (see
    /// [`TraceSettings::receivers_per_event`]): stratum `j` of `K` holds elements
    /// `⌊jN/K⌋ .. ⌊(j+1)N/K⌋`; its element is `lo + ⌊u·size⌋`, weight `size`.
    #[inline]
    pub fn receivers(&self, n_el: usize, u: f64) -> impl Iterator<Item = (usize, f64)> {
        let k = match self.receivers_per_event {
            0 => n_el,
            k => k.min(n_el),
        };
        (0..k).map(move |j| {
            if k == n_el {
                return (j, 1.0); // every element (the default): no divisions
            }
            let lo = j * n_el / k;
            let hi = (j + 1) * n_el / k;
            let size = hi - lo;
            let e = lo + ((u * size as f64) as usize).min(size - 1);
            (e, size as f64)
        })
    }

    /// The estimator weight [`TraceSettings::receivers`] gives element `e` (its
    /// stratum's size).
    pub fn receiver_weight(&self, n_el: usize, e: usize) -> f64 {
        let k = match self.receivers_per_event {
            0 => n_el,
            k => k.min(n_el),
        };
        (0..k)
            .map(|j| (j * n_el / k, (j + 1) * n_el / k))
            .find(|&(lo, hi)| (lo..hi).contains(&e))
            .map_or(1.0, |(lo, hi)| (hi - lo) as f64)
    }
}
