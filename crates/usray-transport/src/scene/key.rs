//! Parameter keys: the identity of every continuous scalar of a scene.
//!
//! A [`ParamKey`] names one parameter structurally: the table that owns it
//! ([`Owner`]: the medium, the probe, a transmit, a material or an object by
//! name, …), the quantity ([`Field`]) and, for an array, the component. It is
//! printed as, and parsed from, the dotted path of the scene file
//! (`objects.cylinder.center_m.2`; see [`super::params`]) — the only place that
//! spelling exists.
//!
//! [`PARAMETERS`] declares every parameter once, in the order `usray params`
//! lists them: its spelling, whether it is an array, its learning-rate group
//! ([`ParamGroup`]), its default range ([`RangeRule`]) and the part of the
//! image formation that also reads it ([`ImagingRole`]). Adding a parameter is
//! a row there and an arm of `slot!` in `scene/slots.rs` (where its value
//! lives in [`Scene`]), plus the physics that reads it ([`Scene::lift`]).

use super::Scene;
use std::fmt;
use std::str::FromStr;
use usray_signal::array::RADIUS_KEY;
use usray_signal::transmit::{FOCUS_KEY, VIRTUAL_SOURCE_KEY};

/// The table of the scene file a parameter belongs to.
#[derive(Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Debug)]
pub enum Owner {
    /// `[medium]`.
    Medium,
    /// `[probe]`.
    Probe,
    /// `[acquisition]`.
    Acquisition,
    /// The `I`-th `[[acquisition.transmits]]` (from 0).
    Transmit(usize),
    /// `[imaging]`.
    Imaging,
    /// `[materials.NAME]`.
    Material(String),
    /// The `[[objects]]` entry with this `name`.
    Object(String),
}

/// [`Owner`] without its name or index: which rows of [`PARAMETERS`] apply.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Section {
    /// `[medium]`.
    Medium,
    /// `[probe]`.
    Probe,
    /// `[acquisition]`.
    Acquisition,
    /// `[[acquisition.transmits]]`.
    Transmit,
    /// `[imaging]`.
    Imaging,
    /// `[materials.NAME]`.
    Material,
    /// `[[objects]]`.
    Object,
}

impl Owner {
    /// The section of this owner.
    pub fn section(&self) -> Section {
        match self {
            Owner::Medium => Section::Medium,
            Owner::Probe => Section::Probe,
            Owner::Acquisition => Section::Acquisition,
            Owner::Transmit(_) => Section::Transmit,
            Owner::Imaging => Section::Imaging,
            Owner::Material(_) => Section::Material,
            Owner::Object(_) => Section::Object,
        }
    }
}

/// The quantity a parameter is; which owners have it is [`PARAMETERS`]' business.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Debug)]
pub enum Field {
    /// Sound speed, m/s.
    SoundSpeed,
    /// Acoustic impedance, MRayl.
    Impedance,
    /// Attenuation, dB/(cm·MHz).
    Attenuation,
    /// Element pitch, m.
    Pitch,
    /// Element width, m.
    ElementWidth,
    /// Centre frequency, Hz.
    CenterFrequency,
    /// Pulse cycles.
    Cycles,
    /// Receive main lobe, degrees.
    MainLobe,
    /// Receive cutoff, degrees.
    Cutoff,
    /// Element elevation extent, m.
    Elevation,
    /// Radius (convex array, cylinder, sphere), m.
    Radius,
    /// Plane-wave steering angles, degrees (an array).
    Angles,
    /// A listed plane wave's steering angle, degrees.
    Angle,
    /// A diverging wave's virtual source `[x, z]`, m.
    VirtualSource,
    /// A focused wave's focus `[x, z]`, m.
    Focus,
    /// Sampling frequency, Hz.
    SamplingFrequency,
    /// Deepest echo recorded, m.
    MaxDepth,
    /// Depth gain, dB/cm.
    DepthGain,
    /// Lateral image extent `[min, max]`, m.
    XRange,
    /// Axial image extent `[min, max]`, m.
    ZRange,
    /// Image pixel size, m.
    Pixel,
    /// Receive f-number.
    FNumber,
    /// Display dynamic range, dB.
    DynamicRange,
    /// GGX roughness α.
    Roughness,
    /// Scatterers per mm³.
    ScattererDensity,
    /// Scatterer amplitude strength.
    ScattererStrength,
    /// Centre `[x, y, z]`, m.
    Center,
    /// Wall thickness of a hollow cylinder, m.
    Thickness,
    /// A slab's top face depth, m.
    ZTop,
    /// A slab's bottom face depth, m.
    ZBottom,
    /// A plane's normal (an array).
    Normal,
    /// A mesh's Euler rotation, degrees (an array).
    Rotation,
    /// A mesh's uniform scale.
    Scale,
}

