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
//! ```
//! # let text = include_str!("../../../../scenes/cylinder.toml");
//! let mut s = usray_transport::Scene::from_toml_str(text, "cylinder.toml", ".").unwrap();
//! assert_eq!(s.get("objects.cylinder.center_m.2").unwrap(), 0.015);
//! s.set("objects.cylinder.radius_m", 0.006).unwrap();
//! assert!(s.set("objects.cylinder.nope", 1.0).is_err());
//! ```

use super::{Scene, SceneError};

/// Thickest wall [`Scene::set_projected`] leaves a hollow cylinder, as a fraction
/// of its radius (the scene requires `thickness_m < radius_m`).
pub const MAX_WALL_FRACTION: f64 = 0.99;

impl Scene {
    /// Visit every parameter (path, mutable value) in a fixed order.
    pub fn visit_params_mut(&mut self, f: &mut dyn FnMut(&str, &mut f64)) {
        let m = &mut self.medium;
        f("medium.sound_speed_m_s", &mut m.sound_speed_m_s);
        f("medium.impedance_mrayl", &mut m.impedance_mrayl);
        f("medium.attenuation_db_cm_mhz", &mut m.attenuation_db_cm_mhz);
        let p = &mut self.probe;
        f("probe.pitch_m", &mut p.pitch_m);
        f("probe.element_width_m", &mut p.element_width_m);
        f("probe.center_frequency_hz", &mut p.center_frequency_hz);
        f("probe.cycles", &mut p.cycles);
        f("probe.main_lobe_deg", &mut p.main_lobe_deg);
        f("probe.cutoff_deg", &mut p.cutoff_deg);
        f("probe.elevation_m", &mut p.elevation_m);
        if let Some(r) = p.radius_m.as_mut() {
            f("probe.radius_m", r);
        }
        let a = &mut self.acquisition;
        for (i, v) in a.angles_deg.iter_mut().enumerate() {
            f(&format!("acquisition.angles_deg.{i}"), v);
        }
        for (i, t) in a.transmits.iter_mut().enumerate() {
            let k = |leaf: &str| format!("acquisition.transmits.{i}.{leaf}");
            if let Some(v) = t.angle_deg.as_mut() {
                f(&k("angle_deg"), v);
            }
            for (key, point) in [
                ("virtual_source_m", &mut t.virtual_source_m),
                ("focus_m", &mut t.focus_m),
            ] {
                if let Some(point) = point.as_mut() {
                    for (j, v) in point.iter_mut().enumerate() {
                        f(&k(&format!("{key}.{j}")), v);
                    }
                }
            }
        }
        f(
            "acquisition.sampling_frequency_hz",
            &mut a.sampling_frequency_hz,
        );
        f("acquisition.max_depth_m", &mut a.max_depth_m);
        f(
            "acquisition.depth_gain_db_per_cm",
            &mut a.depth_gain_db_per_cm,
        );
        let im = &mut self.imaging;
        for i in 0..2 {
            f(&format!("imaging.x_range_m.{i}"), &mut im.x_range_m[i]);
        }
        for i in 0..2 {
            f(&format!("imaging.z_range_m.{i}"), &mut im.z_range_m[i]);
        }
        f("imaging.pixel_m", &mut im.pixel_m);
        f("imaging.f_number", &mut im.f_number);
        f("imaging.dynamic_range_db", &mut im.dynamic_range_db);
        if let Some(c) = im.sound_speed_m_s.as_mut() {
            f("imaging.sound_speed_m_s", c);
        }
        for (name, m) in self.materials.iter_mut() {
            let k = |leaf: &str| format!("materials.{name}.{leaf}");
            f(&k("impedance_mrayl"), &mut m.impedance_mrayl);
            f(&k("sound_speed_m_s"), &mut m.sound_speed_m_s);
            f(&k("roughness"), &mut m.roughness);
            f(&k("attenuation_db_cm_mhz"), &mut m.attenuation_db_cm_mhz);
            f(
                &k("scatterer_density_per_mm3"),
                &mut m.scatterer_density_per_mm3,
            );
            f(&k("scatterer_strength"), &mut m.scatterer_strength);
        }
        for o in self.objects.iter_mut() {
            let name = o.name.clone();
            let k = |leaf: &str| format!("objects.{name}.{leaf}");
            for i in 0..3 {
                f(&k(&format!("center_m.{i}")), &mut o.center_m[i]);
            }
            let opts: [(&str, &mut Option<f64>); 4] = [
                ("radius_m", &mut o.radius_m),
                ("thickness_m", &mut o.thickness_m),
                ("z_top_m", &mut o.z_top_m),
                ("z_bottom_m", &mut o.z_bottom_m),
            ];
            for (leaf, v) in opts {
                if let Some(v) = v.as_mut() {
                    f(&k(leaf), v);
                }
            }
            if let Some(n) = o.normal.as_mut() {
                for (i, v) in n.iter_mut().enumerate() {
                    f(&k(&format!("normal.{i}")), v);
                }
            }
            if let Some(r) = o.rotation_deg.as_mut() {
                for (i, v) in r.iter_mut().enumerate() {
                    f(&k(&format!("rotation_deg.{i}")), v);
                }
            }
            if let Some(s) = o.scale.as_mut() {
                f(&k("scale"), s);
            }
        }
    }

