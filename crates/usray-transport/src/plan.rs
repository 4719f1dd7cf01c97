//! The acquisition plan: what a scene's acquisition *is* — its elements, its
//! transmits, the sample grid of its records and its pulse with the
//! down-shift basis — derived once from the [`Scene`] and passed to the
//! render, the gradient and the channel metadata, so that none of them
//! re-derives it.
//!
//! The plan holds values (`f64`). The tracer, which differentiates element
//! positions and transmit delays, evaluates the same formulas in `T` from the
//! lifted scene: each formula exists once, in `usray_signal`
//! ([`ArrayGeometry::element`] for element centres and normals,
//! [`TransmitWave::element_delay_s`] for the firing times), and the plan's
//! values are those formulas at the scene's values
//! ([`Scene::array_geometry`], [`Scene::transmit_waves`]).
//!
//! # The sample grid
//! `t0_s = 0` on the clock of CONTRACT §1 (sample 0 is the instant the
//! wavefront passes the probe-frame origin); `n_samples = ⌈f_s·(2·max_depth/c +
//! max_{e,tx} |t_tx(e)| + 4√σ)⌉ + 1` with `c` the imaging speed (the scanner's
//! record length), `t_tx(e)` element `e`'s firing time in transmit `tx`
//! (plane waves: `x_e sin θ/c`) and `4√σ` the pulse half-support
//! ([`usray_signal::pulse::pulse_support_s`]). Echoes that arrive before
//! `t = 0` (near-field, negative `x·sin θ`) are cut.

use crate::scene::Scene;
use usray_ad::{Dual, Real};
use usray_signal::array::ArrayGeometry;
use usray_signal::transmit::TransmitWave;
use usray_signal::{ChannelMeta, ProbeMeta, TransmitMeta};

/// One element of the array in the imaging plane (CONTRACT §1 frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element {
    /// Centre `(x, z)`, metres.
    pub position_m: [f64; 2],
    /// Unit normal `(x, z)` of the face, pointing into the medium.
    pub normal: [f64; 2],
}

/// One transmit (one record per element).
#[derive(Clone, Debug, PartialEq)]
pub struct Transmit {
    /// The wave, whose arrival time at an element is that element's firing
    /// time ([`TransmitWave::element_delay_s`]).
    pub wave: TransmitWave<f64>,
    /// Its entry in the channel metadata (CONTRACT §2).
    meta: TransmitMeta,
}

impl Transmit {
    /// The firing time (s) of `element` with `c` the speed the scanner assumes.
    pub fn delay_s(&self, element: &Element, c: f64) -> f64 {
        self.wave.element_delay_s(element.position_m, c)
    }
}

/// The sample grid of every record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleGrid {
    /// Samples per record.
    pub n_samples: usize,
    /// Time of sample 0, s (CONTRACT §1 clock).
    pub t0_s: f64,
    /// Sampling frequency, Hz.
    pub fs_hz: f64,
}

/// The pulse (`usray_signal::pulse`, paper eq. `axial_sig`) and what the
/// down-shift of attenuated echoes needs of it ([`crate::downshift`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PulsePlan {
    /// Centre frequency `f_c`, Hz.
    pub center_frequency_hz: f64,
    /// Cycles (envelope FWHM = `cycles/f_c`).
    pub cycles: f64,
    /// Down-shift nodes when nothing is differentiated: 1 (the plain pulse)
    /// without attenuation ([`crate::downshift::node_count`]).
    shift_nodes: usize,
}

impl PulsePlan {
    /// The down-shift nodes of a render or gradient: [`crate::downshift::node_count`]
    /// for this scene; `differentiated` (an attenuation is differentiated, or
    /// the render carries derivatives) asks for at least 2 (the slope `∂p/∂s`
    /// at `s = 0`).
    ///
    /// ```
    /// # let text = include_str!("../../../scenes/cylinder.toml");
    /// # let mut scene = usray_transport::Scene::from_toml_str(text, "cylinder.toml", ".").unwrap();
    /// use usray_transport::plan::AcquisitionPlan;
    /// let nodes = |s: &usray_transport::Scene, d| AcquisitionPlan::new(s).pulse.nodes(d);
    /// assert_eq!(nodes(&scene, false), 1);
    /// assert_eq!(nodes(&scene, true), 2);
    /// let alpha = usray_transport::ParamKey::medium(usray_transport::Field::Attenuation);
    /// scene.set(&alpha, 1.0).unwrap();
    /// assert!(nodes(&scene, false) >= 2);
    /// // 100 dB/(cm·MHz): capped at a shift of f_c/2 (4 σ_f for 3 cycles).
    /// scene.set(&alpha, 100.0).unwrap();
    /// assert_eq!(nodes(&scene, false), 10);
    /// ```
    pub fn nodes(&self, differentiated: bool) -> usize {
        if differentiated {
            self.shift_nodes.max(2)
        } else {
            self.shift_nodes
        }
    }