/// The learning-rate group of a parameter in a fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamGroup {
    /// Material and effect strengths: impedance, roughness, wall thickness,
    /// scatterer density/strength, attenuation.
    Material,
    /// Object geometry: radius, centre, mesh transform (rotation, scale), plane normal,
    /// slab faces.
    Geometry,
    /// Acquisition and imaging: pitch, element width, frequency, cycles, sound
    /// speeds (medium, material, beamformer), depth gain, angles, everything else.
    Acquisition,
}

/// The default admissible range of a parameter named without one, around its
/// current value `v` ([`ParamKey::default_range`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RangeRule {
    /// `[0.01, 1]` (GGX α).
    Roughness,
    /// `[0.5·v, 2·v]`.
    HalfToDouble,
    /// `[0.9·v, 1.1·v]`.
    TenPercent,
    /// `[0.8·v, 1.2·v]`.
    TwentyPercent,
    /// `[0, max(2, 2·v)]` (attenuation, dB/(cm·MHz)).
    Attenuation,
    /// `[0, max(20, 2·v)]` (scatterers per mm³).
    ScattererDensity,
    /// `[0, max(1, 2·v)]`.
    ScattererStrength,
    /// `[v − 3, v + 3]` (dB/cm).
    DepthGain,
    /// `[0, max(5 mm, 2·v)]` (a hollow cylinder's wall).
    Wall,
    /// `[v − h, v + h]`, `h = max(0.3·|v|, 2 mm)` (lengths).
    Length,
    /// `[v − h, v + h]`, `h = max(0.5·|v|, 1)` (anything else).
    Other,
}

impl RangeRule {
    /// The range around `v`.
    pub fn around(self, v: f64) -> (f64, f64) {
        match self {
            RangeRule::Roughness => (0.01, 1.0),
            RangeRule::HalfToDouble => (0.5 * v, 2.0 * v),
            RangeRule::TenPercent => (0.9 * v, 1.1 * v),
            RangeRule::TwentyPercent => (0.8 * v, 1.2 * v),
            RangeRule::Attenuation => (0.0, f64::max(2.0, 2.0 * v)),
            RangeRule::ScattererDensity => (0.0, f64::max(20.0, 2.0 * v)),
            RangeRule::ScattererStrength => (0.0, f64::max(1.0, 2.0 * v)),
            RangeRule::DepthGain => (v - 3.0, v + 3.0),
            RangeRule::Wall => (0.0, f64::max(5e-3, 2.0 * v)),
            RangeRule::Length => {
                let h = f64::max(0.3 * v.abs(), 2e-3);
                (v - h, v + h)
            }
            RangeRule::Other => {
                let h = f64::max(0.5 * v.abs(), 1.0);
                (v - h, v + h)
            }
        }
    }
}

/// The part of the image formation (delay-and-sum, demodulation) that reads a
/// parameter besides the transport.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImagingRole {
    /// The sound speed the beamformer assumes.
    SoundSpeed,
    /// The element pitch (element positions of delay-and-sum).
    Pitch,
    /// The centre frequency (IQ mixing, low-pass, phase rotation).
    CenterFrequency,
}

/// How a row's parameter reaches the image formation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImagingUse {
    /// Not at all.
    No,
    /// Always, in this role.
    Always(ImagingRole),
    /// As the beamformer's sound speed when `imaging.sound_speed_m_s` is absent
    /// (the beamformer then assumes the medium's).
    UnlessImagingSoundSpeed,
}

/// One declared parameter (a row of [`PARAMETERS`]).
#[derive(Clone, Copy, Debug)]
pub struct Declaration {
    /// The table it lives in.
    pub section: Section,
    /// The quantity.
    pub field: Field,
    /// Its key in the scene file (the last path part before a component).
    pub spelling: &'static str,
    /// An array: the key takes a component index (`center_m.2`).
    pub array: bool,
    /// Learning-rate group.
    pub group: ParamGroup,
    /// Default range.
    pub range: RangeRule,
    /// Role in the image formation.
    pub imaging: ImagingUse,
}