    /// Every parameter path with its value, in a fixed order (`usray params`).
    pub fn params(&self) -> Vec<(String, f64)> {
        let mut out = Vec::new();
        self.clone()
            .visit_params_mut(&mut |p, v| out.push((p.to_string(), *v)));
        out
    }

    /// The value of one parameter; an error names the path when it does not exist.
    pub fn get(&self, path: &str) -> Result<f64, SceneError> {
        let mut found = None;
        self.clone().visit_params_mut(&mut |p, v| {
            if p == path {
                found = Some(*v);
            }
        });
        found.ok_or_else(|| unknown(self, path))
    }

    /// Set one parameter and re-validate the scene. On error (unknown path, value
    /// out of range) the scene is left unchanged.
    pub fn set(&mut self, path: &str, value: f64) -> Result<(), SceneError> {
        let mut next = self.clone();
        let mut found = false;
        next.visit_params_mut(&mut |p, v| {
            if p == path {
                *v = value;
                found = true;
            }
        });
        if !found {
            return Err(unknown(self, path));
        }
        next.validate()?;
        *self = next;
        Ok(())
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
    /// let mut s = usray_transport::Scene::from_toml_str(text, "ring.toml", ".").unwrap();
    /// let r = s.get("objects.tube.radius_m").unwrap();
    /// assert!(s.set("objects.tube.thickness_m", 1.5 * r).is_err());
    /// s.set_projected(&[("objects.tube.thickness_m", 1.5 * r)]).unwrap();
    /// let t = s.get("objects.tube.thickness_m").unwrap();
    /// assert_eq!(t, usray_transport::scene::params::MAX_WALL_FRACTION * r);
    /// ```
    pub fn set_projected(&mut self, values: &[(&str, f64)]) -> Result<(), SceneError> {
        let mut next = self.clone();
        for (path, value) in values {
            let mut found = false;
            next.visit_params_mut(&mut |p, v| {
                if p == *path {
                    *v = *value;
                    found = true;
                }
            });
            if !found {
                return Err(unknown(self, path));
            }
        }
        for o in next.objects.iter_mut() {
            if let (Some(r), Some(t)) = (o.radius_m, o.thickness_m.as_mut()) {
                if r > 0.0 && *t >= r {
                    *t = MAX_WALL_FRACTION * r;
                }
            }
        }
        next.validate()?;
        *self = next;
        Ok(())
    }
}

fn unknown(s: &Scene, path: &str) -> SceneError {
    SceneError::new(
        &s.source,
        path,
        "unknown parameter path; `usray params SCENE` lists the valid ones",
    )
}
