//! The TOML schema of CONTRACT §3 (every table rejects unknown keys) and its
//! validation rules.

use super::{Scene, SceneError};
use serde::{Deserialize, Serialize};
use usray_signal::ImagingSettings;

/// `[medium]`: the background medium the probe is coupled to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Medium {
    /// Sound speed, m/s (used for transport).
    pub sound_speed_m_s: f64,
    /// Acoustic impedance, MRayl.
    pub impedance_mrayl: f64,
    /// Attenuation, dB/(cm·MHz) (effect `attenuation`; 0 = off).
    #[serde(default)]
    pub attenuation_db_cm_mhz: f64,
}

/// `[probe]`: a linear, phased or convex array (CONTRACT §1 frame; the
/// geometry of `usray_signal::array`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Probe {
    /// Array kind: `"linear"`, `"phased"` or `"convex"` (`usray_signal::array::ArrayKind`).
    pub kind: String,
    /// Radius of curvature of a convex array, metres (required for
    /// `"convex"`, refused for the flat kinds).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_m: Option<f64>,
    /// Number of elements.
    pub n_elements: usize,
    /// Centre-to-centre spacing, metres.
    pub pitch_m: f64,
    /// Element width along `x`, metres.
    pub element_width_m: f64,
    /// Centre frequency `f_c`, hertz.
    pub center_frequency_hz: f64,
    /// Pulse length in cycles (envelope FWHM = cycles/f_c; `usray_signal::pulse`).
    pub cycles: f64,
    /// Receive directivity model ([`ReceiveDirectivity`]): without it, the
    /// paper's lobe when `main_lobe_deg` or `cutoff_deg` is given, else the
    /// element's own ([`Probe::receive_model`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub receive_directivity: Option<ReceiveDirectivity>,
    /// How the element's face meets an oblique echo ([`ReceiveBaffle`]):
    /// `"soft"` (the default) or `"rigid"`; only with the element's own
    /// directivity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub receive_baffle: Option<ReceiveBaffle>,
    /// Main lobe of the paper's receive lobe, degrees (paper eq. `cutoff`,
    /// `α_m`); 5° when the lobe is asked for without it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub main_lobe_deg: Option<f64>,
    /// Cutoff of the paper's receive lobe, degrees (paper eq. `cutoff`, `α_c`);
    /// 60° when the lobe is asked for without it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cutoff_deg: Option<f64>,
    /// Element extent along `y` (elevation), metres; default 4 mm.
    #[serde(default = "default_elevation")]
    pub elevation_m: f64,
}

/// The paper's receive lobe's main lobe when a scene asks for the lobe without
/// giving it, degrees.
const DEFAULT_MAIN_LOBE_DEG: f64 = 5.0;

/// The paper's receive lobe's cutoff when a scene asks for the lobe without
/// giving it, degrees.
const DEFAULT_CUTOFF_DEG: f64 = 60.0;

/// How an element weighs an echo by its direction of arrival
/// (`probe.receive_directivity`), on top of the obliquity `cos α` of its
/// projected width that every receiver measure carries.
///
/// The default is the element's own directivity: a uniformly sensitive strip
/// of width `w` receiving a plane wave from angle `α` averages it to
/// `sinc(π w sin α / λ)` (`sinc x = sin x / x`, `λ = c/f_c` with the medium's
/// speed and the probe's centre frequency; Szabo, *Diagnostic Ultrasound
/// Imaging*, 2nd ed., §6.3 eq. 6.16), which with the obliquity is the
/// soft-baffle element of Selfridge, Kino & Khuri-Yakub (Appl. Phys. Lett.
/// 37, 1980) that Field II and PyMUST use. The paper's trapezoid (eq.
/// `cutoff`) is far narrower than a narrow element's: at 2.5 MHz a 0.27 mm
/// element receives at 30° within 0.7 dB of its broadside response, the
/// 5°/60° lobe 5 dB below it, and the sides of a ring came out 4–7 dB darker
/// than k-Wave's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReceiveDirectivity {
    /// `sinc(π w sin α / λ)` along the element's width (the default); in 3-D
    /// `sin α` is the arriving direction's component along the width.
    #[default]
    Element,
    /// The paper's lobe (eq. `cutoff`): 1 inside `main_lobe_deg`, falling
    /// linearly to 0 at `cutoff_deg`.
    Lobe,
}

/// The baffle of an element's face in receive (`probe.receive_baffle`), with
/// the element's own directivity: whether an echo arriving at `α` to the
/// normal is received with the obliquity `cos α` of the element's projected
/// width.
///
/// A strip in a soft (pressure-release) baffle receives
/// `cos α · sinc(π w sin α / λ)`, in a rigid one `sinc(π w sin α / λ)`
/// (Selfridge, Kino & Khuri-Yakub, Appl. Phys. Lett. 37, 1980, eqs. 4–5).
/// Field II and PyMUST use the soft baffle, the default. An element that
/// averages the pressure over its face, as k-Wave's sensor elements do, has
/// no obliquity: the rigid baffle. On the k-Wave ring g1 at 0° (a grid 16
/// points per wavelength), the end elements receive the near wall's echo
/// 1.7 dB below the centre element; traced in 2-D the model gives 3.4 dB with
/// the soft baffle and 1.6 dB with the rigid one (`docs/diagnosis.md`,
/// "The element's baffle"). The rigid baffle weighs an arrival by
/// `1/cos α` against the ray density's `cos α`, so echoes near grazing carry
/// more Monte Carlo variance.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReceiveBaffle {
    /// `cos α · sinc(π w sin α / λ)` (the default).
    #[default]
    Soft,
    /// `sinc(π w sin α / λ)`: the pressure averaged over the face.
    Rigid,
}

