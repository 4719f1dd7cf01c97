//! The array and the transmits a scene describes (`[probe]` kind and radius,
//! `acquisition.angles_deg` and `[[acquisition.transmits]]`), as the
//! geometry of `usray_signal::array` and the time models of
//! `usray_signal::transmit`: checked by the same rules as channel files
//! (`ArrayGeometry::from_meta`, `TransmitWave::from_meta`), evaluated in
//! values for the acquisition plan and in `T` for the tracer.

use super::key::{Field, ParamKey};
use super::{Scene, SceneError};
use usray_ad::Real;
use usray_signal::array::{ArrayGeometry, ArrayKind, RADIUS_KEY};
use usray_signal::transmit::{TransmitWave, FOCUS_KEY, VIRTUAL_SOURCE_KEY};
use usray_signal::{ProbeMeta, TransmitMeta};

impl Scene {
    /// Number of transmits: the plane waves of `angles_deg`, then `transmits`.
    pub fn n_transmits(&self) -> usize {
        self.acquisition.angles_deg.len() + self.acquisition.transmits.len()
    }

    /// The probe as channel metadata describes it (CONTRACT §2; `radius_m` in
    /// `extra` for a convex array).
    pub fn probe_meta(&self) -> ProbeMeta {
        let p = &self.probe;
        let mut extra = serde_json::Map::new();
        if let Some(r) = p.radius_m {
            extra.insert(RADIUS_KEY.into(), r.into());
        }
        ProbeMeta {
            kind: p.kind.clone(),
            n_elements: p.n_elements,
            pitch_m: p.pitch_m,
            element_width_m: p.element_width_m,
            extra: extra.into_iter().collect(),
        }
    }

    /// The transmits as channel metadata describes them (CONTRACT §2), in
    /// acquisition order.
    pub fn transmit_metas(&self) -> Vec<TransmitMeta> {
        let a = &self.acquisition;
        let plane = |angle_deg: f64| TransmitMeta {
            kind: "plane_wave".into(),
            angle_rad: angle_deg.to_radians(),
            t0_s: None,
            extra: Default::default(),
        };
        let listed = a.transmits.iter().map(|t| {
            let mut m = plane(t.angle_deg.unwrap_or(0.0));
            m.kind = t.kind.clone();
            for (key, point) in [
                (VIRTUAL_SOURCE_KEY, t.virtual_source_m),
                (FOCUS_KEY, t.focus_m),
            ] {
                if let Some([x, z]) = point {
                    m.extra.insert(key.into(), serde_json::json!([x, z]));
                }
            }
            m
        });
        a.angles_deg
            .iter()
            .map(|&d| plane(d))
            .chain(listed)
            .collect()
    }

    /// The array's geometry in values (the scene is validated).
    pub fn array_geometry(&self) -> ArrayGeometry<f64> {
        self.array_geometry_t(|k| self.get(&k).unwrap_or(f64::NAN))
    }

    /// The array's geometry with its parameters read by `get` (a parameter
    /// key → its value in `T`): `probe.pitch_m`, `probe.element_width_m`,
    /// `probe.radius_m` (convex arrays; `+∞` for flat ones, unused).
    pub(crate) fn array_geometry_t<T: Real>(
        &self,
        get: impl Fn(ParamKey) -> T,
    ) -> ArrayGeometry<T> {
        let kind = ArrayKind::parse(&self.probe.kind).unwrap_or(ArrayKind::Linear);
        ArrayGeometry {
            kind,
            n_elements: self.probe.n_elements,
            pitch_m: get(ParamKey::probe(Field::Pitch)),
            element_width_m: get(ParamKey::probe(Field::ElementWidth)),
            radius_m: match self.probe.radius_m {
                Some(_) => get(ParamKey::probe(Field::Radius)),
                None => T::from_f64(f64::INFINITY),
            },
        }
    }

    /// The transmitted waves in values (the scene is validated).
    pub fn transmit_waves(&self) -> Vec<TransmitWave<f64>> {
        self.transmit_waves_t(|k| self.get(&k).unwrap_or(f64::NAN))
    }

