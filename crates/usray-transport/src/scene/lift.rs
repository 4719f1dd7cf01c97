//! The numeric state of a scene in any `T: Real`: what the tracer reads.

use super::key::{Field, ParamKey};
use super::{Emission, ReceiveBaffle, ReceiveDirectivity, Scene, SceneError, ShapeKind};
use crate::integrator::EdgeWaves;
use crate::probe::{ElementDirectivity, ReceiveLobe, Receiver};
use std::sync::Arc;
use usray_ad::Real;
use usray_geometry::shapes::cylinder::Cylinder;
use usray_geometry::shapes::half_space::HalfSpace;
use usray_geometry::shapes::hollow_cylinder::HollowCylinder;
use usray_geometry::shapes::slab::Slab;
use usray_geometry::shapes::sphere::Sphere;
use usray_geometry::{Geometry, MeshInstance, TriangleMesh, Vec3};
use usray_signal::array::{ArrayGeometry, Element};
use usray_signal::transmit::TransmitWave;

/// Acoustic properties of one medium, in `T`.
#[derive(Clone, Copy, Debug)]
pub struct MaterialT<T> {
    /// Sound speed, m/s.
    pub sound_speed: T,
    /// Impedance, MRayl.
    pub impedance: T,
    /// GGX roughness `α` of the boundary of an object made of it.
    pub roughness: T,
    /// Attenuation, dB/(cm·MHz).
    pub attenuation_db_cm_mhz: T,
    /// Scatterers per mm³ (volume scattering; 0 = off).
    pub scatterer_density_per_mm3: T,
    /// Scatterer amplitude strength (dimensionless).
    pub scatterer_strength: T,
}

/// One object of a lifted scene: its index in the geometry and its material.
#[derive(Clone, Copy, Debug)]
pub struct ObjectT<T> {
    /// The object's material.
    pub material: MaterialT<T>,
}

/// The scatterers in a hollow cylinder's lumen (`lumen_scatterer_*` keys): a
/// [`crate::effects::ScattererField`] restricted to the disc `ρ < r − t` about
/// the tube's axis (along `y`), in whatever medium fills the lumen — the
/// medium around the tube, so the tracer visits them on segments whose medium
/// is `enclosing`. The disc's edge is a value: like the scatterer grid, the
/// support is not differentiated; the strength and density are.
#[derive(Clone, Copy, Debug)]
pub struct LumenT<T> {
    /// The tube's index among the scene's objects (it keys the field).
    pub object: usize,
    /// The tube's axis point `(x, z)`, m.
    pub axis_xz_m: [f64; 2],
    /// The lumen's radius `r − t`, m.
    pub radius_m: f64,
    /// The object whose material fills the lumen (the innermost object holding
    /// the tube's wall, "later is inside"), `None` for the background medium.
    pub enclosing: Option<usize>,
    /// Scatterers per mm³.
    pub scatterer_density_per_mm3: T,
    /// Scatterer amplitude strength (dimensionless).
    pub scatterer_strength: T,
}

impl<T> LumenT<T> {
    /// The part `[s₀, s₁] ⊂ [0, len]` of the segment `origin + s·dir` (m, `dir`
    /// a unit vector) inside the lumen's disc, if any: the roots of
    /// `|(o + s d) − a|² = ρ²` in the `x`–`z` plane.
    ///
    /// ```
    /// use usray_transport::scene::LumenT;
    /// let l = LumenT { object: 0, axis_xz_m: [0.0, 0.01], radius_m: 0.002, enclosing: None,
    ///                  scatterer_density_per_mm3: 5.0, scatterer_strength: 0.1 };
    /// let (s0, s1) = l.chord([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 1.0).unwrap();
    /// assert!((s0 - 0.008).abs() < 1e-15 && (s1 - 0.012).abs() < 1e-15);
    /// assert!(l.chord([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.005).is_none()); // ends before
    /// assert!(l.chord([0.003, 0.0, 0.0], [0.0, 0.0, 1.0], 1.0).is_none()); // passes by
    /// ```
    pub fn chord(&self, origin: [f64; 3], dir: [f64; 3], len: f64) -> Option<(f64, f64)> {
        let (rx, rz) = (origin[0] - self.axis_xz_m[0], origin[2] - self.axis_xz_m[1]);
        let a = dir[0] * dir[0] + dir[2] * dir[2];
        let b = rx * dir[0] + rz * dir[2];
        let c = rx * rx + rz * rz - self.radius_m * self.radius_m;
        let (s0, s1) = if a <= 1e-300 {
            // Along the axis: inside throughout or not at all.
            if c >= 0.0 {
                return None;
            }
            (0.0, len)
        } else {
            let disc = b * b - a * c;
            if disc <= 0.0 {
                return None;
            }
            let q = disc.sqrt();
            (((-b - q) / a).max(0.0), ((-b + q) / a).min(len))
        };
        (s1 > s0).then_some((s0, s1))
    }
}

