//! Counter-based random numbers (pbrt-v4 style): every sample is a pure hash of
//! its key `(seed, transmit, element, ray, branches, bounce, dimension)`.
//!
//! **Stratification across an element's rays** ([`PathSampler::stratified`]):
//! the `N` rays of one element and transmit share, for every decision
//! `(branches, bounce, dimension)`, one keyed permutation `π` of `0..N`, and ray
//! `r` draws `u = (π(r) + ξ_r)/N` with its own jitter `ξ_r` — a Latin hypercube
//! over the rays (McKay, Beckman & Conover 1979; pbrt-v4's padded stratified
//! samples). Every sample is still uniform on `[0, 1)` and the dimensions of one
//! ray are still independent, so every estimator keeps its expectation; the `N`
//! emission points of an element are spread evenly over its face instead of
//! clumping, which is what the echo of a wall integrates. The permutation is
//! Kensler's hash-based one (2013, "Correlated Multi-Jittered Sampling",
//! Pixar Technical Memo 13-01, `permute`), so no table is built and a path
//! replay (gradients) reads the same numbers.
//!
//! No generator state is carried by a thread, so one thread and many produce
//! bit-identical samples, and a replay of a path (for gradients, `DESIGN.md`)
//! sees exactly the same numbers (common random numbers). The hash is the
//! SplitMix64 finaliser (Steele, Lea & Flood 2014, "Fast splittable pseudorandom
//! number generators") applied to each key component in turn.

/// SplitMix64 finaliser: a bijective 64-bit mix with full avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Fold one more key component into a running hash.
#[inline]
fn fold(h: u64, k: u64) -> u64 {
    mix64(
        h ^ k
            .wrapping_add(0x9e37_79b9_7f4a_7c15)
            .wrapping_mul(0xd6e8_feb8_6659_fd93),
    )
}

/// Which dimension of a bounce a sample drives. Fixed numbering so that a path
/// replay reads the same number for the same decision.
pub mod dim {
    /// Emission: position across the element width.
    pub const EMIT_X: u32 = 0;
    /// Emission: position across the elevation extent.
    pub const EMIT_Y: u32 = 1;
    /// Emission: first direction sample (cosine hemisphere, radius).
    pub const EMIT_U1: u32 = 2;
    /// Emission: second direction sample (cosine hemisphere, azimuth).
    pub const EMIT_U2: u32 = 3;
    /// Surface: first microfacet-normal sample (Heitz 2018).
    pub const GGX_U1: u32 = 4;
    /// Surface: second microfacet-normal sample.
    pub const GGX_U2: u32 = 5;
    /// Receiver connection: which element (uniform).
    pub const ELEMENT: u32 = 7;
    /// Volume: free-flight distance to the next scatterer.
    pub const FREE_FLIGHT: u32 = 8;
    /// Volume scatterer events within one segment start at this dimension.
    pub const VOLUME_BASE: u32 = 16;
}

/// Kensler's keyed permutation of `0..len` (2013, "Correlated Multi-Jittered
/// Sampling", §3 `permute`; pbrt-v4 `PermutationElement`): element `i` of the
/// permutation keyed by `key`. Every step is a bijection of the `w`-bit integers
/// (`2^w ≥ len`: xor-shifts within the mask, odd multiplications modulo `2^32`,
/// whose low bits depend only on low bits), cycle-walked until the image falls
/// below `len`, then rotated by the key.
///
/// ```
/// use usray_transport::rng::permutation_element;
/// let mut seen: Vec<u32> = (0..20).map(|i| permutation_element(i, 20, 0xabcd)).collect();
/// seen.sort_unstable();
/// assert_eq!(seen, (0..20).collect::<Vec<_>>());
/// ```
///
/// # Panics
/// Debug builds panic if `i >= len`.
#[inline]
pub fn permutation_element(mut i: u32, len: u32, key: u32) -> u32 {
    debug_assert!(i < len, "permutation index {i} out of 0..{len}");
    let p = key;
    let mut w = len.wrapping_sub(1);
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
        i ^= p;
        i = i.wrapping_mul(0xe170_893d);
        i ^= p >> 16;
        i ^= (i & w) >> 4;
        i ^= p >> 8;
        i = i.wrapping_mul(0x0929_eb3f);
        i ^= p >> 23;
        i ^= (i & w) >> 1;
        i = i.wrapping_mul(1 | p >> 27);
        i = i.wrapping_mul(0x6935_fa69);
        i ^= (i & w) >> 11;
        i = i.wrapping_mul(0x74dc_b303);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0x9e50_1cc3);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0xc860_a3df);
        i &= w;
        i ^= i >> 5;
        if i < len {
            break;
        }
    }
    ((u64::from(i) + u64::from(p)) % u64::from(len)) as u32
}