impl Probe {
    /// The receive directivity this probe uses: `receive_directivity` when
    /// given, else the paper's lobe when either of its angles is, else the
    /// element's own.
    pub fn receive_model(&self) -> ReceiveDirectivity {
        match self.receive_directivity {
            Some(d) => d,
            None if self.main_lobe_deg.is_some() || self.cutoff_deg.is_some() => {
                ReceiveDirectivity::Lobe
            }
            None => ReceiveDirectivity::Element,
        }
    }

    /// The paper's lobe's `(main lobe, cutoff)`, degrees, with the defaults
    /// for the angles not given.
    pub fn lobe_deg(&self) -> (f64, f64) {
        (
            self.main_lobe_deg.unwrap_or(DEFAULT_MAIN_LOBE_DEG),
            self.cutoff_deg.unwrap_or(DEFAULT_CUTOFF_DEG),
        )
    }
}

fn default_elevation() -> f64 {
    4e-3
}

/// `[acquisition]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Acquisition {
    /// Plane-wave steering angles, degrees: shorthand for plane-wave
    /// transmits, fired before those of `transmits`.
    #[serde(default)]
    pub angles_deg: Vec<f64>,
    /// Transmits of any kind (`[[acquisition.transmits]]`), after the plane
    /// waves of `angles_deg`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub transmits: Vec<TransmitSpec>,
    /// Sampling frequency, hertz.
    pub sampling_frequency_hz: f64,
    /// Deepest point recorded (two-way), metres.
    pub max_depth_m: f64,
    /// Primary rays emitted per element and transmit.
    pub rays_per_element: usize,
    /// Maximum number of surface interactions per path.
    pub max_bounces: u32,
    /// Random seed (counter-based RNG key).
    pub seed: u64,
    /// Scanner time-gain, dB per cm of depth `c·t/2` (effect `depth_gain`; 0 = off).
    #[serde(default)]
    pub depth_gain_db_per_cm: f64,
    /// How primary ray directions are chosen (default `"plane_wave"`).
    #[serde(default)]
    pub emission: Emission,
    /// Whether the transmit aperture's two edges radiate their edge waves
    /// (the finite aperture's diffraction; `integrator::EdgeWaves`), with the
    /// collimated emission in 2-D, the only case that models them. Off unless
    /// asked for: their echoes lie in the image's faint regions, where at a
    /// diagnosis's ray counts their Monte Carlo noise dominates the log image.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub edge_waves: bool,
    /// Whether a thin layer (a tube's wall, a slab) lets the part of a wave
    /// beyond its critical angle tunnel through it (frustrated total
    /// reflection; `thin_layer`) instead of reflecting it totally. Off unless
    /// asked for: it brings a thin wall's lumen to a full-wave solver's level,
    /// but without the wave guided along the wall that the default bounce
    /// limit cuts off, the diagnosis names more false effects on full-wave
    /// rings with it (`docs/diagnosis.md`, Known limits).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub thin_layer_tunnelling: bool,
    /// How an element's rays draw their random numbers (default `"stratified"`).
    #[serde(default)]
    pub sampler: Sampler,
    /// Receivers each scattering event connects to (default: all `n_elements`,
    /// a deterministic sum with weight 1). `K < n_elements` draws one element per
    /// stratum of `n_elements/K` (weight `n_elements/K`); `1` is the paper's
    /// single uniformly chosen element (weight `n_elements`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub receivers_per_event: Option<usize>,
    /// Spatial dimensions of the transport: 3 (the default) or 2, for data
    /// simulated in 2-D (`dimensions = 2`; [`Dimensions`]). Unset, a command
    /// that compares with measured data follows what they declare
    /// (`usray_signal::io::declared_dimensions`), else 3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dimensions: Option<Dimensions>,
}

impl Acquisition {
    /// Traced in 2-D: `dimensions = 2` (unset is 3).
    pub fn is_planar(&self) -> bool {
        self.dimensions.is_some_and(|d| d.is_planar())
    }
}