/// A scene's numbers in `T` (CONTRACT §1 frame, SI units): the input of the
/// generic tracer. Build it with [`Scene::lift`].
#[derive(Clone, Debug)]
pub struct SceneT<T> {
    /// Background medium (roughness unused).
    pub medium: MaterialT<T>,
    /// Objects, indexed like the geometry's objects and the scene's `[[objects]]`.
    pub objects: Vec<ObjectT<T>>,
    /// The hollow cylinders' lumens that hold scatterers (usually none: the
    /// tracer visits this list on every segment).
    pub lumens: Vec<LumenT<T>>,
    /// The geometry (hit finding in values, hit quantities in `T`).
    pub geometry: Geometry<T>,
    /// Number of elements.
    pub n_elements: usize,
    /// The array: kind, pitch, element width and convex radius, m
    /// (`usray_signal::array`; element centres and normals from it alone).
    pub array: ArrayGeometry<T>,
    /// Every element's centre and normal ([`ArrayGeometry::elements`]),
    /// evaluated once here.
    pub elements: Vec<Element<T>>,
    /// Element elevation extent, m.
    pub elevation: T,
    /// Centre frequency, Hz.
    pub center_frequency: T,
    /// Pulse cycles.
    pub cycles: T,
    /// `σ_f` of the pulse spectrum, Hz, from `center_frequency` and `cycles`
    /// (`usray_signal::pulse::pulse_bandwidth_hz`; the down-shift's scale,
    /// [`crate::downshift`]).
    pub pulse_bandwidth: T,
    /// The largest down-shift the tracer places, in `σ_f`, from the values of
    /// `center_frequency` and `cycles` ([`crate::downshift::max_shift`]).
    pub max_shift: f64,
    /// Every element's receive directivity (`probe.receive_directivity`).
    pub receiver: Receiver<T>,
    /// The transmitted waves in acquisition order (`usray_signal::transmit`:
    /// each element's firing time).
    pub transmits: Vec<TransmitWave<T>>,
    /// Sampling frequency, Hz (a plain number: it fixes the sample grid).
    pub fs: f64,
    /// Depth gain, dB/cm.
    pub depth_gain_db_per_cm: T,
    /// Sound speed the scanner assumes (transmit delays, depth gain), m/s.
    pub imaging_sound_speed: T,
    /// Emission model of the primary rays.
    pub emission: Emission,
    /// 2-D transport (`acquisition.dimensions = 2`): rays, normals and lobes in
    /// the `xz` plane, densities per radian.
    pub planar: bool,
    /// The transmit aperture's edge waves (`acquisition.edge_waves`; `None`:
    /// not modelled).
    pub edge_waves: Option<EdgeWaves<T>>,
    /// Thin layers let a wave beyond their critical angle tunnel through
    /// (`acquisition.thin_layer_tunnelling`; [`crate::thin_layer`]).
    pub thin_layer_tunnelling: bool,
}

impl<T: Real> SceneT<T> {
    /// The thickness of object `object` where a wave entering it beyond the
    /// critical angle tunnels through ([`crate::thin_layer`]): a layer's
    /// ([`usray_geometry::Geometry::layer_thickness`]) when the scene asks for
    /// tunnelling and the wave enters it; `None` otherwise.
    pub fn tunnelling_layer(&self, object: usize, entering: bool) -> Option<T> {
        (self.thin_layer_tunnelling && entering)
            .then(|| self.geometry.layer_thickness(object))
            .flatten()
    }

    /// What an element receives of a direction's neighbourhood, seen from
    /// squared distance `r2` (m²) at cosine `cos_e` to its normal: its solid
    /// angle `w h cos θ_e / r²` (sr) in 3-D, its angle `w cos θ_e / r` (rad) in
    /// 2-D (`w` its width, `h` its elevation). Receiver connections multiply
    /// by it; its inverse is their density in the MIS weights.
    #[inline]
    pub fn element_measure(&self, cos_e: T, r2: T) -> T {
        if self.planar {
            self.array.element_width_m * cos_e / r2.sqrt()
        } else {
            self.array.element_width_m * self.elevation * cos_e / r2
        }
    }

    /// The medium of object `k`, or the background for `None`.
    pub fn medium_of(&self, k: Option<usize>) -> &MaterialT<T> {
        match k {
            Some(k) => &self.objects[k].material,
            None => &self.medium,
        }
    }
}

