//! Counter-based random numbers (pbrt-v4 style): every sample is a pure hash of
//! its key `(seed, transmit, element, ray, branches, bounce, dimension)`.
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

/// The random numbers of one path: key `(seed, transmit, element, ray)` fixed,
/// `(bounce, dimension)` chosen per call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathSampler {
    base: u64,
}

impl PathSampler {
    /// The sampler of path `ray` emitted by `element` in transmit `transmit`.
    pub fn new(seed: u64, transmit: u32, element: u32, ray: u32) -> Self {
        let h = fold(mix64(seed ^ 0x5851_f42d_4c95_7f2d), u64::from(transmit));
        let h = fold(h, u64::from(element));
        Self {
            base: fold(h, u64::from(ray)),
        }
    }

    /// The sampler of one branch of this path (`branch` 0 = reflected, 1 =
    /// transmitted continuation of the current vertex): a new key, so the two
    /// continuations of a split draw independent numbers at their later vertices.
    #[inline]
    pub fn branch(&self, branch: u32) -> Self {
        Self {
            base: fold(self.base, 0x6272_616e_6368 ^ u64::from(branch)),
        }
    }

    /// The raw 64-bit hash of `(bounce, dimension)` on this path.
    #[inline]
    pub fn bits(&self, bounce: u32, dimension: u32) -> u64 {
        fold(fold(self.base, u64::from(bounce)), u64::from(dimension))
    }

    /// A uniform sample in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn uniform(&self, bounce: u32, dimension: u32) -> f64 {
        (self.bits(bounce, dimension) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

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
}