/// One `[[acquisition.transmits]]` entry (CONTRACT §3): `kind = "plane_wave"`
/// with `angle_deg`, `"diverging"` with `virtual_source_m = [x, z]` (behind the
/// array, `z < 0`) or `"focused"` with `focus_m = [x, z]` (in front, `z > 0`),
/// metres in the probe frame; the time models of `usray_signal::transmit`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransmitSpec {
    /// `"plane_wave"`, `"diverging"` or `"focused"`.
    pub kind: String,
    /// Steering angle of a plane wave, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_deg: Option<f64>,
    /// Virtual source `[x, z]` of a diverging wave, m.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact::option"
    )]
    pub virtual_source_m: Option<[f64; 2]>,
    /// Focus `[x, z]` of a focused wave, m.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact::option"
    )]
    pub focus_m: Option<[f64; 2]>,
}

/// Emission model of the primary rays (`acquisition.emission`).
///
/// The default is the collimated plane wave: with the paper's cosine lobe the
/// echoes of off-axis emitters add as incoherent clutter that fills a plane-wave
/// image (on a 96-element scene at 20 rays, 84% of the residual lay outside the
/// object and the Monte Carlo noise loss was as large as the gaps a diagnosis
/// must tell apart), while a steered plane wave is what the transmit delays
/// form in the field.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Emission {
    /// Each element radiates a cosine lobe (paper eq. `directivity`,
    /// importance-sampled on the cosine-weighted hemisphere); the steered plane
    /// wave only exists through the transmit delays, so echoes from off-axis
    /// emitters add as incoherent Monte Carlo noise that averages out slowly.
    /// The paper's model; ask for it with `emission = "cosine"`.
    Cosine,
    /// Geometric-acoustics wave (the default): every ray leaves along the
    /// transmitted wave's ray through its emission point (a plane wave's
    /// steering direction `(sin θ, 0, cos θ)`; away from a virtual source;
    /// towards a focus) with weight `f_d = n·ω` (paper eq. `directivity` at
    /// that direction); in 2-D, with `acquisition.edge_waves = true`, the
    /// aperture's edge waves besides. Far less noise.
    #[default]
    PlaneWave,
}

/// Spatial dimensions of the transport (`acquisition.dimensions`).
///
/// `3` (the default): rays in space, rough surfaces scatter in elevation too,
/// an element receives over its face (`probe.elevation_m` high). `2`: the scene
/// is its cross-section at `y = 0`, every ray, normal and scattered direction
/// stays in the `xz` plane and densities are per radian
/// ([`crate::ggx_planar`]), as in data simulated in 2-D (k-Wave's 2-D
/// solver, PyMUST's `simus`), whose sources and scatterers are lines along
/// `y`. In 2-D, an echo spreads over `1/r` where in 3-D it spreads over `1/r²`
/// (a receiver connection's measure is the element's angle `w cos θ / r`
/// instead of its solid angle `w h cos θ / r²`), and a rough wall's echo is not
/// lost out of the plane. Objects are cut at `y = 0`; a normal there with a `y`
/// component (a tilted mesh) is projected onto the plane.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub enum Dimensions {
    /// Two: the `xz` plane.
    Two,
    /// Three (the default).
    #[default]
    Three,
}

impl Dimensions {
    /// `true` in 2-D.
    pub fn is_planar(&self) -> bool {
        *self == Self::Two
    }
}

impl TryFrom<u8> for Dimensions {
    type Error = String;

    /// `2` or `3`.
    ///
    /// ```
    /// use usray_transport::scene::Dimensions;
    /// assert_eq!(Dimensions::try_from(2), Ok(Dimensions::Two));
    /// assert!(Dimensions::try_from(1).unwrap_err().contains("2 or 3"));
    /// ```
    fn try_from(d: u8) -> Result<Self, Self::Error> {
        match d {
            2 => Ok(Self::Two),
            3 => Ok(Self::Three),
            other => Err(format!("dimensions = {other}: expected 2 or 3")),
        }
    }
}

impl From<Dimensions> for u8 {
    fn from(d: Dimensions) -> u8 {
        match d {
            Dimensions::Two => 2,
            Dimensions::Three => 3,
        }
    }
}

/// How the rays of one element and transmit draw their random numbers
/// (`acquisition.sampler`; [`crate::rng`]). Both are unbiased; they differ in
/// variance, and so in the fixed-seed loss landscapes fits descend
/// (`docs/performance.md`, "Samplers": the stratified one has 3–12× less
/// variance at equal cost, so it is the default).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Sampler {
    /// A Latin hypercube over the element's rays: for every decision of a path
    /// (emission point, microfacet normal, …) the rays fall one in each of
    /// `rays_per_element` strata of `[0, 1)`
    /// ([`crate::rng::PathSampler::stratified`]). The default.
    #[default]
    Stratified,
    /// Every ray draws independently (the paper's sampler).
    Independent,
}

impl core::str::FromStr for Sampler {
    type Err = String;

    /// The scene file's spelling: `"stratified"` or `"independent"`.
    ///
    /// ```
    /// use usray_transport::scene::Sampler;
    /// assert_eq!("stratified".parse(), Ok(Sampler::Stratified));
    /// assert!("sobol".parse::<Sampler>().unwrap_err().contains("`independent`"));
    /// ```
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "stratified" => Ok(Self::Stratified),
            "independent" => Ok(Self::Independent),
            other => Err(format!(
                "unknown sampler `{other}`, expected `stratified` or `independent`"
            )),
        }
    }
}

