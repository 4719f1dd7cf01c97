//! The acquisition quantities an importer looks for, under the spellings files
//! use, and where in a MATLAB file it finds them: the fields of one struct (the
//! "parameter struct", whatever its name), then the file's top-level variables.

use crate::mat::{MatFile, MatValue};

/// A quantity a plane-wave import needs or can use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Quantity {
    /// Sampling frequency, Hz.
    SamplingFrequency,
    /// Centre frequency, Hz.
    CenterFrequency,
    /// Sound speed, m/s.
    SoundSpeed,
    /// Element pitch, m.
    Pitch,
    /// Element width, m.
    ElementWidth,
    /// Number of elements.
    ElementCount,
    /// Transmit steering angles (radians or degrees).
    Angles,
    /// Time of sample 0 after the transmit's time origin, s.
    StartTime,
    /// Per-element transmit delays, s (or wavelengths).
    TransmitDelays,
    /// Fractional bandwidth, %.
    Bandwidth,
    /// Radius of curvature of a convex array, m (`Inf`: flat).
    Radius,
}

/// The unit an angle variable's name states (`TXangle_deg`, `angles_rad`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum AngleUnit {
    Degrees,
    Radians,
}

impl Quantity {
    /// Quantities that mark a struct as the acquisition's parameters.
    const MARKERS: [Quantity; 7] = [
        Quantity::SamplingFrequency,
        Quantity::SoundSpeed,
        Quantity::Pitch,
        Quantity::Angles,
        Quantity::CenterFrequency,
        Quantity::ElementCount,
        Quantity::StartTime,
    ];

    /// Names the quantity goes by, normalised by [`normalise`] (Verasonics,
    /// PyMUST/MUST, USTB and common hand-written exports).
    fn spellings(self) -> &'static [&'static str] {
        match self {
            Quantity::SamplingFrequency => &[
                "fs",
                "samplingfrequency",
                "samplefrequency",
                "samplingrate",
                "samplerate",
                "fsample",
                "fsamp",
            ],
            Quantity::CenterFrequency => &[
                "fc",
                "f0",
                "centerfrequency",
                "centrefrequency",
                "transmitfrequency",
                "txfrequency",
                "txfreq",
                "frequency",
            ],
            Quantity::SoundSpeed => &["c", "c0", "soundspeed", "speedofsound", "sos"],
            Quantity::Pitch => &["pitch", "elementpitch"],
            Quantity::ElementWidth => &["width", "elementwidth"],
            Quantity::ElementCount => &[
                "nelements",
                "nelement",
                "nelem",
                "numelements",
                "numberofelements",
                "nbelements",
                "nel",
            ],
            Quantity::Angles => &[
                "txangle",
                "txangles",
                "angles",
                "angle",
                "steeringangles",
                "steeringangle",
                "steerangles",
                "theta",
                "tilt",
            ],
            Quantity::StartTime => &["t0", "tstart", "starttime", "initialtime", "time0"],
            Quantity::TransmitDelays => &[
                "txdelay",
                "txdelays",
                "transmitdelay",
                "transmitdelays",
                "delays",
            ],
            Quantity::Bandwidth => &["bandwidth", "bw", "fractionalbandwidth"],
            Quantity::Radius => &["radius", "radiusofcurvature", "curvatureradius"],
        }
    }

    /// What the quantity is, for messages.
    pub(super) fn describe(self) -> &'static str {
        match self {
            Quantity::SamplingFrequency => "sampling frequency (Hz)",
            Quantity::CenterFrequency => "centre frequency (Hz)",
            Quantity::SoundSpeed => "sound speed (m/s)",
            Quantity::Pitch => "element pitch (m)",
            Quantity::ElementWidth => "element width (m)",
            Quantity::ElementCount => "number of elements",
            Quantity::Angles => "transmit angles",
            Quantity::StartTime => "time of sample 0 (s)",
            Quantity::TransmitDelays => "transmit delays",
            Quantity::Bandwidth => "fractional bandwidth (%)",
            Quantity::Radius => "radius of curvature (m)",
        }
    }

    /// The spellings, for a message that says what was looked for.
    pub(super) fn looked_for(self) -> String {
        self.spellings().join(", ")
    }

    /// Whether `name` spells this quantity, and the angle unit its name states.
    fn matches(self, name: &str) -> Option<Option<AngleUnit>> {
        let n = normalise(name);
        if self.spellings().contains(&n.as_str()) {
            return Some(None);
        }
        if self != Quantity::Angles {
            return None;
        }
        for (suffix, unit) in [
            ("degrees", AngleUnit::Degrees),
            ("deg", AngleUnit::Degrees),
            ("radians", AngleUnit::Radians),
            ("rad", AngleUnit::Radians),
        ] {
            if let Some(stem) = n.strip_suffix(suffix) {
                if self.spellings().contains(&stem) {
                    return Some(Some(unit));
                }
            }
        }
        None
    }
}

/// Lower case, letters and digits only: `Sampling_Frequency` → `samplingfrequency`.
fn normalise(name: &str) -> String {
    name.chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .map(|c| c.to_ascii_lowercase())
        .collect()
}

/// One quantity as found in the file.
pub(super) struct Found<'a> {
    /// Where: `param1.fs`, or `fs` for a top-level variable.
    pub name: String,
    /// The value.
    pub value: &'a MatValue,
    /// The angle unit the name states, if any.
    pub unit: Option<AngleUnit>,
}

/// A quantity found as an array of numbers.
pub(super) struct Numbers {
    /// Where: `param1.TXangle`, or `theta` for a top-level variable.
    pub name: String,
    /// The numbers, column-major.
    pub values: Vec<f64>,
    /// The angle unit the name states, if any.
    pub unit: Option<AngleUnit>,
}