impl Scene {
    /// Build the scene's numeric state in `T`. `seed(key, value)` turns a
    /// parameter into a `T`: return `T::from_f64(value)` for a constant, or an AD
    /// variable for a parameter to differentiate. `seed` is called for each
    /// parameter the tracer reads, once per read (so it must give the same `T`
    /// for the same key and value):
    ///
    /// ```
    /// # let text = include_str!("../../../../scenes/cylinder.toml");
    /// # let scene = usray_transport::Scene::from_toml_str(text, "cylinder.toml", ".").unwrap();
    /// use usray_ad::{Dual, Real};
    /// use usray_transport::{Field, ParamKey};
    /// let radius = ParamKey::object("cylinder", Field::Radius);
    /// let st = scene
    ///     .lift::<Dual<1>>(|key, v| {
    ///         if *key == radius { Dual::variable(v, 0) } else { Dual::from_f64(v) }
    ///     })
    ///     .unwrap();
    /// assert_eq!(st.objects.len(), 1);
    /// ```
    pub fn lift<T: Real>(
        &self,
        seed: impl Fn(&ParamKey, f64) -> T,
    ) -> Result<SceneT<T>, SceneError> {
        self.lift_with(None, seed)
    }

    /// The placed mesh of every mesh object (index = object index; `None` for
    /// other shapes), in `f64`: OBJ read and BVH built once, for
    /// [`Scene::lift_with`].
    pub fn mesh_instances(&self) -> Result<Vec<Option<MeshInstance<f64>>>, SceneError> {
        let mut out = Vec::with_capacity(self.objects.len());
        for o in &self.objects {
            out.push(match o.shape {
                ShapeKind::Mesh => {
                    let mesh = load_mesh(self, o)?;
                    let tf =
                        mesh_transform::<f64>(o, &|field, c| self.value(&object_key(o, field, c)));
                    Some(MeshInstance::new(mesh, tf).map_err(|e| {
                        SceneError::new(&self.source, format!("objects.{}", o.name), e.to_string())
                    })?)
                }
                _ => None,
            });
        }
        Ok(out)
    }

    /// The value of `key`, 0 when the scene lacks it (the lift reads only
    /// parameters it has checked are present).
    fn value(&self, key: &ParamKey) -> f64 {
        self.slot(key).copied().unwrap_or(0.0)
    }