    /// The taps of the records of `nodes` down-shift nodes sampled at `fs`:
    /// the plain pulse for one node ([`usray_signal::pulse::pulse_taps`]),
    /// else the value and slope records of each node
    /// ([`crate::downshift::node_taps`]).
    pub fn taps(&self, fs: f64, nodes: usize) -> Vec<Vec<f64>> {
        let (fc, cycles) = (self.center_frequency_hz, self.cycles);
        if nodes == 1 {
            vec![usray_signal::pulse::pulse_taps(fs, fc, cycles)]
        } else {
            crate::downshift::node_taps(fs, fc, cycles, nodes)
        }
    }

    /// `[∂taps/∂f_c, ∂taps/∂cycles]` of each record of [`PulsePlan::taps`]
    /// (per Hz and per cycle), by forward duals through
    /// [`usray_signal::pulse::shifted_pulse`] and its slope in `s`: the
    /// pulse-shape terms of the gradient (`crate::gradient`, step 3).
    pub fn shape_derivative_taps(&self, fs: f64, nodes: usize) -> Vec<[Vec<f64>; 2]> {
        let (fc, cycles) = (self.center_frequency_hz, self.cycles);
        let mut d = crate::downshift::node_taps_with(fs, fc, cycles, nodes, |t, s, slope| {
            let (t, f, c) = (
                Dual::<2>::from_f64(t),
                Dual::variable(fc, 0),
                Dual::variable(cycles, 1),
            );
            if slope {
                usray_signal::pulse::shifted_pulse_ds(t, f, c, s).eps
            } else {
                usray_signal::pulse::shifted_pulse(t, f, c, s).eps
            }
        });
        // One record for the plain pulse (the value of node 0).
        d.truncate(if nodes == 1 { 1 } else { 2 * nodes });
        d.into_iter()
            .map(|r| [0, 1].map(|m| r.iter().map(|e| e[m]).collect()))
            .collect()
    }
}

/// The acquisition of a scene, derived once (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct AcquisitionPlan {
    /// The elements in index order.
    pub elements: Vec<Element>,
    /// The transmits in acquisition order.
    pub transmits: Vec<Transmit>,
    /// The records' sample grid.
    pub grid: SampleGrid,
    /// The pulse and its down-shift basis.
    pub pulse: PulsePlan,
    /// The speed the scanner assumes (transmit delays, record length), m/s.
    pub imaging_sound_speed_m_s: f64,
    /// The probe as the channel metadata describes it.
    probe: ProbeMeta,
    /// Traced in 2-D (`acquisition.dimensions = 2`): the channel metadata say so.
    planar: bool,
}

impl AcquisitionPlan {
    /// The plan of a (validated) scene.
    ///
    /// ```
    /// # let text = include_str!("../../../scenes/cylinder.toml");
    /// # let scene = usray_transport::Scene::from_toml_str(text, "cylinder.toml", ".").unwrap();
    /// use usray_transport::plan::AcquisitionPlan;
    /// let plan = AcquisitionPlan::new(&scene);
    /// assert_eq!(plan.elements.len(), 128);
    /// assert_eq!(plan.elements[0].position_m, [-63.5 * 0.3e-3, 0.0]);
    /// assert_eq!(plan.transmits.len(), 5);
    /// assert_eq!(plan.grid.t0_s, 0.0);
    /// ```
    pub fn new(scene: &Scene) -> Self {
        let (p, a) = (&scene.probe, &scene.acquisition);
        let (elements, transmits) = layout(scene);
        let c = scene.imaging_sound_speed();
        let fs = a.sampling_frequency_hz;
        let (fc, cycles) = (p.center_frequency_hz, p.cycles);
        let max_delay = max_transmit_delay_s(&elements, &transmits, c);
        let n_samples = (record_duration_s_of(scene, max_delay) * fs).ceil() as usize + 1;
        let grid = SampleGrid {
            n_samples,
            t0_s: 0.0,
            fs_hz: fs,
        };
        // The latest instant a kept deposit can carry: the records' end plus
        // the earliest firing (`downshift::node_count`).
        let t_end = grid.t0_s + n_samples as f64 / fs + max_delay;
        let (alpha_max, c_max) = attenuation_bound(scene);
        let shift_nodes = crate::downshift::node_count(alpha_max, c_max, t_end, fc, cycles);
        AcquisitionPlan {
            elements,
            transmits,
            grid,
            pulse: PulsePlan {
                center_frequency_hz: fc,
                cycles,
                shift_nodes,
            },
            imaging_sound_speed_m_s: c,
            probe: scene.probe_meta(),
            planar: a.is_planar(),
        }
    }

