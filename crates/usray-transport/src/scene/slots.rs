//! Where each parameter's value lives in a [`Scene`]: the map from a
//! [`ParamKey`] to its `f64` (for reading and for writing), and the list of
//! the keys a scene has, in the order of [`PARAMETERS`].

use super::key::{Field as F, Owner, ParamKey, Section as S, PARAMETERS};
use super::Scene;

/// Where a key's value lives in a scene: `Some(place)` when the scene has the
/// parameter. Expanded once for `&` and once for `&mut` (`Scene::slot`,
/// `Scene::slot_mut`), so reading and writing share one map.
macro_rules! slot {
    ($s:expr, $key:expr, $as_:ident, $get:ident, $iter:ident $(, $m:ident)?) => {{
        let key = $key;
        let c = key.component;
        // Component `c` of an array (`None` when out of range).
        macro_rules! at {
            ($xs:expr) => {
                match c {
                    Some(i) => $xs.$get(i),
                    None => None,
                }
            };
        }
        match (&key.owner, key.field) {
            (Owner::Medium, F::SoundSpeed) => Some(&$($m)? $s.medium.sound_speed_m_s),
            (Owner::Medium, F::Impedance) => Some(&$($m)? $s.medium.impedance_mrayl),
            (Owner::Medium, F::Attenuation) => Some(&$($m)? $s.medium.attenuation_db_cm_mhz),
            (Owner::Probe, F::Pitch) => Some(&$($m)? $s.probe.pitch_m),
            (Owner::Probe, F::ElementWidth) => Some(&$($m)? $s.probe.element_width_m),
            (Owner::Probe, F::CenterFrequency) => Some(&$($m)? $s.probe.center_frequency_hz),
            (Owner::Probe, F::Cycles) => Some(&$($m)? $s.probe.cycles),
            (Owner::Probe, F::MainLobe) => $s.probe.main_lobe_deg.$as_(),
            (Owner::Probe, F::Cutoff) => $s.probe.cutoff_deg.$as_(),
            (Owner::Probe, F::Elevation) => Some(&$($m)? $s.probe.elevation_m),
            (Owner::Probe, F::Radius) => $s.probe.radius_m.$as_(),
            (Owner::Acquisition, F::Angles) => at!($s.acquisition.angles_deg),
            (Owner::Acquisition, F::SamplingFrequency) => {
                Some(&$($m)? $s.acquisition.sampling_frequency_hz)
            }
            (Owner::Acquisition, F::MaxDepth) => Some(&$($m)? $s.acquisition.max_depth_m),
            (Owner::Acquisition, F::DepthGain) => Some(&$($m)? $s.acquisition.depth_gain_db_per_cm),
            (Owner::Transmit(i), field) => match $s.acquisition.transmits.$get(*i) {
                None => None,
                Some(t) => match (field, &$($m)? t.virtual_source_m, &$($m)? t.focus_m) {
                    (F::Angle, _, _) => t.angle_deg.$as_(),
                    (F::VirtualSource, Some(p), _) | (F::Focus, _, Some(p)) => at!(p),
                    _ => None,
                },
            },
            (Owner::Imaging, F::XRange) => at!($s.imaging.x_range_m),
            (Owner::Imaging, F::ZRange) => at!($s.imaging.z_range_m),
            (Owner::Imaging, F::Pixel) => Some(&$($m)? $s.imaging.pixel_m),
            (Owner::Imaging, F::FNumber) => Some(&$($m)? $s.imaging.f_number),
            (Owner::Imaging, F::DynamicRange) => Some(&$($m)? $s.imaging.dynamic_range_db),
            (Owner::Imaging, F::SoundSpeed) => $s.imaging.sound_speed_m_s.$as_(),
            (Owner::Material(name), field) => match $s.materials.$get(name.as_str()) {
                None => None,
                Some(m) => match field {
                    F::Impedance => Some(&$($m)? m.impedance_mrayl),
                    F::SoundSpeed => Some(&$($m)? m.sound_speed_m_s),
                    F::Roughness => Some(&$($m)? m.roughness),
                    F::Attenuation => Some(&$($m)? m.attenuation_db_cm_mhz),
                    F::ScattererDensity => Some(&$($m)? m.scatterer_density_per_mm3),
                    F::ScattererStrength => Some(&$($m)? m.scatterer_strength),
                    _ => None,
                },
            },
            (Owner::Object(name), field) => match $s.objects.$iter().find(|o| &o.name == name) {
                None => None,
                Some(o) => match field {
                    F::Center => at!(o.center_m),
                    F::Radius => o.radius_m.$as_(),
                    F::Thickness => o.thickness_m.$as_(),
                    F::ScattererDensity => o.lumen_scatterer_density_per_mm3.$as_(),
                    F::ScattererStrength => o.lumen_scatterer_strength.$as_(),
                    F::ZTop => o.z_top_m.$as_(),
                    F::ZBottom => o.z_bottom_m.$as_(),
                    F::Normal => match &$($m)? o.normal {
                        Some(n) => at!(n),
                        None => None,
                    },
                    F::Rotation => match &$($m)? o.rotation_deg {
                        Some(r) => at!(r),
                        None => None,
                    },
                    F::Scale => o.scale.$as_(),
                    _ => None,
                },
            },
            _ => None,
        }
        .filter(|_| key.declaration().is_some_and(|d| d.array == c.is_some()))
    }};
}

impl Scene {
    /// The value of `key`, if the scene has that parameter.
    pub(crate) fn slot(&self, key: &ParamKey) -> Option<&f64> {
        slot!(self, key, as_ref, get, iter)
    }

    /// The place of `key`'s value, if the scene has that parameter.
    pub(crate) fn slot_mut(&mut self, key: &ParamKey) -> Option<&mut f64> {
        slot!(self, key, as_mut, get_mut, iter_mut, mut)
    }

    /// Every parameter's key, in [`PARAMETERS`]' order for each owner: the
    /// medium, the probe, the acquisition (its transmits in order), the
    /// imaging, the materials by name, the objects in file order.
    pub fn param_keys(&self) -> Vec<ParamKey> {
        let mut out = Vec::new();
        let mut rows = PARAMETERS;
        while let Some(first) = rows.first() {
            // A run of rows of one section, visited for each owner of it.
            let n = rows
                .iter()
                .position(|d| d.section != first.section)
                .unwrap_or(rows.len());
            let (run, rest) = rows.split_at(n);
            rows = rest;
            let owners: Vec<Owner> = match first.section {
                S::Medium => vec![Owner::Medium],
                S::Probe => vec![Owner::Probe],
                S::Acquisition => vec![Owner::Acquisition],
                S::Imaging => vec![Owner::Imaging],
                S::Transmit => (0..self.acquisition.transmits.len())
                    .map(Owner::Transmit)
                    .collect(),
                S::Material => self
                    .materials
                    .keys()
                    .cloned()
                    .map(Owner::Material)
                    .collect(),
                S::Object => self
                    .objects
                    .iter()
                    .map(|o| Owner::Object(o.name.clone()))
                    .collect(),
            };
            for owner in owners {
                for d in run {
                    let key = ParamKey::new(owner.clone(), d.field);
                    if !d.array {
                        if self.slot(&key).is_some() {
                            out.push(key);
                        }
                        continue;
                    }
                    for i in 0.. {
                        let key = key.clone().at(i);
                        if self.slot(&key).is_none() {
                            break;
                        }
                        out.push(key);
                    }
                }
            }
        }
        out
    }
}