    /// [`Scene::lift`] reusing meshes placed by [`Scene::mesh_instances`] (no file
    /// read, no BVH build: cheap enough to lift per path in reverse mode). The
    /// parameters' values must be the ones the instances were built with.
    pub fn lift_with<T: Real>(
        &self,
        meshes: Option<&[Option<MeshInstance<f64>>]>,
        seed: impl Fn(&ParamKey, f64) -> T,
    ) -> Result<SceneT<T>, SceneError> {
        let get = |key: ParamKey| -> T { seed(&key, self.value(&key)) };
        let material = |key: &dyn Fn(Field) -> ParamKey, rough: bool| {
            let opt = |field| if rough { get(key(field)) } else { T::zero() };
            MaterialT {
                sound_speed: get(key(Field::SoundSpeed)),
                impedance: get(key(Field::Impedance)),
                roughness: opt(Field::Roughness),
                attenuation_db_cm_mhz: get(key(Field::Attenuation)),
                scatterer_density_per_mm3: opt(Field::ScattererDensity),
                scatterer_strength: opt(Field::ScattererStrength),
            }
        };
        let deg = T::from_f64(core::f64::consts::PI / 180.0);
        let mut geometry = Geometry::new();
        let mut objects = Vec::new();
        for (oi, o) in self.objects.iter().enumerate() {
            let k = |field, c| get(object_key(o, field, c));
            let center = Vec3::new(
                k(Field::Center, Some(0)),
                k(Field::Center, Some(1)),
                k(Field::Center, Some(2)),
            );
            let gerr = |e: &dyn std::fmt::Display| {
                SceneError::new(&self.source, format!("objects.{}", o.name), e.to_string())
            };
            let added = match o.shape {
                ShapeKind::Cylinder => match o.thickness_m {
                    Some(_) => geometry.add(HollowCylinder::new(
                        center,
                        k(Field::Radius, None),
                        k(Field::Thickness, None),
                    )),
                    None => geometry.add(Cylinder::new(center, k(Field::Radius, None))),
                },
                ShapeKind::Sphere => geometry.add(Sphere::new(center, k(Field::Radius, None))),
                ShapeKind::Slab => {
                    geometry.add(Slab::new(k(Field::ZTop, None), k(Field::ZBottom, None)))
                }
                ShapeKind::Plane => {
                    let n = match o.normal {
                        Some(_) => Vec3::new(
                            k(Field::Normal, Some(0)),
                            k(Field::Normal, Some(1)),
                            k(Field::Normal, Some(2)),
                        ),
                        None => Vec3::from_f64s([0.0, 0.0, -1.0]),
                    };
                    geometry.add(HalfSpace::new(center, n.normalize()))
                }
                ShapeKind::Mesh => {
                    let tf = mesh_transform::<T>(o, &k);
                    let inst = match meshes.and_then(|m| m.get(oi)).and_then(Option::as_ref) {
                        Some(placed) => placed.with_transform(tf),
                        None => MeshInstance::new(load_mesh(self, o)?, tf).map_err(|e| gerr(&e))?,
                    };
                    geometry.add(inst)
                }
            };
            added.map_err(|e| gerr(&e))?;
            objects.push(ObjectT {
                material: material(&|field| ParamKey::material(&o.material, field), true),
            });
        }
        // The lumens, once every object is placed (their enclosing object may
        // come earlier in the file).
        let mut lumens = Vec::new();
        for (oi, o) in self.objects.iter().enumerate() {
            let (Some(r), Some(t), Some(_), Some(_)) = (
                o.radius_m,
                o.thickness_m,
                o.lumen_scatterer_density_per_mm3,
                o.lumen_scatterer_strength,
            ) else {
                continue;
            };
            let [x, _, z] = o.center_m;
            // A point in the middle of the wall: the objects holding it other
            // than the tube hold the tube; the innermost fills its lumen.
            let in_wall = [x + r - 0.5 * t, 0.0, z];
            let enclosing = geometry.containing(in_wall).into_iter().rfind(|&j| j != oi);
            let k = |field| get(ParamKey::object(&o.name, field));
            lumens.push(LumenT {
                object: oi,
                axis_xz_m: [x, z],
                radius_m: r - t,
                enclosing,
                scatterer_density_per_mm3: k(Field::ScattererDensity),
                scatterer_strength: k(Field::ScattererStrength),
            });
        }
        let probe = |field| get(ParamKey::probe(field));
        let (center_frequency, cycles) = (probe(Field::CenterFrequency), probe(Field::Cycles));
        let array = self.array_geometry_t(get);
        let receiver = match self.probe.receive_model() {
            ReceiveDirectivity::Element => {
                let d = ElementDirectivity::new(
                    array.element_width_m * center_frequency
                        / get(ParamKey::medium(Field::SoundSpeed)),
                );
                Receiver::Element(match self.probe.receive_baffle.unwrap_or_default() {
                    ReceiveBaffle::Soft => d,
                    ReceiveBaffle::Rigid => d.rigid_baffle(),
                })
            }
            ReceiveDirectivity::Lobe => {
                // An angle the scene gives is a parameter; one it leaves out
                // is the lobe's default (`Probe::lobe_deg`).
                let (main_lobe_deg, cutoff_deg) = self.probe.lobe_deg();
                let angle = |field, given: Option<f64>, value: f64| match given {
                    Some(_) => probe(field) * deg,
                    None => T::from_f64(value) * deg,
                };
                Receiver::Lobe(ReceiveLobe::new(
                    angle(Field::MainLobe, self.probe.main_lobe_deg, main_lobe_deg),
                    angle(Field::Cutoff, self.probe.cutoff_deg, cutoff_deg),
                ))
            }
        };
        let planar = self.acquisition.is_planar();
        if self.acquisition.edge_waves && !planar {
            return Err(SceneError::new(
                &self.source,
                "acquisition.edge_waves".to_string(),
                "edge waves are modelled in 2-D only (`acquisition.dimensions = 2`): \
                 3-D paths keep the energy law, which has no edge-wave term"
                    .to_string(),
            ));
        }
        // The edge waves radiate into the background medium; their boundary is
        // regularised at half the recorded depth (`integrator::EdgeWaves`).
        let edge_waves = self.acquisition.edge_waves.then(|| {
            EdgeWaves::new(
                center_frequency,
                get(ParamKey::medium(Field::SoundSpeed)),
                array.element_width_m,
                self.probe.n_elements,
                0.5 * self.acquisition.max_depth_m,
            )
        });
        Ok(SceneT {
            medium: material(&ParamKey::medium, false),
            objects,
            lumens,
            geometry,
            n_elements: self.probe.n_elements,
            array,
            elements: array.elements(),
            elevation: probe(Field::Elevation),
            center_frequency,
            cycles,
            pulse_bandwidth: usray_signal::pulse::pulse_bandwidth_hz(center_frequency, cycles),
            max_shift: crate::downshift::max_shift(center_frequency.value(), cycles.value()),
            receiver,
            transmits: self.transmit_waves_t(get),
            fs: self.acquisition.sampling_frequency_hz,
            depth_gain_db_per_cm: get(ParamKey::acquisition(Field::DepthGain)),
            imaging_sound_speed: match self.imaging.sound_speed_m_s {
                Some(_) => get(ParamKey::imaging(Field::SoundSpeed)),
                None => get(ParamKey::medium(Field::SoundSpeed)),
            },
            emission: self.acquisition.emission,
            planar,
            edge_waves,
            thin_layer_tunnelling: self.acquisition.thin_layer_tunnelling,
        })
    }