/// `[imaging]`: the beamformer's grid and assumptions.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Imaging {
    /// Lateral extent `[x_min, x_max]`, metres.
    #[serde(deserialize_with = "exact::array")]
    pub x_range_m: [f64; 2],
    /// Depth extent `[z_min, z_max]`, metres.
    #[serde(deserialize_with = "exact::array")]
    pub z_range_m: [f64; 2],
    /// Pixel size, metres.
    pub pixel_m: f64,
    /// Receive F-number (0 = full aperture).
    pub f_number: f64,
    /// Displayed dynamic range, dB.
    pub dynamic_range_db: f64,
    /// Speed the beamformer assumes, m/s (default: the medium's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sound_speed_m_s: Option<f64>,
    /// The envelope shown at 0 dB, in the channel data's unit (default: each
    /// image's own maximum). `fit` and `grad` (and `diagnose --levels
    /// absolute`) set it to the measured image's maximum when the data are in
    /// the renders' unit, so that model and measurement are compared at their
    /// absolute levels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_amplitude: Option<f64>,
}

impl Default for Imaging {
    /// The beamformer's defaults ([`ImagingSettings::default`]): one set of
    /// numbers for a scene without `[imaging]` and for the image formation.
    fn default() -> Self {
        let d = ImagingSettings::default();
        Self {
            x_range_m: d.x_range_m,
            z_range_m: d.z_range_m,
            pixel_m: d.pixel_m,
            f_number: d.f_number,
            dynamic_range_db: d.dynamic_range_db,
            sound_speed_m_s: d.sound_speed_m_s,
            reference_amplitude: d.reference_amplitude,
        }
    }
}

/// `[materials.NAME]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Acoustic impedance, MRayl.
    pub impedance_mrayl: f64,
    /// Sound speed, m/s.
    pub sound_speed_m_s: f64,
    /// GGX roughness `α` (paper eq. `GGX_PDF`); 0 = smooth.
    #[serde(default)]
    pub roughness: f64,
    /// Attenuation, dB/(cm·MHz); 0 = off.
    #[serde(default)]
    pub attenuation_db_cm_mhz: f64,
    /// Sub-resolution scatterers per mm³ (effect `volume_scattering`; 0 = off).
    #[serde(default)]
    pub scatterer_density_per_mm3: f64,
    /// Scatterer amplitude strength (dimensionless; 0 = off).
    #[serde(default)]
    pub scatterer_strength: f64,
}

/// The shape of an object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShapeKind {
    /// Infinite cylinder along `y` (`center_m`, `radius_m`, optional `thickness_m`).
    Cylinder,
    /// Sphere (`center_m`, `radius_m`).
    Sphere,
    /// Horizontal slab between depths `z_top_m` and `z_bottom_m`.
    Slab,
    /// Half-space: the solid is the side of the plane through `center_m` opposite
    /// to `normal` (outward normal; default `[0, 0, −1]`: everything deeper).
    Plane,
    /// Closed triangle mesh from an OBJ file (`path`, relative to the scene file),
    /// placed by `center_m` (translation), `rotation_deg` (Euler x, y, z) and `scale`.
    Mesh,
}

/// `[[objects]]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Object {
    /// Unique name (used in parameter paths).
    pub name: String,
    /// Shape kind.
    pub shape: ShapeKind,
    /// Material name (a key of `[materials]`).
    pub material: String,
    /// Centre / reference point / translation, metres.
    #[serde(default, deserialize_with = "exact::array")]
    pub center_m: [f64; 3],
    /// Radius (cylinder, sphere), metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_m: Option<f64>,
    /// Wall thickness of a hollow cylinder, metres (effect `wall_thickness`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness_m: Option<f64>,
    /// Sub-resolution scatterers per mm³ in a hollow cylinder's lumen (blood in
    /// a vessel: effect `volume_scattering`). The lumen holds the medium around
    /// the tube (its speed and attenuation); these scatterers sit in it, inside
    /// the wall's inner radius only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lumen_scatterer_density_per_mm3: Option<f64>,
    /// Amplitude strength of the lumen's scatterers (as a material's
    /// `scatterer_strength`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lumen_scatterer_strength: Option<f64>,
    /// Slab top depth, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z_top_m: Option<f64>,
    /// Slab bottom depth, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z_bottom_m: Option<f64>,
    /// Outward normal of a plane (half-space).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact::option"
    )]
    pub normal: Option<[f64; 3]>,
    /// Mesh file, relative to the scene file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<String>,
    /// Mesh rotation, Euler angles about x, y, z in degrees.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact::option"
    )]
    pub rotation_deg: Option<[f64; 3]>,
    /// Mesh uniform scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<f64>,
}

/// The lower end of a range that must be positive (the smallest positive
/// normal `f64`): `within(k, v, (POSITIVE, hi))` is `0 < v ≤ hi`.
const POSITIVE: f64 = f64::MIN_POSITIVE;