const fn row(
    section: Section,
    field: Field,
    spelling: &'static str,
    array: bool,
    group: ParamGroup,
    range: RangeRule,
    imaging: ImagingUse,
) -> Declaration {
    Declaration {
        section,
        field,
        spelling,
        array,
        group,
        range,
        imaging,
    }
}

use Field as F;
use ImagingUse::{Always, No, UnlessImagingSoundSpeed};
use ParamGroup::{Acquisition as Acq, Geometry as Geo, Material as Mat};
use RangeRule as R;
use Section as S;

#[rustfmt::skip]
/// Every parameter, once, in the order [`Scene::params`] lists them (the rows
/// of one section run in order within each owner of that section).
pub const PARAMETERS: &[Declaration] = &[
    row(S::Medium, F::SoundSpeed, "sound_speed_m_s", false, Acq, R::TenPercent, UnlessImagingSoundSpeed),
    row(S::Medium, F::Impedance, "impedance_mrayl", false, Mat, R::HalfToDouble, No),
    row(S::Medium, F::Attenuation, "attenuation_db_cm_mhz", false, Mat, R::Attenuation, No),
    row(S::Probe, F::Pitch, "pitch_m", false, Acq, R::TwentyPercent, Always(ImagingRole::Pitch)),
    row(S::Probe, F::ElementWidth, "element_width_m", false, Acq, R::TwentyPercent, No),
    row(S::Probe, F::CenterFrequency, "center_frequency_hz", false, Acq, R::TwentyPercent, Always(ImagingRole::CenterFrequency)),
    row(S::Probe, F::Cycles, "cycles", false, Acq, R::HalfToDouble, No),
    row(S::Probe, F::MainLobe, "main_lobe_deg", false, Acq, R::Other, No),
    row(S::Probe, F::Cutoff, "cutoff_deg", false, Acq, R::Other, No),
    row(S::Probe, F::Elevation, "elevation_m", false, Acq, R::Length, No),
    row(S::Probe, F::Radius, RADIUS_KEY, false, Acq, R::Length, No),
    row(S::Acquisition, F::Angles, "angles_deg", true, Acq, R::Other, No),
    row(S::Transmit, F::Angle, "angle_deg", false, Acq, R::Other, No),
    row(S::Transmit, F::VirtualSource, VIRTUAL_SOURCE_KEY, true, Acq, R::Length, No),
    row(S::Transmit, F::Focus, FOCUS_KEY, true, Acq, R::Length, No),
    row(S::Acquisition, F::SamplingFrequency, "sampling_frequency_hz", false, Acq, R::Other, No),
    row(S::Acquisition, F::MaxDepth, "max_depth_m", false, Acq, R::Length, No),
    row(S::Acquisition, F::DepthGain, "depth_gain_db_per_cm", false, Acq, R::DepthGain, No),
    row(S::Imaging, F::XRange, "x_range_m", true, Acq, R::Length, No),
    row(S::Imaging, F::ZRange, "z_range_m", true, Acq, R::Length, No),
    row(S::Imaging, F::Pixel, "pixel_m", false, Acq, R::Length, No),
    row(S::Imaging, F::FNumber, "f_number", false, Acq, R::Other, No),
    row(S::Imaging, F::DynamicRange, "dynamic_range_db", false, Acq, R::Other, No),
    row(S::Imaging, F::SoundSpeed, "sound_speed_m_s", false, Acq, R::TenPercent, Always(ImagingRole::SoundSpeed)),
    row(S::Material, F::Impedance, "impedance_mrayl", false, Mat, R::HalfToDouble, No),
    row(S::Material, F::SoundSpeed, "sound_speed_m_s", false, Acq, R::TenPercent, No),
    row(S::Material, F::Roughness, "roughness", false, Mat, R::Roughness, No),
    row(S::Material, F::Attenuation, "attenuation_db_cm_mhz", false, Mat, R::Attenuation, No),
    row(S::Material, F::ScattererDensity, "scatterer_density_per_mm3", false, Mat, R::ScattererDensity, No),
    row(S::Material, F::ScattererStrength, "scatterer_strength", false, Mat, R::ScattererStrength, No),
    row(S::Object, F::Center, "center_m", true, Geo, R::Length, No),
    row(S::Object, F::Radius, "radius_m", false, Geo, R::Length, No),
    row(S::Object, F::Thickness, "thickness_m", false, Mat, R::Wall, No),
    row(S::Object, F::ScattererDensity, "lumen_scatterer_density_per_mm3", false, Mat, R::ScattererDensity, No),
    row(S::Object, F::ScattererStrength, "lumen_scatterer_strength", false, Mat, R::ScattererStrength, No),
    row(S::Object, F::ZTop, "z_top_m", false, Geo, R::Length, No),
    row(S::Object, F::ZBottom, "z_bottom_m", false, Geo, R::Length, No),
    row(S::Object, F::Normal, "normal", true, Geo, R::Other, No),
    row(S::Object, F::Rotation, "rotation_deg", true, Geo, R::Other, No),
    row(S::Object, F::Scale, "scale", false, Geo, R::Other, No),
];