/// Where quantities are looked up: the parameter struct's fields first, then the
/// file's top-level variables.
pub(super) struct Params<'a> {
    /// The parameter struct's name, if the file has one.
    pub struct_name: Option<&'a str>,
    fields: Vec<(&'a str, &'a MatValue)>,
    top: Vec<(&'a str, &'a MatValue)>,
}

impl<'a> Params<'a> {
    /// The parameter struct is `forced` if given, else the 1×1 struct holding the
    /// most marker quantities (sampling frequency, sound speed, pitch, angles, …),
    /// the first in file order on a tie; none if no struct holds any.
    pub(super) fn find(vars: &'a MatFile, forced: Option<&str>) -> Result<Params<'a>, String> {
        let structs: Vec<(&str, &MatValue)> = vars
            .iter()
            .filter(|(_, v)| matches!(v, MatValue::Struct { elems, .. } if elems.len() == 1))
            .map(|(n, v)| (n.as_str(), v))
            .collect();
        let chosen = match forced {
            Some(name) => Some(
                structs
                    .iter()
                    .find(|(n, _)| *n == name)
                    .copied()
                    .ok_or_else(|| {
                        let names: Vec<&str> = structs.iter().map(|(n, _)| *n).collect();
                        format!("--param {name}: the file has no 1×1 struct of that name (its structs: {names:?})")
                    })?,
            ),
            None => {
                let score = |v: &MatValue| {
                    let fields = struct_fields(v);
                    Quantity::MARKERS
                        .iter()
                        .filter(|q| fields.iter().any(|(n, _)| q.matches(n).is_some()))
                        .count()
                };
                let mut best: Option<((&str, &MatValue), usize)> = None;
                for &s in &structs {
                    let k = score(s.1);
                    if k > 0 && best.is_none_or(|(_, b)| k > b) {
                        best = Some((s, k));
                    }
                }
                best.map(|(s, _)| s)
            }
        };
        Ok(Params {
            struct_name: chosen.map(|(n, _)| n),
            fields: chosen.map(|(_, v)| struct_fields(v)).unwrap_or_default(),
            top: vars.iter().map(|(n, v)| (n.as_str(), v)).collect(),
        })
    }

    /// The quantity `q`, from the parameter struct, else from a top-level variable.
    pub(super) fn get(&self, q: Quantity) -> Option<Found<'a>> {
        let prefix = self
            .struct_name
            .map(|s| format!("{s}."))
            .unwrap_or_default();
        let in_struct = self
            .fields
            .iter()
            .find_map(|(n, v)| q.matches(n).map(|u| (format!("{prefix}{n}"), *v, u)));
        let at_top = || {
            self.top
                .iter()
                .find_map(|(n, v)| q.matches(n).map(|u| (n.to_string(), *v, u)))
        };
        in_struct
            .or_else(at_top)
            .map(|(name, value, unit)| Found { name, value, unit })
    }

    /// The quantity `q` as a finite numeric scalar, with where it was found; an
    /// error if the file has it in another shape.
    pub(super) fn scalar(&self, q: Quantity) -> Result<Option<(String, f64)>, String> {
        let Some(f) = self.get(q) else {
            return Ok(None);
        };
        match f.value.scalar() {
            Some(v) if v.is_finite() => Ok(Some((f.name, v))),
            Some(v) => Err(format!("`{}` = {v} is not finite", f.name)),
            None => Err(format!(
                "`{}` ({}) is not a numeric scalar",
                f.name,
                q.describe()
            )),
        }
    }

    /// The quantity `q` as finite numbers (any shape, column-major), with where
    /// it was found and the unit its name states.
    pub(super) fn numbers(&self, q: Quantity) -> Result<Option<Numbers>, String> {
        let Some(f) = self.get(q) else {
            return Ok(None);
        };
        match f.value {
            MatValue::Numeric { re, im: None, .. } => {
                if let Some(v) = re.iter().find(|v| !v.is_finite()) {
                    return Err(format!("`{}` holds {v}, not a finite number", f.name));
                }
                Ok(Some(Numbers {
                    name: f.name,
                    values: re.clone(),
                    unit: f.unit,
                }))
            }
            _ => Err(format!(
                "`{}` ({}) is not a real numeric array",
                f.name,
                q.describe()
            )),
        }
    }
}

/// The fields of a 1×1 struct as `(name, value)`; empty for anything else.
fn struct_fields(v: &MatValue) -> Vec<(&str, &MatValue)> {
    match v {
        MatValue::Struct { fields, elems, .. } if elems.len() == 1 => fields
            .iter()
            .map(String::as_str)
            .zip(elems[0].iter())
            .collect(),
        _ => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spellings_match_across_conventions() {
        assert!(Quantity::SamplingFrequency.matches("Fs").is_some());
        assert!(Quantity::SamplingFrequency
            .matches("sampling_frequency")
            .is_some());
        assert!(Quantity::SoundSpeed.matches("c0").is_some());
        assert!(Quantity::SoundSpeed.matches("fs").is_none());
        assert_eq!(
            Quantity::Angles.matches("TXangle_deg"),
            Some(Some(AngleUnit::Degrees))
        );
        assert_eq!(
            Quantity::Angles.matches("anglesRad"),
            Some(Some(AngleUnit::Radians))
        );
        assert_eq!(Quantity::Angles.matches("TXangle"), Some(None));
        assert!(Quantity::Pitch.matches("pitch_deg").is_none());
    }
}
