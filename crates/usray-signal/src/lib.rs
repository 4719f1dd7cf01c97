//! # usray-signal
//!
//! Ultrasound image formation with adjoints. Every operator that turns channel data
//! (CONTRACT §2) into a B-mode image has a forward and a vector-Jacobian product
//! (VJP), so image-space losses can be pulled back to the channel data the ray
//! tracer produced (paper §"Differentiating through beamforming and
//! post-processing"):
//!
//! | module | operator |
//! |---|---|
//! | [`array`](mod@array) | element centres and normals of linear, phased and convex arrays |
//! | [`transmit`] | plane, diverging and focused waves: delay laws and arrival times |
//! | [`pulse`] | transmit pulse `s(t)` (paper eq. `axial_sig`), its derivative, convolution |
//! | [`gain`] | depth-gain (time-gain) compensation |
//! | [`filter`] | Butterworth low-/band-pass, zero-phase forward–backward |
//! | [`demod`] | IQ demodulation at `f_c`, Hilbert analytic signal |
//! | [`das`] | delay-and-sum (paper eq. `das`) for any array and transmit, back-projection (eq. `das_adjoint`), calibration gradients (`c`, pitch) |
//! | [`grid`] | polar sector grids of phased and convex probes, bilinear scan conversion and its VJP |
//! | [`imaging`] | imaging settings: grid, aperture, dynamic range, demodulation |
//! | [`post`] | envelope, `20 log10`, normalisation, dynamic-range clip |
//! | [`bmode`] | the composed operator `B` with one forward and one VJP call |
//! | [`io`] | channel data and B-mode files, [`write_atomic`] |
//! | [`mat`] | MATLAB `.mat` reader (v5 here, v7.3/HDF5 in a private module) and Verasonics plane-wave import |
//! | [`uff`] | UFF (USTB, PICMUS) plane-wave channel data: import and export |
//! | [`spectral_shift`](mod@spectral_shift) | the echoes' mean frequency, measured against a model's, along their path: the spectral-shift estimate of attenuation |
//!
//! ## Frames: the `frame` key (extension of CONTRACT §2)
//!
//! Each entry of `transmits` may carry an extra key `"frame": k` (a non-negative
//! integer) naming the acquisition the transmit belongs to. [`BMode`] sums the
//! transmits of one frame coherently (delay-and-sum), takes the envelope of each
//! frame, and averages the envelopes over frames (incoherent mean) before log
//! compression; its VJP differentiates exactly that. Frames are for acquisitions
//! that must not be summed coherently, e.g. successive shots of a moving object:
//! [`import_mat`] tags the frames of a Verasonics `RF(time, element, frame)` array
//! `frame` 0, 1, …, so `PWI_disk.mat` (a rotating disk, 32 shots) is imaged as 32
//! frames. Either every transmit carries `frame` or none does
//! ([`ChannelMeta::frames`] and [`read_channels`] reject a mix or a non-integer);
//! data without `frame` keys is one frame, all transmits compounded coherently.
//! One delay-and-sum pass forms every frame's coherent image at once
//! ([`das::Das::frame_of`], output `[nz, nx, n_frames]`), so 32 one-transmit
//! frames cost about as much as one 32-transmit frame.
//!
//! ## Errors, not panics
//!
//! Every function that takes user data returns [`Result`]: in particular
//! [`BMode::forward`], [`BMode::vjp`], [`BMode::vjp_into`] and
//! [`BMode::calibration_vjp`] report channel data of another shape than the
//! operator was built for (both shapes in the message), cotangents of the wrong
//! length, a workspace of another operator and a VJP before any forward pass. The
//! low-level [`das::Das`] methods take caller-sized buffers and document their
//! panics on length mismatches (programming errors); `BMode` checks before calling them.
//!
//! ```
//! use usray_signal::{BMode, ChannelData, ChannelMeta, ImagingSettings};
//! // One point scatterer at (0, 10 mm), 0° plane wave, 32 elements, 40 MHz sampling.
//! let meta: ChannelMeta = serde_json::from_value(serde_json::json!({
//!     "format": "usray-channels/1", "sampling_frequency_hz": 40e6, "t0_s": 0.0,
//!     "sound_speed_m_s": 1540.0, "center_frequency_hz": 5e6,
//!     "probe": {"kind": "linear", "n_elements": 32, "pitch_m": 0.3e-3, "element_width_m": 0.27e-3},
//!     "transmits": [{"kind": "plane_wave", "angle_rad": 0.0}]
//! })).unwrap();
//! let ns = 800;
//! let mut samples = vec![0.0; 32 * ns];
//! for e in 0..32 {
//!     let xe = (e as f64 - 15.5) * 0.3e-3;
//!     let tof = (0.01 + (xe * xe + 0.01 * 0.01_f64).sqrt()) / 1540.0;
//!     for k in 0..ns {
//!         samples[e * ns + k] = usray_signal::pulse::pulse(k as f64 / 40e6 - tof, 5e6, 3.0);
//!     }
//! }
//! let ch = ChannelData { meta, n_samples: ns, samples };
//! let mut s = ImagingSettings::new([-2e-3, 2e-3], [8e-3, 12e-3], 0.1e-3);
//! s.f_number = 0.0;
//! let b = BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
//! let mut ws = b.workspace();
//! let img = b.forward(&ch, &mut ws).unwrap();
//! // The brightest pixel is the scatterer.
//! let k = usray_signal::post::argmax(&img.data);
//! assert!((img.x_m[k % img.nx]).abs() < 0.15e-3 && (img.z_m[k / img.nx] - 0.01).abs() < 0.15e-3);
//! // Gradient of a loss (sum of the image) with respect to the channel data.
//! let g = b.vjp(&mut ws, &vec![1.0; img.data.len()]).unwrap();
//! assert_eq!(g.len(), ch.samples.len());
//! ```
pub mod array;
pub mod bmode;
pub mod channels;
pub mod das;
pub mod demod;
pub mod error;
pub mod filter;
pub mod gain;
pub mod grid;
mod h5;
pub mod imaging;
pub mod import;
pub mod io;
pub mod mat;
mod mat73;
pub mod post;
pub mod pulse;
pub mod spectral_shift;
pub mod transmit;
pub mod uff;

pub use bmode::{BMode, Demod, Image, ImagingSettings, Workspace};
pub use channels::{ChannelData, ChannelMeta, ProbeMeta, TransmitMeta};
pub use error::{Result, SignalError};
pub use import::{import_mat, import_mat_with, ImportOptions};
pub use io::{read_channels, write_atomic, write_channels};
/// Complex sample type used for IQ and analytic data (re-exported from `rustfft`).
pub use rustfft::num_complex::Complex64;
pub use spectral_shift::{spectral_shift, EchoSpectrum, SpectralShift, SpectralShiftOptions};
pub use uff::{export_uff, import_uff, import_uff_with};
