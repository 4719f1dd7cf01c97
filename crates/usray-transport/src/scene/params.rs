//! Parameter paths: every continuous scalar of a scene, by its dotted path.
//!
//! The form is `TABLE.KEY` for the top-level tables, `materials.NAME.KEY`,
//! `objects.NAME.KEY` (NAME is the object's `name`), and a trailing `.I` for a
//! component of an array (`objects.cylinder.center_m.2` is the cylinder's depth,
//! `acquisition.angles_deg.0` the first steering angle,
//! `acquisition.transmits.1.focus_m.1` the depth of the second listed
//! transmit's focus). Integers (`n_elements`,
//! `rays_per_element`, `max_bounces`, `seed`) and strings are not parameters.
//! Optional keys are parameters only when present in the scene.
//!
//! In code a parameter is a [`ParamKey`] ([`super::key`]): the path is parsed
//! once, at the edge ([`Scene::key`], or `str::parse` without a scene), and
//! printed by its `Display`.
//!
//! ```
//! # let text = include_str!("../../../../scenes/cylinder.toml");
//! use usray_transport::scene::key::{Field, ParamKey};
//! let mut s = usray_transport::Scene::from_toml_str(text, "cylinder.toml", ".").unwrap();
//! let depth = s.key("objects.cylinder.center_m.2").unwrap();
//! assert_eq!(s.get(&depth).unwrap(), 0.015);
//! s.set(&ParamKey::object("cylinder", Field::Radius), 0.006).unwrap();
//! assert!(s.key("objects.cylinder.nope").is_err());
//! assert!(s.get(&ParamKey::object("nope", Field::Radius)).is_err());
//! ```

use super::key::{Field, ParamKey};
use super::{Scene, SceneError};

/// Thickest wall [`Scene::set_projected`] leaves a hollow cylinder, as a fraction
/// of its radius (the scene requires `thickness_m < radius_m`).
pub const MAX_WALL_FRACTION: f64 = 0.99;

impl Scene {
    /// The key of the parameter at dotted `path`; an error names the path when
    /// the scene has no such parameter.
    pub fn key(&self, path: &str) -> Result<ParamKey, SceneError> {
        path.parse::<ParamKey>()
            .ok()
            .filter(|k| self.slot(k).is_some())
            .ok_or_else(|| unknown(self, path))
    }

    /// Every parameter with its value, in a fixed order (`usray params`).
    pub fn params(&self) -> Vec<(ParamKey, f64)> {
        self.param_keys()
            .into_iter()
            .map(|k| {
                let v = self.slot(&k).copied().unwrap_or(f64::NAN);
                (k, v)
            })
            .collect()
    }

    /// The value of one parameter; an error names the path when the scene does
    /// not have it.
    pub fn get(&self, key: &ParamKey) -> Result<f64, SceneError> {
        self.slot(key)
            .copied()
            .ok_or_else(|| unknown(self, &key.to_string()))
    }

    /// Set one parameter and re-validate the scene. On error (unknown key, value
    /// out of range) the scene is left unchanged.
    pub fn set(&mut self, key: &ParamKey, value: f64) -> Result<(), SceneError> {
        self.set_values(&[(key, value)], false)
    }
}

impl Scene {
    /// Sets several parameters at once and projects the bounds that couple them
    /// onto the valid region instead of refusing the step: a hollow cylinder's
    /// `thickness_m` is kept at most [`MAX_WALL_FRACTION`] of its `radius_m`.
    /// This is for optimisers, whose steps may cross a coupled bound that no
    /// box of per-parameter ranges can express (a radius shrinking under its
    /// wall); a user's file still gets [`Scene::set`]'s error. Other invalid
    /// values are refused as by [`Scene::set`], leaving the scene unchanged.
    ///
    /// ```
    /// # let text = include_str!("../../../../scenes/ring.toml");
    /// use usray_transport::scene::key::{Field, ParamKey};
    /// let mut s = usray_transport::Scene::from_toml_str(text, "ring.toml", ".").unwrap();
    /// let (radius, wall) = (ParamKey::object("tube", Field::Radius), ParamKey::object("tube", Field::Thickness));
    /// let r = s.get(&radius).unwrap();
    /// assert!(s.set(&wall, 1.5 * r).is_err());
    /// s.set_projected(&[(&wall, 1.5 * r)]).unwrap();
    /// let t = s.get(&wall).unwrap();
    /// assert_eq!(t, usray_transport::scene::params::MAX_WALL_FRACTION * r);
    /// ```
    pub fn set_projected(&mut self, values: &[(&ParamKey, f64)]) -> Result<(), SceneError> {
        self.set_values(values, true)
    }

    /// Sets `values` (projecting coupled bounds when `project`) and validates;
    /// on any error every value is put back as it was.
    fn set_values(&mut self, values: &[(&ParamKey, f64)], project: bool) -> Result<(), SceneError> {
        // The old values, restored in reverse order on error (a key given twice
        // ends with its first old value).
        let mut undo: Vec<(ParamKey, f64)> = Vec::with_capacity(values.len());
        let mut result = Ok(());
        for (key, value) in values {
            match self.slot_mut(key) {
                Some(v) => {
                    undo.push(((*key).clone(), *v));
                    *v = *value;
                }
                None => {
                    result = Err(unknown(self, &key.to_string()));
                    break;
                }
            }
        }
        if result.is_ok() && project {
            for o in self.objects.iter_mut() {
                if let (Some(r), Some(t)) = (o.radius_m, o.thickness_m.as_mut()) {
                    if r > 0.0 && *t >= r {
                        undo.push((ParamKey::object(&o.name, Field::Thickness), *t));
                        *t = MAX_WALL_FRACTION * r;
                    }
                }
            }
        }
        if result.is_ok() {
            result = self.validate();
        }
        if result.is_err() {
            for (key, old) in undo.iter().rev() {
                if let Some(v) = self.slot_mut(key) {
                    *v = *old;
                }
            }
        }
        result
    }
}

fn unknown(s: &Scene, path: &str) -> SceneError {
    SceneError::new(
        &s.source,
        path,
        "unknown parameter path; `usray params SCENE` lists the valid ones",
    )
}