    /// The transmitted waves with their parameters read by `get`: plane waves
    /// from `acquisition.angles_deg.I` and `acquisition.transmits.I.angle_deg`
    /// (degrees, converted with the same `× π/180` as ever), diverging and
    /// focused waves from `….virtual_source_m.K` and `….focus_m.K`.
    pub(crate) fn transmit_waves_t<T: Real>(
        &self,
        get: impl Fn(ParamKey) -> T,
    ) -> Vec<TransmitWave<T>> {
        let deg = T::from_f64(core::f64::consts::PI / 180.0);
        let a = &self.acquisition;
        let plane = (0..a.angles_deg.len()).map(|i| TransmitWave::PlaneWave {
            angle_rad: get(ParamKey::acquisition(Field::Angles).at(i)) * deg,
        });
        let listed = a.transmits.iter().enumerate().map(|(i, t)| {
            let k = |field| ParamKey::transmit(i, field);
            let point = |field| [get(k(field).at(0)), get(k(field).at(1))];
            match t.kind.as_str() {
                "diverging" => TransmitWave::Diverging {
                    source_m: point(Field::VirtualSource),
                },
                "focused" => TransmitWave::Focused {
                    focus_m: point(Field::Focus),
                },
                _ => TransmitWave::PlaneWave {
                    angle_rad: get(k(Field::Angle)) * deg,
                },
            }
        });
        plane.chain(listed).collect()
    }

    /// Checks `[probe]`'s kind and radius and every transmit with the rules
    /// of channel files (`usray_signal`): a known kind, a convex radius of at
    /// least half the aperture, elements that do not overlap, each transmit
    /// kind with its own key (and no other's), a virtual source behind the
    /// array, a focus in front of it. The error names the scene key.
    pub(super) fn check_acquisition(&self) -> Result<(), SceneError> {
        let f = self.source.as_str();
        // usray_signal's messages start with the key they blame, in backticks.
        ArrayGeometry::from_meta(&self.probe_meta()).map_err(|m| {
            let key = m.split('`').nth(1).unwrap_or("probe.kind").to_string();
            SceneError::new(f, key, m)
        })?;
        let a = &self.acquisition;
        if self.n_transmits() == 0 {
            return Err(SceneError::new(
                f,
                "acquisition.angles_deg",
                "expected at least one transmit (`angles_deg` or `[[acquisition.transmits]]`)",
            ));
        }
        let metas = self.transmit_metas();
        for (i, t) in a.transmits.iter().enumerate() {
            let key = |leaf: &str| format!("acquisition.transmits.{i}.{leaf}");
            let given = [
                ("angle_deg", t.angle_deg.is_some()),
                (VIRTUAL_SOURCE_KEY, t.virtual_source_m.is_some()),
                (FOCUS_KEY, t.focus_m.is_some()),
            ];
            let own = match t.kind.as_str() {
                "plane_wave" => "angle_deg",
                "diverging" => VIRTUAL_SOURCE_KEY,
                "focused" => FOCUS_KEY,
                other => {
                    return Err(SceneError::new(
                        f,
                        key("kind"),
                        format!(
                            "expected \"plane_wave\", \"diverging\" or \"focused\", found {other:?}"
                        ),
                    ))
                }
            };
            if given.iter().any(|&(leaf, present)| leaf == own && !present) {
                return Err(SceneError::new(
                    f,
                    key(own),
                    format!("required for a {:?} transmit", t.kind),
                ));
            }
            if let Some((leaf, _)) = given
                .iter()
                .find(|&&(leaf, present)| leaf != own && present)
            {
                return Err(SceneError::new(
                    f,
                    key(leaf),
                    format!("not a key of a {:?} transmit (it takes `{own}`)", t.kind),
                ));
            }
            let j = a.angles_deg.len() + i;
            TransmitWave::from_meta(j, &metas[j]).map_err(|m| SceneError::new(f, key(own), m))?;
        }
        Ok(())
    }
}