/// The random numbers of one path: key `(seed, transmit, element, ray)` fixed,
/// `(bounce, dimension)` chosen per call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathSampler {
    /// Hash of the whole key: this ray's own numbers (the jitter `ξ_r`).
    base: u64,
    /// Hash of the key without the ray: shared by the element's rays (the
    /// permutations `π`).
    strata: u64,
    /// This ray's index and the number of rays stratified together (1: none).
    ray: u32,
    rays: u32,
}

impl PathSampler {
    /// The sampler of path `ray` emitted by `element` in transmit `transmit`,
    /// independent of the element's other rays.
    pub fn new(seed: u64, transmit: u32, element: u32, ray: u32) -> Self {
        Self::stratified(seed, transmit, element, ray, 1)
    }

    /// The sampler of path `ray` of `rays` emitted by `element` in transmit
    /// `transmit`, stratified with the other `rays − 1` (module docs). With
    /// `rays = 1` it is [`PathSampler::new`], bit for bit.
    ///
    /// ```
    /// use usray_transport::rng::PathSampler;
    /// // The 8 rays of one element fall one in each eighth of [0, 1).
    /// let mut strata: Vec<usize> = (0..8)
    ///     .map(|r| (PathSampler::stratified(3, 0, 5, r, 8).uniform(0, 0) * 8.0) as usize)
    ///     .collect();
    /// strata.sort_unstable();
    /// assert_eq!(strata, (0..8).collect::<Vec<_>>());
    /// ```
    ///
    /// # Panics
    /// Debug builds panic if `rays > 1` and `ray >= rays` (with one ray any
    /// index is an independent path).
    pub fn stratified(seed: u64, transmit: u32, element: u32, ray: u32, rays: u32) -> Self {
        debug_assert!(rays <= 1 || ray < rays, "ray {ray} out of 0..{rays}");
        let h = fold(mix64(seed ^ 0x5851_f42d_4c95_7f2d), u64::from(transmit));
        let h = fold(h, u64::from(element));
        Self {
            base: fold(h, u64::from(ray)),
            strata: fold(h, 0x7374_7261_7461),
            ray,
            rays: rays.max(1),
        }
    }

    /// The sampler of one branch of this path (`branch` 0 = reflected, 1 =
    /// transmitted continuation of the current vertex): a new key, so the two
    /// continuations of a split draw independent numbers at their later vertices
    /// (still stratified with the same branch of the element's other rays).
    #[inline]
    pub fn branch(&self, branch: u32) -> Self {
        let k = 0x6272_616e_6368 ^ u64::from(branch);
        Self {
            base: fold(self.base, k),
            strata: fold(self.strata, k),
            ..*self
        }
    }

    /// The raw 64-bit hash of `(bounce, dimension)` on this path.
    #[inline]
    pub fn bits(&self, bounce: u32, dimension: u32) -> u64 {
        fold(fold(self.base, u64::from(bounce)), u64::from(dimension))
    }

    /// A uniform sample in `[0, 1)`: `(π(ray) + ξ)/rays` with `ξ` this ray's
    /// own 53-bit uniform and `π` the permutation the element's rays share for
    /// `(bounce, dimension)` (module docs); `ξ` itself for one ray.
    #[inline]
    pub fn uniform(&self, bounce: u32, dimension: u32) -> f64 {
        let xi = (self.bits(bounce, dimension) >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        if self.rays == 1 {
            return xi;
        }
        let key = fold(fold(self.strata, u64::from(bounce)), u64::from(dimension));
        let stratum = permutation_element(self.ray, self.rays, (key >> 32) as u32);
        // (stratum + ξ)/N < 1 in f64 for N < 2^32 except where rounding reaches 1.
        ((f64::from(stratum) + xi) / f64::from(self.rays)).min(ONE_BELOW)
    }
}

/// The largest `f64` below 1.
const ONE_BELOW: f64 = 1.0 - f64::EPSILON / 2.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keyed_and_uniform() {
        let s = PathSampler::new(1, 0, 3, 7);
        assert_eq!(s.uniform(2, 5), PathSampler::new(1, 0, 3, 7).uniform(2, 5));
        assert_ne!(s.uniform(2, 5), PathSampler::new(2, 0, 3, 7).uniform(2, 5));
        assert_ne!(s.uniform(2, 5), s.uniform(2, 6));
        let n = 100_000;
        let mean: f64 = (0..n)
            .map(|i| PathSampler::new(9, 0, 0, i).uniform(0, 0))
            .sum::<f64>()
            / n as f64;
        // Standard error of the mean of U(0,1) is 1/sqrt(12 n) = 9.1e-4.
        assert!((mean - 0.5).abs() < 4.0 * 9.2e-4, "mean {mean}");
    }

