//! The receiver responses of volume scatterers, traced once per scatterer and
//! element and reused by every event at that scatterer (step 3a of the module
//! docs of [`super`]).
//!
//! A volume-scattering event snaps to a scatterer of a fixed grid
//! ([`crate::effects::ScattererField::scatterer_near`]), and its receiver
//! connection to element `e` — the straight line from the scatterer to the
//! element's centre, its boundary crossings, attenuation, the element's
//! directivity and solid angle and, in 2-D, the point source's spreading —
//! depends on the scatterer, the element and the scene's parameters, never on
//! the path that lit the scatterer. The echo of an event is the product of
//! what reached the scatterer (amplitude, attenuation exponent, time) and that
//! response (`a = a_q·R_e`, `β = β_q + β_e`, `τ = τ_q + τ_e`), so a chunk of
//! paths traces each response once. On a speckled lumen, where about a
//! thousand events per transmit light each scatterer, the connections were
//! four fifths of a render's time (`docs/performance.md`).
//!
//! A response is a pure function of its key and the lifted scene: whether it
//! comes from the cache or is traced afresh, the deposit is the same, bit for
//! bit, so renders stay independent of the thread count and of how paths are
//! grouped. A cache whose values live on a rewound reverse-mode tape must not
//! outlive its path: the reverse replay uses [`Responses::disabled`].

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use usray_ad::Real;
use usray_geometry::MediumStack;

/// The largest memory one cache may hold, bytes: scatterers beyond are traced
/// every time (a response of 8 dual partials takes about 220 bytes, so the
/// responses of about 1 100 scatterers on 64 elements fit: a 2-D lumen holds a
/// few hundred).
const MAX_CACHE_BYTES: usize = 16 << 20;

/// A scatterer's connection to one element (see the module docs): the factor
/// its echo's amplitude takes, and what the line adds to its attenuation
/// exponent and time.
#[derive(Clone, Copy, Debug)]
pub(super) struct Response<T> {
    /// Boundary transmissions × attenuation × solid angle × directivity (×
    /// the 2-D point source's spreading).
    pub amplitude: T,
    /// Attenuation exponent added along the line, Np/Hz.
    pub beta: T,
    /// Travel time from the scatterer to the element, s.
    pub time: T,
}

/// Which scatterer, seen from where.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) struct ScattererKey {
    /// The field's key ([`crate::effects::ScattererField::key`]).
    pub field: u64,
    /// The scatterer's grid cell.
    pub cell: [i64; 3],
    /// The media its connections leave into (the event's segment's).
    pub stack: MediumStack,
}

/// A response slot: not traced yet (`None`), blocked (`Some(None)`: total
/// reflection, zero directivity, too many crossings) or known.
type Slot<T> = Option<Option<Response<T>>>;

/// The responses traced so far: each scatterer met owns one slot per element
/// in `slots`, from the index `map` gives it.
pub(crate) struct Responses<T> {
    map: HashMap<ScattererKey, usize, BuildHasherDefault<WordHasher>>,
    slots: Vec<Slot<T>>,
    capacity: usize,
}

impl<T: Real> Responses<T> {
    /// An empty cache, bounded in memory ([`MAX_CACHE_BYTES`]).
    pub(crate) fn new() -> Self {
        Self {
            map: HashMap::default(),
            slots: Vec::new(),
            capacity: MAX_CACHE_BYTES / size_of::<Slot<T>>().max(1),
        }
    }

    /// A cache that keeps nothing: every response is traced.
    pub(crate) fn disabled() -> Self {
        Self {
            capacity: 0,
            ..Self::new()
        }
    }

    /// Where the `n_elements` slots of scatterer `key` start, made for it if
    /// it is new and the cache has room; `None` when it has none.
    pub(super) fn scatterer(&mut self, key: ScattererKey, n_elements: usize) -> Option<usize> {
        if self.capacity == 0 {
            return None; // disabled: nothing to look up
        }
        if let Some(&at) = self.map.get(&key) {
            return Some(at);
        }
        let at = self.slots.len();
        if at + n_elements > self.capacity {
            return None;
        }
        self.slots.resize(at + n_elements, None);
        self.map.insert(key, at);
        Some(at)
    }

    /// Slot `i` ([`Responses::scatterer`] + element).
    pub(super) fn get(&self, i: usize) -> Slot<T> {
        self.slots[i]
    }

    /// Keep `response` in slot `i`.
    pub(super) fn set(&mut self, i: usize, response: Option<Response<T>>) {
        self.slots[i] = Some(response);
    }
}

impl<T: Real> Default for Responses<T> {
    fn default() -> Self {
        Self::new()
    }
}

/// A fast hash of keys made of a few machine words (the multiply-rotate of
/// Firefox's and rustc's `FxHasher`): the keys are the tracer's own, so no
/// defence against chosen collisions is needed.
#[derive(Default)]
struct WordHasher(u64);