pub(super) fn validate(s: &Scene) -> Result<(), SceneError> {
    let f = s.source.as_str();
    let err = |k: &str, m: &str| Err(SceneError::new(f, k, m));
    // 1. Every continuous scalar is finite.
    for (key, v) in s.params() {
        if !v.is_finite() {
            return Err(SceneError::new(
                f,
                key.to_string(),
                format!("expected a finite number, found {v}"),
            ));
        }
    }
    let pos = |k: &str, v: f64| -> Result<(), SceneError> {
        if v > 0.0 {
            Ok(())
        } else {
            Err(SceneError::new(
                f,
                k,
                format!("expected a positive number, found {v}"),
            ))
        }
    };
    let nonneg = |k: &str, v: f64| -> Result<(), SceneError> {
        if v >= 0.0 {
            Ok(())
        } else {
            Err(SceneError::new(
                f,
                k,
                format!("expected a number ≥ 0, found {v}"),
            ))
        }
    };
    // Sound speeds and frequencies inside their physical ranges (a speed of
    // 1e-287 m/s made a record of 1e285 s, blamed on the sampling frequency).
    let within = |k: &str, v: f64, (lo, hi): (f64, f64)| -> Result<(), SceneError> {
        if v >= lo && v <= hi {
            return Ok(());
        }
        let range = if lo == POSITIVE {
            format!("a positive value up to {hi:e}")
        } else {
            format!("a value in [{lo:e}, {hi:e}]")
        };
        Err(SceneError::new(
            f,
            k,
            format!("expected {range} (usray_transport::scene::limits), found {v}"),
        ))
    };
    // 2. Medium.
    within(
        "medium.sound_speed_m_s",
        s.medium.sound_speed_m_s,
        limits::SOUND_SPEED_M_S,
    )?;
    within(
        "medium.impedance_mrayl",
        s.medium.impedance_mrayl,
        limits::IMPEDANCE_MRAYL,
    )?;
    within(
        "medium.attenuation_db_cm_mhz",
        s.medium.attenuation_db_cm_mhz,
        limits::ATTENUATION_DB_CM_MHZ,
    )?;
    // 3. Probe.
    let p = &s.probe;
    if p.n_elements == 0 {
        return err("probe.n_elements", "expected at least 1 element");
    }
    within("probe.pitch_m", p.pitch_m, (POSITIVE, limits::MAX_PITCH_M))?;
    pos("probe.element_width_m", p.element_width_m)?;
    within(
        "probe.center_frequency_hz",
        p.center_frequency_hz,
        limits::FREQUENCY_HZ,
    )?;
    within(
        "probe.cycles",
        p.cycles,
        (limits::MIN_CYCLES, limits::MAX_CYCLES),
    )?;
    pos("probe.elevation_m", p.elevation_m)?;
    match p.receive_model() {
        ReceiveDirectivity::Lobe => {
            let (main_lobe, cutoff) = p.lobe_deg();
            nonneg("probe.main_lobe_deg", main_lobe)?;
            if !(cutoff > main_lobe && cutoff <= 90.0) {
                return err(
                    "probe.cutoff_deg",
                    &format!(
                        "expected main_lobe_deg < cutoff_deg ≤ 90, found {cutoff} (main lobe {main_lobe})"
                    ),
                );
            }
        }
        ReceiveDirectivity::Element => {
            for (key, given) in [
                ("probe.main_lobe_deg", p.main_lobe_deg),
                ("probe.cutoff_deg", p.cutoff_deg),
            ] {
                if given.is_some() {
                    return err(
                        key,
                        "applies only to `receive_directivity = \"lobe\"` (the paper's lobe), \
                         not to the element's own directivity: drop it, or ask for the lobe",
                    );
                }
            }
        }
    }
    if p.receive_baffle.is_some() && p.receive_model() == ReceiveDirectivity::Lobe {
        return err(
            "probe.receive_baffle",
            "applies only to the element's own directivity, not to the paper's lobe: \
             drop it, or drop the lobe's angles",
        );
    }
    // 4. Acquisition.
    let a = &s.acquisition;
    for (i, &ang) in a.angles_deg.iter().enumerate() {
        if ang.abs() >= 90.0 {
            return err(
                &format!("acquisition.angles_deg.{i}"),
                &format!("expected |angle| < 90 degrees, found {ang}"),
            );
        }
    }
    within(
        "acquisition.sampling_frequency_hz",
        a.sampling_frequency_hz,
        limits::FREQUENCY_HZ,
    )?;
    pos("acquisition.max_depth_m", a.max_depth_m)?;
    if a.rays_per_element == 0 {
        return err("acquisition.rays_per_element", "expected at least 1 ray");
    }
    if a.edge_waves && a.emission == Emission::Cosine {
        return err(
            "acquisition.edge_waves",
            "applies only to `emission = \"plane_wave\"`: the cosine lobe has no aperture \
             (each element radiates alone)",
        );
    }
    if a.receivers_per_event == Some(0) {
        return err(
            "acquisition.receivers_per_event",
            "expected at least 1 receiver (omit the key for all elements)",
        );
    }
    // 5. Imaging.
    let im = &s.imaging;
    within(
        "imaging.pixel_m",
        im.pixel_m,
        (POSITIVE, limits::MAX_PIXEL_M),
    )?;
    within("imaging.f_number", im.f_number, limits::F_NUMBER)?;
    within(
        "imaging.dynamic_range_db",
        im.dynamic_range_db,
        limits::DYNAMIC_RANGE_DB,
    )?;
    if let Some(c) = im.sound_speed_m_s {
        within("imaging.sound_speed_m_s", c, limits::SOUND_SPEED_M_S)?;
    }
    if let Some(m) = im.reference_amplitude {
        pos("imaging.reference_amplitude", m)?;
    }
    if im.x_range_m[1] <= im.x_range_m[0] {
        return err("imaging.x_range_m", "expected [min, max] with min < max");
    }
    if im.z_range_m[1] <= im.z_range_m[0] {
        return err("imaging.z_range_m", "expected [min, max] with min < max");
    }
    // 6. Materials.
    for (name, m) in &s.materials {
        let k = |leaf: &str| format!("materials.{name}.{leaf}");
        within(
            &k("impedance_mrayl"),
            m.impedance_mrayl,
            limits::IMPEDANCE_MRAYL,
        )?;
        within(
            &k("sound_speed_m_s"),
            m.sound_speed_m_s,
            limits::SOUND_SPEED_M_S,
        )?;
        within(&k("roughness"), m.roughness, limits::ROUGHNESS)?;
        within(
            &k("attenuation_db_cm_mhz"),
            m.attenuation_db_cm_mhz,
            limits::ATTENUATION_DB_CM_MHZ,
        )?;
        nonneg(&k("scatterer_density_per_mm3"), m.scatterer_density_per_mm3)?;
        nonneg(&k("scatterer_strength"), m.scatterer_strength)?;
    }
    // 7. Objects.
    let mut names = std::collections::BTreeSet::new();
    for (i, o) in s.objects.iter().enumerate() {
        if o.name.is_empty() || o.name.contains('.') {
            return err(
                &format!("objects.{i}.name"),
                "expected a non-empty name without '.'",
            );
        }
        if !names.insert(o.name.as_str()) {
            return err(
                &format!("objects.{}.name", o.name),
                "expected a unique object name (duplicate)",
            );
        }
        let k = |leaf: &str| format!("objects.{}.{leaf}", o.name);
        if !s.materials.contains_key(&o.material) {
            return err(
                &k("material"),
                &format!(
                    "unknown material {:?}; expected one of {:?}",
                    o.material,
                    s.materials.keys().collect::<Vec<_>>()
                ),
            );
        }
        let need = |leaf: &str, v: Option<f64>| -> Result<f64, SceneError> {
            v.ok_or_else(|| {
                SceneError::new(f, k(leaf), format!("required for shape {:?}", o.shape))
            })
        };
        let forbid = |leaf: &str, present: bool| -> Result<(), SceneError> {
            if present {
                Err(SceneError::new(
                    f,
                    k(leaf),
                    format!("not used by shape {:?}; remove it", o.shape),
                ))
            } else {
                Ok(())
            }
        };
        let forbid_lumen = || {
            forbid(
                "lumen_scatterer_density_per_mm3",
                o.lumen_scatterer_density_per_mm3.is_some(),
            )?;
            forbid(
                "lumen_scatterer_strength",
                o.lumen_scatterer_strength.is_some(),
            )
        };
        match o.shape {
            ShapeKind::Cylinder | ShapeKind::Sphere => {
                let r = need("radius_m", o.radius_m)?;
                within(&k("radius_m"), r, (POSITIVE, limits::MAX_LENGTH_M))?;
                if let Some(t) = o.thickness_m {
                    if o.shape == ShapeKind::Sphere {
                        return err(
                            &k("thickness_m"),
                            "hollow spheres are not supported; thickness_m is for cylinders",
                        );
                    }
                    if !(t > 0.0 && t < r) {
                        return err(
                            &k("thickness_m"),
                            &format!("expected 0 < thickness_m < radius_m = {r}, found {t}"),
                        );
                    }
                }
                let lumen = [
                    (
                        "lumen_scatterer_density_per_mm3",
                        o.lumen_scatterer_density_per_mm3,
                    ),
                    ("lumen_scatterer_strength", o.lumen_scatterer_strength),
                ];
                for (leaf, v) in lumen {
                    if let Some(v) = v {
                        if o.thickness_m.is_none() {
                            return err(
                                &k(leaf),
                                "a lumen needs a hollow cylinder (shape cylinder with thickness_m); remove it",
                            );
                        }
                        nonneg(&k(leaf), v)?;
                    }
                }
                forbid("z_top_m", o.z_top_m.is_some())?;
                forbid("z_bottom_m", o.z_bottom_m.is_some())?;
                forbid("path", o.path.is_some())?;
                forbid("normal", o.normal.is_some())?;
                forbid("rotation_deg", o.rotation_deg.is_some())?;
                forbid("scale", o.scale.is_some())?;
            }
            ShapeKind::Slab => {
                let top = need("z_top_m", o.z_top_m)?;
                let bot = need("z_bottom_m", o.z_bottom_m)?;
                if bot <= top {
                    return err(
                        &k("z_bottom_m"),
                        &format!("expected z_bottom_m > z_top_m = {top}, found {bot}"),
                    );
                }
                forbid("radius_m", o.radius_m.is_some())?;
                forbid("thickness_m", o.thickness_m.is_some())?;
                forbid_lumen()?;
                forbid("path", o.path.is_some())?;
                forbid("normal", o.normal.is_some())?;
                forbid("rotation_deg", o.rotation_deg.is_some())?;
                forbid("scale", o.scale.is_some())?;
            }
            ShapeKind::Plane => {
                if let Some(n) = o.normal {
                    if n.iter().map(|x| x * x).sum::<f64>() <= 0.0 {
                        return err(&k("normal"), "expected a non-zero vector");
                    }
                }
                forbid("radius_m", o.radius_m.is_some())?;
                forbid("thickness_m", o.thickness_m.is_some())?;
                forbid_lumen()?;
                forbid("z_top_m", o.z_top_m.is_some())?;
                forbid("z_bottom_m", o.z_bottom_m.is_some())?;
                forbid("path", o.path.is_some())?;
                forbid("rotation_deg", o.rotation_deg.is_some())?;
                forbid("scale", o.scale.is_some())?;
            }
            ShapeKind::Mesh => {
                let Some(path) = &o.path else {
                    return err(&k("path"), "required for shape mesh (an OBJ file)");
                };
                let full = s.base_dir.join(path);
                if !full.is_file() {
                    return err(
                        &k("path"),
                        &format!("mesh file {} not found", full.display()),
                    );
                }
                if let Some(sc) = o.scale {
                    pos(&k("scale"), sc)?;
                }
                forbid("radius_m", o.radius_m.is_some())?;
                forbid("thickness_m", o.thickness_m.is_some())?;
                forbid_lumen()?;
                forbid("z_top_m", o.z_top_m.is_some())?;
                forbid("z_bottom_m", o.z_bottom_m.is_some())?;
                forbid("normal", o.normal.is_some())?;
            }
        }
    }
    // 8. Consistency and sizes, checked before anything is allocated or traced.
    if p.element_width_m > p.pitch_m {
        return err(
            "probe.element_width_m",
            &format!(
                "expected element_width_m ≤ pitch_m = {}, found {}",
                p.pitch_m, p.element_width_m
            ),
        );
    }
    s.check_acquisition()?;
    if im.z_range_m[1] <= 0.0 {
        return err(
            "imaging.z_range_m",
            &format!(
                "the window [{}, {}] m lies above the probe (z ≤ 0): expected depths below it",
                im.z_range_m[0], im.z_range_m[1]
            ),
        );
    }
    limits::check(s)
}