    #[test]
    fn permutation_is_a_bijection() {
        for len in 1..=70u32 {
            for key in [0u32, 1, 0xdead_beef, 0x8000_0001, 12_345] {
                let mut seen = vec![false; len as usize];
                for i in 0..len {
                    let j = permutation_element(i, len, key) as usize;
                    assert!(!seen[j], "len {len} key {key}: {j} twice");
                    seen[j] = true;
                }
            }
        }
    }

    /// Each ray of a stratified element keeps the uniform marginal: χ² of the
    /// first sample of ray 3 of 7 over 20 000 seeds in 20 bins (19 degrees of
    /// freedom; 43.8 is the 0.999 quantile), and of a later bounce's sample on a
    /// branch.
    #[test]
    fn stratified_marginal_is_uniform() {
        let (n, bins) = (20_000u64, 20usize);
        for (bounce, dimension, branch) in [(0, 0, None), (2, 5, Some(1))] {
            let mut counts = vec![0.0; bins];
            for seed in 0..n {
                let mut s = PathSampler::stratified(seed, 1, 4, 3, 7);
                if let Some(b) = branch {
                    s = s.branch(b);
                }
                counts[(s.uniform(bounce, dimension) * bins as f64) as usize] += 1.0;
            }
            let expected = n as f64 / bins as f64;
            let chi2: f64 = counts
                .iter()
                .map(|c| (c - expected).powi(2) / expected)
                .sum();
            assert!(chi2 < 43.8, "χ² {chi2} at bounce {bounce} dim {dimension}");
        }
    }

    /// The rays of one element fill every stratum once, for every decision and
    /// branch; two dimensions of one ray are uncorrelated over seeds (the
    /// correlation of 20 000 independent pairs has standard error 0.0071).
    #[test]
    fn stratified_rays_fill_their_strata_independently_per_dimension() {
        let rays = 13;
        for (bounce, dimension) in [(0, 0), (0, 1), (3, 4)] {
            let mut strata: Vec<u32> = (0..rays)
                .map(|r| {
                    let u = PathSampler::stratified(9, 2, 1, r, rays)
                        .branch(0)
                        .uniform(bounce, dimension);
                    (u * f64::from(rays)) as u32
                })
                .collect();
            strata.sort_unstable();
            assert_eq!(strata, (0..rays).collect::<Vec<_>>());
        }
        let n = 20_000;
        let pairs: Vec<(f64, f64)> = (0..n)
            .map(|seed| {
                let s = PathSampler::stratified(seed, 0, 0, 2, 5);
                (s.uniform(0, 0) - 0.5, s.uniform(0, 1) - 0.5)
            })
            .collect();
        let corr = pairs.iter().map(|(a, b)| a * b).sum::<f64>() / n as f64 * 12.0;
        assert!(corr.abs() < 4.0 * 0.0071, "correlation {corr}");
    }

    /// With one ray the sampler draws what the independent sampler drew before
    /// stratification existed: the formula of that version, written out.
    #[test]
    fn one_ray_is_the_independent_sampler() {
        let old_base = |seed: u64, tx: u64, el: u64, ray: u64| {
            fold(fold(fold(mix64(seed ^ 0x5851_f42d_4c95_7f2d), tx), el), ray)
        };
        let old_uniform = |base: u64, bounce: u64, dim: u64| {
            (fold(fold(base, bounce), dim) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
        };
        let base = old_base(5, 1, 2, 9);
        let branched = fold(base, 0x6272_616e_6368 ^ 1);
        for s in [
            PathSampler::new(5, 1, 2, 9),
            PathSampler::stratified(5, 1, 2, 9, 1),
        ] {
            assert_eq!(s.uniform(1, 4).to_bits(), old_uniform(base, 1, 4).to_bits());
            assert_eq!(
                s.branch(1).uniform(2, 0).to_bits(),
                old_uniform(branched, 2, 0).to_bits()
            );
        }
        // Stratified over several rays, the numbers differ.
        assert_ne!(
            PathSampler::stratified(5, 1, 2, 1, 4)
                .uniform(1, 4)
                .to_bits(),
            old_uniform(old_base(5, 1, 2, 1), 1, 4).to_bits()
        );
    }
}