/// The declaration of `field` in `section`, if that table has it.
fn declaration(section: Section, field: Field) -> Option<&'static Declaration> {
    PARAMETERS
        .iter()
        .find(|d| d.section == section && d.field == field)
}

/// One parameter of a scene: owner, quantity and, for an array, the component.
/// `Display` and `FromStr` are the dotted path of the scene file; `Debug` is
/// the path quoted, as the string it stands for.
///
/// ```
/// use usray_transport::scene::key::{Field, ParamKey, ParamGroup};
/// let k: ParamKey = "objects.cylinder.center_m.2".parse().unwrap();
/// assert_eq!(k, ParamKey::object("cylinder", Field::Center).at(2));
/// assert_eq!(k.to_string(), "objects.cylinder.center_m.2");
/// assert_eq!(k.group(), ParamGroup::Geometry);
/// assert!("objects.cylinder.center_m".parse::<ParamKey>().is_err()); // no component
/// assert!("probe.roughness".parse::<ParamKey>().is_err()); // not a key of [probe]
/// ```
#[derive(Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ParamKey {
    /// The table it lives in.
    pub owner: Owner,
    /// The quantity.
    pub field: Field,
    /// The component of an array quantity (`None` for a scalar).
    pub component: Option<usize>,
}

impl ParamKey {
    /// The scalar `field` of `owner` (add a component with [`ParamKey::at`]).
    pub fn new(owner: Owner, field: Field) -> Self {
        Self {
            owner,
            field,
            component: None,
        }
    }

    /// A key of `[medium]`.
    pub fn medium(field: Field) -> Self {
        Self::new(Owner::Medium, field)
    }

    /// A key of `[probe]`.
    pub fn probe(field: Field) -> Self {
        Self::new(Owner::Probe, field)
    }

    /// A key of `[acquisition]`.
    pub fn acquisition(field: Field) -> Self {
        Self::new(Owner::Acquisition, field)
    }

    /// A key of the `index`-th `[[acquisition.transmits]]`.
    pub fn transmit(index: usize, field: Field) -> Self {
        Self::new(Owner::Transmit(index), field)
    }

    /// A key of `[imaging]`.
    pub fn imaging(field: Field) -> Self {
        Self::new(Owner::Imaging, field)
    }

    /// A key of material `name`.
    pub fn material(name: &str, field: Field) -> Self {
        Self::new(Owner::Material(name.to_string()), field)
    }

    /// A key of the object called `name`.
    pub fn object(name: &str, field: Field) -> Self {
        Self::new(Owner::Object(name.to_string()), field)
    }

    /// This key's component `i` of an array quantity.
    #[must_use]
    pub fn at(mut self, i: usize) -> Self {
        self.component = Some(i);
        self
    }