/// Limits on the sizes a scene implies, so that a typo (`n_elements =
/// 1000000000`, `sampling_frequency_hz = 1.0e15`) is an error naming the key
/// and the limit, not an allocation failure or a run that never ends.
pub mod limits {
    use super::{Scene, SceneError};

    // The ranges a scene shares with channel data are defined once, there.
    pub use usray_signal::channels::limits::{FREQUENCY_HZ, MAX_ELEMENTS, SOUND_SPEED_M_S};
    /// Range of every impedance, MRayl (air's 4·10⁻⁴ to a rigid mirror's 10⁴ and
    /// beyond).
    pub const IMPEDANCE_MRAYL: (f64, f64) = (1e-5, 1e6);
    /// Range of every attenuation, dB/(cm·MHz) (tissue 0.5, bone 20).
    pub const ATTENUATION_DB_CM_MHZ: (f64, f64) = (0.0, 1e3);
    /// Range of a material's `roughness` (GGX α; 1 is already very rough).
    pub const ROUGHNESS: (f64, f64) = (0.0, 10.0);
    /// Fewest `probe.cycles` of the pulse.
    pub const MIN_CYCLES: f64 = 0.1;
    /// Range of `imaging.f_number`.
    pub const F_NUMBER: (f64, f64) = (0.0, 100.0);
    /// Range of `imaging.dynamic_range_db`.
    pub const DYNAMIC_RANGE_DB: (f64, f64) = (super::POSITIVE, 300.0);
    /// Largest `imaging.pixel_m`, m.
    pub const MAX_PIXEL_M: f64 = 0.01;
    /// Largest `probe.pitch_m`, m (as channel data's).
    pub const MAX_PITCH_M: f64 = usray_signal::channels::limits::PITCH_M.1;
    /// Largest number of transmits (`acquisition.angles_deg` and `transmits`).
    pub const MAX_TRANSMITS: usize = 1024;
    /// Largest `acquisition.max_bounces`.
    pub const MAX_BOUNCES: u32 = 64;
    /// Largest `acquisition.rays_per_element`.
    pub const MAX_RAYS_PER_ELEMENT: usize = 1_000_000;
    /// Largest `probe.cycles` of the pulse.
    pub const MAX_CYCLES: f64 = 1000.0;
    /// Largest `probe.elevation_m` and `acquisition.max_depth_m`, m.
    pub const MAX_LENGTH_M: f64 = 1.0;
    /// Largest number of samples of all channel records together
    /// (transmits × elements × samples per record): a render peaks near 60
    /// bytes per channel sample (760 MB at 1.28·10⁷ on one thread), so this
    /// keeps it near 600 MB; the shipped scenes have about 10⁶.
    pub const MAX_CHANNEL_SAMPLES: f64 = 1.0e7;
    /// Largest number of image pixels (e.g. 4000 × 4000).
    pub const MAX_PIXELS: f64 = 1.6e7;