    /// Number of samples of the channel data, `n_tx · n_el · n_samples`.
    pub fn channel_len(&self) -> usize {
        self.transmits.len() * self.elements.len() * self.grid.n_samples
    }

    /// The channel-data metadata (CONTRACT §2), with `"dimensions": 2` for a
    /// 2-D scene (data that declare their dimensions are traced in them when
    /// they are compared with a scene that leaves its own unset).
    pub fn channel_meta(&self) -> ChannelMeta {
        let mut extra = serde_json::Map::new();
        if self.planar {
            extra.insert("dimensions".into(), 2.into());
        }
        ChannelMeta {
            format: usray_signal::channels::CHANNELS_FORMAT.to_string(),
            sampling_frequency_hz: self.grid.fs_hz,
            t0_s: self.grid.t0_s,
            sound_speed_m_s: self.imaging_sound_speed_m_s,
            center_frequency_hz: self.pulse.center_frequency_hz,
            probe: self.probe.clone(),
            transmits: self.transmits.iter().map(|t| t.meta.clone()).collect(),
            extra,
        }
    }
}

/// The elements ([`ArrayGeometry::element`], the one formula) and the
/// transmits of a scene.
fn layout(scene: &Scene) -> (Vec<Element>, Vec<Transmit>) {
    let array: ArrayGeometry<f64> = scene.array_geometry();
    let elements = array
        .elements()
        .into_iter()
        .map(|e| Element {
            position_m: e.centre_m,
            normal: e.normal,
        })
        .collect();
    let transmits = scene
        .transmit_waves()
        .into_iter()
        .zip(scene.transmit_metas())
        .map(|(wave, meta)| Transmit { wave, meta })
        .collect();
    (elements, transmits)
}

/// Length of one channel record of a scene, s (module docs). Scene validation
/// bounds the channel data's size with it (after bounding the element and
/// transmit counts).
pub(crate) fn record_duration_s(scene: &Scene) -> f64 {
    let (elements, transmits) = layout(scene);
    let c = scene.imaging_sound_speed();
    record_duration_s_of(scene, max_transmit_delay_s(&elements, &transmits, c))
}

/// The round trip to `max_depth_m` at the imaging speed, the largest transmit
/// delay `max_delay_s` and the pulse's support, s.
fn record_duration_s_of(scene: &Scene, max_delay_s: f64) -> f64 {
    let c = scene.imaging_sound_speed();
    let support =
        usray_signal::pulse::pulse_support_s(scene.probe.center_frequency_hz, scene.probe.cycles);
    2.0 * scene.acquisition.max_depth_m / c + max_delay_s + support
}

/// The largest `|delay|` of any element in any transmit, s, with `c` the
/// imaging speed (plane waves: `max_e |x_e sin θ| / c`, the outermost
/// elements).
fn max_transmit_delay_s(elements: &[Element], transmits: &[Transmit], c: f64) -> f64 {
    transmits
        .iter()
        .flat_map(|t| elements.iter().map(|e| t.delay_s(e, c).abs()))
        .fold(0.0, f64::max)
}

/// The largest attenuation (dB/(cm·MHz)) and sound speed (m/s) of the
/// scene's media: the background and every material.
fn attenuation_bound(scene: &Scene) -> (f64, f64) {
    let media = std::iter::once((
        scene.medium.attenuation_db_cm_mhz,
        scene.medium.sound_speed_m_s,
    ))
    .chain(
        scene
            .materials
            .values()
            .map(|m| (m.attenuation_db_cm_mhz, m.sound_speed_m_s)),
    );
    let (mut alpha_max, mut c_max) = (0.0_f64, 0.0_f64);
    for (a, c) in media {
        alpha_max = alpha_max.max(a);
        c_max = c_max.max(c);
    }
    (alpha_max, c_max)
}
