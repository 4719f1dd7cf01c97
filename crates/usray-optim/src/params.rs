//! Parameters to optimise: scene parameter keys with admissible ranges, and the
//! paper's map from the optimiser's unconstrained state to physical values.
//!
//! Paper §"Parameterization and constraints": the optimiser holds `θ̃ ∈ ℝᵈ`;
//! `θ_n = clip(θ̃, 0, 1)` (eq. clip01) and `θ = θ_min + θ_n (θ_max − θ_min)`
//! (eq. scale_phys). The clip's derivative is 1 strictly inside `(0, 1)` and 0 at or
//! beyond the bounds (eq. clip_grad), so a saturated parameter gets no gradient
//! until the optimiser moves it back inside.

use thiserror::Error;
use usray_transport::{ParamKey, Scene, SceneError};

/// An error in a `--params` specification.
#[derive(Debug, Error, PartialEq)]
pub enum ParamSpecError {
    /// The text is not `PATH` or `PATH=MIN:MAX`.
    #[error("parameter `{0}`: expected PATH or PATH=MIN:MAX (e.g. objects.cylinder.radius_m=0.003:0.007)")]
    Syntax(String),
    /// `PATH` is not a parameter of the scene.
    #[error("`{path}` is not a parameter of the scene (see `usray params SCENE`)")]
    Unknown {
        /// The text given as the path.
        path: String,
        /// The scene's error.
        #[source]
        source: SceneError,
    },
    /// A bound is not a finite number.
    #[error("parameter `{path}`: bound `{text}` is not a finite number")]
    Bound {
        /// The parameter path.
        path: String,
        /// The offending text.
        text: String,
    },
    /// `MIN` is not below `MAX`.
    #[error("parameter `{path}`: range {min}:{max} is empty (MIN must be below MAX)")]
    EmptyRange {
        /// The parameter path.
        path: String,
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
    },
}

/// One optimised parameter: its key and admissible range `[min, max]` in the
/// parameter's own unit.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamSpec {
    /// The scene parameter (printed as its dotted path, CONTRACT §3).
    pub key: ParamKey,
    /// Lower bound `θ_min`.
    pub min: f64,
    /// Upper bound `θ_max`.
    pub max: f64,
}

impl ParamSpec {
    /// Parses `PATH=MIN:MAX`, or `PATH` alone with the parameter's default range
    /// around its value in `scene` ([`default_range`]). `PATH` must be a
    /// parameter of `scene`.
    ///
    /// ```
    /// # let scene = usray_transport::Scene::from_toml_str(include_str!("../../../scenes/cylinder.toml"), "c.toml", ".").unwrap();
    /// use usray_optim::ParamSpec;
    /// let p = ParamSpec::parse("objects.cylinder.radius_m=0.003:0.007", &scene).unwrap();
    /// assert_eq!((p.min, p.max), (0.003, 0.007));
    /// assert_eq!(p.key.to_string(), "objects.cylinder.radius_m");
    /// let q = ParamSpec::parse("materials.target.roughness", &scene).unwrap();
    /// assert_eq!((q.min, q.max), (0.01, 1.0));
    /// assert!(ParamSpec::parse("objects.nope.radius_m", &scene).is_err());
    /// ```
    pub fn parse(text: &str, scene: &Scene) -> Result<Self, ParamSpecError> {
        let text = text.trim();
        let (path, range) = match text.split_once('=') {
            Some((p, r)) => (p.trim(), Some(r)),
            None => (text, None),
        };
        let key = scene.key(path).map_err(|source| ParamSpecError::Unknown {
            path: path.to_string(),
            source,
        })?;
        let (min, max) = match range {
            None => default_range(&key, scene.get(&key).unwrap_or(f64::NAN)),
            Some(r) => {
                let (a, b) = r
                    .split_once(':')
                    .ok_or_else(|| ParamSpecError::Syntax(text.to_string()))?;
                let num = |s: &str| {
                    s.trim()
                        .parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| ParamSpecError::Bound {
                            path: path.to_string(),
                            text: s.trim().to_string(),
                        })
                };
                (num(a)?, num(b)?)
            }
        };
        if min >= max {
            return Err(ParamSpecError::EmptyRange {
                path: path.to_string(),
                min,
                max,
            });
        }
        Ok(Self { key, min, max })
    }

    /// `key` with its default range around `value` ([`default_range`]).
    pub fn around(key: ParamKey, value: f64) -> Self {
        let (min, max) = default_range(&key, value);
        Self { key, min, max }
    }

    /// `θ = θ_min + θ_n (θ_max − θ_min)` (paper eq. scale_phys).
    pub fn physical(&self, normalised: f64) -> f64 {
        self.min + normalised * (self.max - self.min)
    }

    /// The inverse of [`ParamSpec::physical`]: `θ_n = (θ − θ_min)/(θ_max − θ_min)`.
    pub fn normalised(&self, physical: f64) -> f64 {
        (physical - self.min) / (self.max - self.min)
    }
}