    /// Checks `s` against the limits above (after the per-key checks).
    pub(super) fn check(s: &Scene) -> Result<(), SceneError> {
        let f = s.source.as_str();
        let over = |key: &str, found: String, limit: String| {
            Err(SceneError::new(
                f,
                key,
                format!("{found} is past the limit of {limit} (usray_transport::scene::limits)"),
            ))
        };
        let (p, a, im) = (&s.probe, &s.acquisition, &s.imaging);
        if p.n_elements > MAX_ELEMENTS {
            return over(
                "probe.n_elements",
                p.n_elements.to_string(),
                MAX_ELEMENTS.to_string(),
            );
        }
        if s.n_transmits() > MAX_TRANSMITS {
            return over(
                "acquisition.angles_deg",
                format!("{} transmits", s.n_transmits()),
                MAX_TRANSMITS.to_string(),
            );
        }
        if a.max_bounces > MAX_BOUNCES {
            return over(
                "acquisition.max_bounces",
                a.max_bounces.to_string(),
                MAX_BOUNCES.to_string(),
            );
        }
        if a.rays_per_element > MAX_RAYS_PER_ELEMENT {
            return over(
                "acquisition.rays_per_element",
                a.rays_per_element.to_string(),
                MAX_RAYS_PER_ELEMENT.to_string(),
            );
        }
        if p.cycles > MAX_CYCLES {
            return over("probe.cycles", p.cycles.to_string(), MAX_CYCLES.to_string());
        }
        for (key, v) in [
            ("probe.elevation_m", p.elevation_m),
            ("acquisition.max_depth_m", a.max_depth_m),
        ] {
            if v > MAX_LENGTH_M {
                return over(key, format!("{v} m"), format!("{MAX_LENGTH_M} m"));
            }
        }
        // Samples per record from the record's duration (the acquisition
        // plan's), in floating point: a huge product must not wrap.
        let duration_s = crate::plan::record_duration_s(s);
        let per_record = duration_s * a.sampling_frequency_hz;
        let total = per_record * p.n_elements as f64 * s.n_transmits() as f64;
        if total.is_nan() || total > MAX_CHANNEL_SAMPLES {
            return over(
                "acquisition.sampling_frequency_hz",
                format!(
                    "{total:.3e} channel samples ({} transmits × {} elements × {per_record:.3e} samples per record of {:.3e} s at {} Hz, from max_depth_m, the sound_speed_m_s of the medium and the beamformer, the aperture (probe.n_elements × pitch_m, for the steered transmits' delays), probe.cycles and probe.center_frequency_hz)",
                    s.n_transmits(),
                    p.n_elements,
                    duration_s,
                    a.sampling_frequency_hz
                ),
                format!("{MAX_CHANNEL_SAMPLES:.1e}"),
            );
        }
        let pixels = ((im.x_range_m[1] - im.x_range_m[0]) / im.pixel_m + 1.0)
            * ((im.z_range_m[1] - im.z_range_m[0]) / im.pixel_m + 1.0);
        if pixels.is_nan() || pixels > MAX_PIXELS {
            return over(
                "imaging.pixel_m",
                format!("{pixels:.3e} pixels"),
                format!("{MAX_PIXELS:.1e}"),
            );
        }
        Ok(())
    }
}

/// Fixed-length number lists of a scene file (`x_range_m`, `center_m`, …): exactly
/// `N` numbers. serde's arrays read the first `N` of a longer list and drop the
/// rest silently (`x_range_m = [-0.01, 0.0, 0.01]` became `[-0.01, 0.0]`).
mod exact {
    use serde::de::{Deserialize, Deserializer, Error};

    fn convert<E: Error, const N: usize>(v: Vec<f64>) -> Result<[f64; N], E> {
        <[f64; N]>::try_from(v.as_slice()).map_err(|_| {
            E::invalid_length(v.len(), &format!("a list of exactly {N} numbers").as_str())
        })
    }

    /// `[f64; N]` from a list of exactly `N` numbers.
    pub fn array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
        convert(Vec::<f64>::deserialize(d)?)
    }

    /// `Option<[f64; N]>` from a list of exactly `N` numbers.
    pub fn option<'de, D: Deserializer<'de>, const N: usize>(
        d: D,
    ) -> Result<Option<[f64; N]>, D::Error> {
        Option::<Vec<f64>>::deserialize(d)?.map(convert).transpose()
    }
}