    /// [`Scene::lift`] with every parameter a constant.
    pub fn lift_const<T: Real>(&self) -> Result<SceneT<T>, SceneError> {
        self.lift(|_, v| T::from_f64(v))
    }

    /// [`Scene::lift`] into a forward dual with the given parameters as its `N`
    /// partials, in the order given; a parameter the scene lacks or
    /// `params.len() != N` is an error naming the path.
    ///
    /// ```
    /// # let text = include_str!("../../../../scenes/cylinder.toml");
    /// # let scene = usray_transport::Scene::from_toml_str(text, "cylinder.toml", ".").unwrap();
    /// use usray_transport::{Field, ParamKey};
    /// let radius = ParamKey::object("cylinder", Field::Radius);
    /// let st = scene
    ///     .lift_dual::<2>(&[radius, ParamKey::material("target", Field::Roughness)])
    ///     .unwrap();
    /// assert!(scene.lift_dual::<1>(&[ParamKey::object("nope", Field::Radius)]).is_err());
    /// ```
    pub fn lift_dual<const N: usize>(
        &self,
        params: &[ParamKey],
    ) -> Result<SceneT<usray_ad::Dual<N>>, SceneError> {
        if params.len() != N {
            let names: Vec<String> = params.iter().map(ToString::to_string).collect();
            return Err(SceneError::new(
                &self.source,
                names.join(","),
                format!(
                    "expected exactly {N} parameter paths, found {}",
                    params.len()
                ),
            ));
        }
        for p in params {
            self.get(p)?;
        }
        self.lift(|key, v| match params.iter().position(|q| q == key) {
            Some(i) => usray_ad::Dual::variable(v, i),
            None => usray_ad::Dual::from_f64(v),
        })
    }
}

/// The key of `field` (component `c`) of object `o`.
fn object_key(o: &super::Object, field: Field, c: Option<usize>) -> ParamKey {
    ParamKey {
        component: c,
        ..ParamKey::object(&o.name, field)
    }
}

/// The object → world transform of a mesh object: `center_m`, `rotation_deg`
/// (Euler, degrees), uniform `scale`; `k(field, component)` reads the object's
/// parameters.
fn mesh_transform<T: Real>(
    o: &super::Object,
    k: &dyn Fn(Field, Option<usize>) -> T,
) -> usray_geometry::Transform<T> {
    let deg = T::from_f64(core::f64::consts::PI / 180.0);
    let c = |field, i| k(field, Some(i));
    let center = Vec3::new(
        c(Field::Center, 0),
        c(Field::Center, 1),
        c(Field::Center, 2),
    );
    let rot = match o.rotation_deg {
        Some(_) => Vec3::new(
            c(Field::Rotation, 0) * deg,
            c(Field::Rotation, 1) * deg,
            c(Field::Rotation, 2) * deg,
        ),
        None => Vec3::zero(),
    };
    let s = match o.scale {
        Some(_) => k(Field::Scale, None),
        None => T::one(),
    };
    usray_geometry::Transform::from_euler(center, rot, Vec3::new(s, s, s))
}

/// Read a mesh object's OBJ file (path relative to the scene file) with
/// `usray_geometry::obj::load_obj` (triangles only) and orient its triangles
/// outward. Errors name the object's `path` key and the file.
fn load_mesh(scene: &Scene, o: &super::Object) -> Result<Arc<TriangleMesh>, SceneError> {
    let key = format!("objects.{}.path", o.name);
    let err = |m: String| SceneError::new(&scene.source, key.clone(), m);
    let rel = o
        .path
        .as_deref()
        .ok_or_else(|| err("required for shape mesh".into()))?;
    let full = scene.base_dir.join(rel);
    let mut mesh = usray_geometry::obj::load_obj(&full).map_err(|e| err(e.to_string()))?;
    mesh.orient_outward();
    Ok(Arc::new(mesh))
}