impl Hasher for WordHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }

    fn write_u64(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(5) ^ word).wrapping_mul(0x517c_c1b7_2722_0a95);
    }

    fn write_u32(&mut self, word: u32) {
        self.write_u64(u64::from(word));
    }

    fn write_u8(&mut self, word: u8) {
        self.write_u64(u64::from(word));
    }

    fn write_i64(&mut self, word: i64) {
        self.write_u64(word as u64);
    }

    fn write_usize(&mut self, word: usize) {
        self.write_u64(word as u64);
    }
}

#[cfg(test)]
mod tests {
    //! A cached response is the response: the deposits of paths sharing a
    //! cache, of paths with a cache too small for every scatterer, and of
    //! paths tracing every connection are the same, bit for bit.
    use super::*;
    use crate::integrator::{element_stack, trace_path_within};
    use crate::{RenderOptions, Scene};

    /// A ring (Z 1.9 MRayl, c 1600 m/s: its connections cross two refracting
    /// boundaries) with speckle in its wall and its lumen, in attenuating
    /// water; traced in `dimensions`.
    fn speckled_ring(dimensions: u8) -> Scene {
        let text = format!(
            "[medium]\nsound_speed_m_s = 1480.0\nimpedance_mrayl = 1.48\nattenuation_db_cm_mhz = 0.5\n\
             [probe]\nkind = \"linear\"\nn_elements = 32\npitch_m = 0.3e-3\nelement_width_m = 0.27e-3\n\
             center_frequency_hz = 2.5e6\ncycles = 1.2\nelevation_m = 4.0e-3\n\
             [acquisition]\nangles_deg = [0.0]\nsampling_frequency_hz = 40.0e6\nmax_depth_m = 0.03\n\
             rays_per_element = 6\nmax_bounces = 4\nseed = 3\nemission = \"plane_wave\"\ndimensions = {dimensions}\n\
             [imaging]\nx_range_m = [-0.005, 0.005]\nz_range_m = [0.008, 0.024]\npixel_m = 0.2e-3\nf_number = 1.5\ndynamic_range_db = 60.0\n\
             [materials.wall]\nimpedance_mrayl = 1.9\nsound_speed_m_s = 1600.0\nroughness = 0.1\n\
             scatterer_density_per_mm3 = 8.0\nscatterer_strength = 0.3\n\
             [[objects]]\nname = \"ring\"\nshape = \"cylinder\"\ncenter_m = [0.0, 0.0, 0.016]\n\
             radius_m = 0.005\nthickness_m = 0.6e-3\nmaterial = \"wall\"\n\
             lumen_scatterer_density_per_mm3 = 5.0\nlumen_scatterer_strength = 0.2\n"
        );
        Scene::from_toml_str(&text, "<speckled ring>", ".").unwrap()
    }

    /// Every deposit of the paths of three emitting elements, in bits, and the
    /// rays cast, with `responses` shared by all the paths.
    fn deposits(scene: &Scene, mut responses: Responses<f64>) -> (Vec<[u64; 4]>, u64) {
        let st = scene.lift(|_, v| v).unwrap();
        let s = crate::render::settings(scene, &RenderOptions::default());
        let (mut out, mut rays) = (Vec::new(), 0);
        for el in [3, 16, 28] {
            let stack = element_stack(&st, el);
            for ray in 0..s.rays_per_element {
                let counted = trace_path_within(
                    &st,
                    &s,
                    0,
                    el,
                    ray as u32,
                    stack,
                    None,
                    &mut responses,
                    |d| {
                        out.push([
                            u64::from(d.element),
                            d.amplitude.to_bits(),
                            d.time.to_bits(),
                            d.shift.to_bits(),
                        ])
                    },
                );
                rays += counted.rays;
            }
        }
        (out, rays)
    }

    #[test]
    fn cached_responses_give_the_deposits_of_traced_ones() {
        for dimensions in [2, 3] {
            let scene = speckled_ring(dimensions);
            let (traced, rays_traced) = deposits(&scene, Responses::disabled());
            let (cached, rays_cached) = deposits(&scene, Responses::new());
            // Room for the responses of three scatterers: the others are traced.
            let three = Responses {
                capacity: 3 * 32,
                ..Responses::new()
            };
            let (partly, rays_partly) = deposits(&scene, three);
            eprintln!(
                "{dimensions}-D: {} deposits; rays cast {rays_traced} traced, {rays_partly} with 3 scatterers cached, {rays_cached} cached",
                traced.len()
            );
            assert!(traced.len() > 10_000, "{} deposits", traced.len());
            assert!(cached == traced, "{dimensions}-D: cached deposits differ");
            assert!(
                partly == traced,
                "{dimensions}-D: partly cached deposits differ"
            );
            // The cache is used: scatterers lit by several paths are connected
            // once; in 2-D, where every path lights the same plane of them,
            // most connections are saved.
            assert!(rays_cached < rays_partly && rays_partly < rays_traced);
            if dimensions == 2 {
                assert!(2 * rays_cached < rays_traced);
            }
        }
    }
}