/// The default admissible range of a parameter that was named without one,
/// around its current `value`: the rule its key declares
/// (`usray_transport::scene::key::PARAMETERS`, [`usray_transport::scene::key::RangeRule`]).
///
/// | kind | range |
/// |---|---|
/// | `roughness` (GGX α) | `[0.01, 1]` |
/// | `impedance_mrayl` | `[0.5·v, 2·v]` |
/// | `sound_speed_m_s` | `[0.9·v, 1.1·v]` |
/// | `pitch_m`, `element_width_m`, `center_frequency_hz` | `[0.8·v, 1.2·v]` |
/// | `cycles` | `[0.5·v, 2·v]` |
/// | `attenuation_db_cm_mhz` | `[0, max(2, 2·v)]` |
/// | `scatterer_density_per_mm3` | `[0, max(20, 2·v)]` |
/// | `scatterer_strength` | `[0, max(1, 2·v)]` |
/// | `depth_gain_db_per_cm` | `[v − 3, v + 3]` |
/// | `thickness_m` | `[0, max(5 mm, 2·v)]` |
/// | other lengths (`*_m`, incl. vector components) | `[v − max(0.3·|v|, 2 mm), v + max(0.3·|v|, 2 mm)]` |
/// | anything else | `[v − max(0.5·|v|, 1), v + max(0.5·|v|, 1)]` |
///
/// ```
/// use usray_transport::{Field, ParamKey};
/// let radius = ParamKey::object("c", Field::Radius);
/// assert_eq!(usray_optim::default_range(&radius, 0.005), (0.003, 0.007));
/// ```
pub fn default_range(key: &ParamKey, value: f64) -> (f64, f64) {
    key.default_range(value)
}

/// The optimiser's unconstrained state `θ̃` for a set of parameters, with the
/// paper's clip-and-scale map to physical values and its chain rule.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamMap {
    /// The parameters, in order.
    pub specs: Vec<ParamSpec>,
}

impl ParamMap {
    /// A map over `specs`.
    pub fn new(specs: Vec<ParamSpec>) -> Self {
        Self { specs }
    }

    /// The unconstrained state that maps to the given physical values (no clipping
    /// is applied: a value outside its range gives a state outside `[0, 1]`).
    pub fn state_from_physical(&self, physical: &[f64]) -> Vec<f64> {
        self.specs
            .iter()
            .zip(physical)
            .map(|(s, &v)| s.normalised(v))
            .collect()
    }

    /// Physical values from the state: eq. clip01 then eq. scale_phys.
    pub fn physical(&self, state: &[f64]) -> Vec<f64> {
        self.specs
            .iter()
            .zip(state)
            .map(|(s, &x)| s.physical(x.clamp(0.0, 1.0)))
            .collect()
    }

    /// Chain rule from `∂L/∂θ` (physical) to `∂L/∂θ̃` (state):
    /// `∂L/∂θ̃_j = ∂L/∂θ_j · (θ_max − θ_min) · 1[0 < θ̃_j < 1]` (eqs. scale_phys, clip_grad).
    ///
    /// ```
    /// use usray_optim::{ParamMap, ParamSpec};
    /// use usray_transport::{Field, ParamKey};
    /// let key = ParamKey::probe(Field::Pitch);
    /// let m = ParamMap::new(vec![ParamSpec { key, min: 1.0, max: 3.0 }]);
    /// assert_eq!(m.state_gradient(&[0.5], &[10.0]), vec![20.0]);
    /// assert_eq!(m.state_gradient(&[1.2], &[10.0]), vec![0.0]); // saturated: no gradient
    /// ```
    pub fn state_gradient(&self, state: &[f64], d_physical: &[f64]) -> Vec<f64> {
        self.specs
            .iter()
            .zip(state.iter().zip(d_physical))
            .map(|(s, (&x, &g))| {
                if x > 0.0 && x < 1.0 {
                    g * (s.max - s.min)
                } else {
                    0.0
                }
            })
            .collect()
    }
}