    /// The declaration of this key (`None` for a combination no table has,
    /// which only a hand-built key can be).
    pub fn declaration(&self) -> Option<&'static Declaration> {
        declaration(self.owner.section(), self.field)
    }

    /// The learning-rate group ([`ParamGroup::Acquisition`] for an undeclared key).
    pub fn group(&self) -> ParamGroup {
        self.declaration()
            .map_or(ParamGroup::Acquisition, |d| d.group)
    }

    /// The default admissible range around the current value `value`
    /// ([`RangeRule`]; [`RangeRule::Other`] for an undeclared key).
    pub fn default_range(&self, value: f64) -> (f64, f64) {
        self.declaration()
            .map_or(RangeRule::Other, |d| d.range)
            .around(value)
    }

    /// The part of `scene`'s image formation that also reads this parameter.
    pub fn imaging_role(&self, scene: &Scene) -> Option<ImagingRole> {
        match self.declaration()?.imaging {
            No => None,
            Always(role) => Some(role),
            UnlessImagingSoundSpeed => scene
                .imaging
                .sound_speed_m_s
                .is_none()
                .then_some(ImagingRole::SoundSpeed),
        }
    }

    /// An attenuation (of the medium or of a material): the tracer's
    /// frequency down-shift depends on it.
    pub fn is_attenuation(&self) -> bool {
        self.field == Field::Attenuation
    }
}

/// How each section's paths begin (the longer prefix first: a transmit's
/// paths also begin with `acquisition.`).
const SECTION_PREFIXES: [(&str, Section); 7] = [
    ("medium.", S::Medium),
    ("probe.", S::Probe),
    ("acquisition.transmits.", S::Transmit),
    ("acquisition.", S::Acquisition),
    ("imaging.", S::Imaging),
    ("materials.", S::Material),
    ("objects.", S::Object),
];

impl fmt::Display for ParamKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let section = self.owner.section();
        let prefix = SECTION_PREFIXES
            .iter()
            .find(|(_, s)| *s == section)
            .map_or("", |(p, _)| p);
        write!(f, "{prefix}")?;
        match &self.owner {
            Owner::Transmit(i) => write!(f, "{i}.")?,
            Owner::Material(name) | Owner::Object(name) => write!(f, "{name}.")?,
            _ => {}
        }
        match self.declaration() {
            Some(d) => write!(f, "{}", d.spelling)?,
            None => write!(f, "{:?}", self.field)?,
        }
        match self.component {
            Some(i) => write!(f, ".{i}"),
            None => Ok(()),
        }
    }
}

impl fmt::Debug for ParamKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?}", self.to_string())
    }
}

/// A text that is not the dotted path of any parameter.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownKey(pub String);

impl fmt::Display for UnknownKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}` is not a parameter path", self.0)
    }
}

impl std::error::Error for UnknownKey {}

impl FromStr for ParamKey {
    type Err = UnknownKey;

    /// Parses a dotted path. Names may hold dots (the quantity and component
    /// are read from the end); the text must be the key's exact spelling
    /// (`center_m.02` is not `center_m.2`). Whether the scene has the key is
    /// [`Scene::key`]'s check.
    fn from_str(text: &str) -> Result<Self, UnknownKey> {
        let unknown = || UnknownKey(text.to_string());
        let (section, rest) = SECTION_PREFIXES
            .iter()
            .find_map(|&(prefix, s)| text.strip_prefix(prefix).map(|rest| (s, rest)))
            .ok_or_else(unknown)?;
        // `rest` is `[OWNER.]SPELLING[.COMPONENT]`.
        let (head, last) = rest.rsplit_once('.').unwrap_or(("", rest));
        let (body, component) = match last.parse::<usize>() {
            Ok(i) if !head.is_empty() => (head, Some(i)),
            _ => (rest, None),
        };
        let named = matches!(section, S::Transmit | S::Material | S::Object);
        let (owner_text, spelling) = match body.rsplit_once('.') {
            Some((o, s)) if named => (o, s),
            None if !named => ("", body),
            _ => return Err(unknown()),
        };
        let d = PARAMETERS
            .iter()
            .find(|d| d.section == section && d.spelling == spelling)
            .ok_or_else(unknown)?;
        if d.array != component.is_some() || (named && owner_text.is_empty()) {
            return Err(unknown());
        }
        let owner = match section {
            S::Medium => Owner::Medium,
            S::Probe => Owner::Probe,
            S::Acquisition => Owner::Acquisition,
            S::Imaging => Owner::Imaging,
            S::Transmit => Owner::Transmit(owner_text.parse().map_err(|_| unknown())?),
            S::Material => Owner::Material(owner_text.to_string()),
            S::Object => Owner::Object(owner_text.to_string()),
        };
        let key = ParamKey {
            owner,
            field: d.field,
            component,
        };
        // Numbers must be spelled as printed (no `+1`, no leading zeros).
        if key.to_string() != text {
            return Err(unknown());
        }
        Ok(key)
    }
}
