//! Shared helpers of the crate's tests.
#![allow(dead_code)]

pub mod probes;
pub mod pymust;

use usray_signal::{post, BMode, ChannelData, ChannelMeta, Complex64, ImagingSettings};

/// A small deterministic generator (SplitMix64), uniform in [−1, 1).
pub struct Rng(pub u64);
impl Rng {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
    pub fn vec(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.next()).collect()
    }
    pub fn cvec(&mut self, n: usize) -> Vec<Complex64> {
        (0..n)
            .map(|_| Complex64::new(self.next(), self.next()))
            .collect()
    }
}

/// Channel metadata: `ne` elements at 0.3 mm, fs, fc, the given angles and t0s.
pub fn meta(ne: usize, fs: f64, fc: f64, angles: &[f64], t0s: &[f64]) -> ChannelMeta {
    let transmits: Vec<serde_json::Value> = angles
        .iter()
        .zip(t0s)
        .map(|(a, t)| serde_json::json!({"kind": "plane_wave", "angle_rad": a, "t0_s": t}))
        .collect();
    serde_json::from_value(serde_json::json!({
        "format": "usray-channels/1", "sampling_frequency_hz": fs, "t0_s": 0.0,
        "sound_speed_m_s": 1540.0, "center_frequency_hz": fc,
        "probe": {"kind": "linear", "n_elements": ne, "pitch_m": 0.3e-3, "element_width_m": 0.27e-3,
                  "bandwidth_percent": 70.0},
        "transmits": transmits
    }))
    .unwrap()
}

pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
pub fn cdot(a: &[Complex64], b: &[Complex64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.re * y.re + x.im * y.im)
        .sum()
}
pub fn norm2(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}
pub const EPS: f64 = f64::EPSILON;

// ---- MAT v5 files built byte by byte (MathWorks, "MAT-File Format", ch. 1) ----

/// A data element: type, byte count, data, padded to 8 bytes.
pub fn tag(ty: u32, data: &[u8]) -> Vec<u8> {
    let mut v = ty.to_le_bytes().to_vec();
    v.extend((data.len() as u32).to_le_bytes());
    v.extend(data);
    while v.len() % 8 != 0 {
        v.push(0);
    }
    v
}
/// An `miMATRIX` of `class` with `dims`, `name` and `body`.
pub fn matrix(name: &str, class: u8, dims: &[i32], body: Vec<u8>) -> Vec<u8> {
    let mut m = tag(6, &[class, 0, 0, 0, 0, 0, 0, 0]);
    m.extend(tag(
        5,
        &dims
            .iter()
            .flat_map(|d| d.to_le_bytes())
            .collect::<Vec<u8>>(),
    ));
    m.extend(tag(1, name.as_bytes()));
    m.extend(body);
    tag(14, &m)
}
/// A `double` array.
pub fn double(name: &str, dims: &[i32], vals: &[f64]) -> Vec<u8> {
    matrix(
        name,
        6,
        dims,
        tag(
            9,
            &vals
                .iter()
                .flat_map(|d| d.to_le_bytes())
                .collect::<Vec<u8>>(),
        ),
    )
}
/// An `int16` array.
pub fn int16(name: &str, dims: &[i32], vals: &[i16]) -> Vec<u8> {
    matrix(
        name,
        10,
        dims,
        tag(
            3,
            &vals
                .iter()
                .flat_map(|d| d.to_le_bytes())
                .collect::<Vec<u8>>(),
        ),
    )
}
/// A 1×1 struct of `fields`.
pub fn structure(name: &str, fields: &[(&str, Vec<u8>)]) -> Vec<u8> {
    let names: Vec<&str> = fields.iter().map(|(f, _)| *f).collect();
    let values: Vec<Vec<u8>> = fields.iter().map(|(_, v)| v.clone()).collect();
    struct_array(name, &names, &[values])
}
/// A 1×n struct array with fields `names`, `elems[i]` element i's values.
pub fn struct_array(name: &str, names: &[&str], elems: &[Vec<Vec<u8>>]) -> Vec<u8> {
    let mut body = tag(5, &32i32.to_le_bytes());
    let mut packed = vec![];
    for f in names {
        let mut b = f.as_bytes().to_vec();
        b.resize(32, 0);
        packed.extend(b);
    }
    body.extend(tag(1, &packed));
    for e in elems {
        for v in e {
            body.extend(v.clone());
        }
    }
    matrix(name, 2, &[1, elems.len() as i32], body)
}
/// A MAT v5 file of `vars`.
pub fn mat_file(vars: &[Vec<u8>]) -> Vec<u8> {
    let mut h = b"MATLAB 5.0 MAT-file, test".to_vec();
    h.resize(116, b' ');
    h.extend([0u8; 8]);
    h.extend([0x00, 0x01, b'I', b'M']);
    for v in vars {
        h.extend(v);
    }
    h
}

/// Relative difference `|a − b| / max(|a|, |b|)`.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-300)
}

/// The B-mode's calibration gradients of the loss `L = ⟨B, w⟩` (`w` random) in the
/// beamformer's sound speed and the probe's pitch, at 1540 m/s and 0.3 mm, against
/// central differences (steps 1e-5 m/s and 1e-11 m, small enough that the brightest
/// pixel, which sets the normalisation, stays put: asserted). Returns
/// `[(fd, analytic); 2]`, sound speed first.
pub fn calibration_against_fd(ch: &ChannelData, s: &ImagingSettings) -> [(f64, f64); 2] {
    let build = |c: f64, pitch: f64| {
        let mut s2 = s.clone();
        s2.sound_speed_m_s = Some(c);
        let mut m = ch.meta.clone();
        m.probe.pitch_m = pitch;
        (BMode::new(&s2, &m, ch.n_samples).unwrap(), m)
    };
    let (b, _) = build(1540.0, 0.3e-3);
    let mut ws = b.workspace();
    let img = b.forward(ch, &mut ws).unwrap();
    let q = post::argmax(ws.envelope());
    let w = Rng(21).vec(img.data.len());
    let g = b.calibration_vjp(&mut ws, &w).unwrap();
    let loss = |c: f64, p: f64| {
        let (b2, m) = build(c, p);
        let c2 = ChannelData {
            meta: m,
            ..ch.clone()
        };
        let mut ws2 = b2.workspace();
        let im = b2.forward(&c2, &mut ws2).unwrap();
        assert_eq!(post::argmax(ws2.envelope()), q, "arg-max moved");
        dot(&im.data, &w)
    };
    let (hc, hp) = (1e-5, 1e-11);
    let fdc = (loss(1540.0 + hc, 0.3e-3) - loss(1540.0 - hc, 0.3e-3)) / (2.0 * hc);
    let fdp = (loss(1540.0, 0.3e-3 + hp) - loss(1540.0, 0.3e-3 - hp)) / (2.0 * hp);
    [(fdc, g.d_sound_speed), (fdp, g.d_pitch)]
}
