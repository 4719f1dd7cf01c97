//! What an importer infers from the samples themselves: the offset of integer
//! samples, and the centre frequency when the file does not store it.

use crate::mat::NumericClass;
use rustfft::num_complex::Complex64;
use rustfft::FftPlanner;

/// The offset subtracted from samples stored as `class`, and why: unsigned
/// integers are taken as centred at mid-range (`2^(bits−1)`: 128 for `uint8`,
/// a common export of signed RF), signed integers and floats as centred at 0.
/// `forced` (the user's `--offset`) wins.
pub(super) fn integer_offset(class: NumericClass, forced: Option<f64>) -> (f64, String) {
    if let Some(o) = forced {
        return (o, format!("offset {o} subtracted (--offset)"));
    }
    match class.integer_range() {
        Some((0.0, hi)) => {
            let mid = (hi + 1.0) / 2.0;
            (
                mid,
                format!(
                    "{} samples taken as centred at mid-range: {mid} subtracted (pass --offset to change)",
                    class.name()
                ),
            )
        }
        _ => (0.0, format!("{} samples used as stored", class.name())),
    }
}

/// A note when the samples' mean sits far from the offset (more than a quarter
/// of the class's range): the offset is then probably wrong.
pub(super) fn offset_warning(values: &[f64], class: NumericClass, offset: f64) -> Option<String> {
    let (lo, hi) = class.integer_range()?;
    if values.is_empty() {
        return None;
    }
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    ((mean - offset).abs() > 0.25 * (hi - lo)).then(|| {
        format!("the samples' mean is {mean:.1}, far from the offset {offset}: check --offset")
    })
}

/// The centre frequency of RF records (`n_samples` each, C order) sampled at
/// `fs_hz`: the middle of the −6 dB band around the peak of the mean power
/// spectrum (records' means removed; up to 64 records, evenly spread). The band's
/// middle, not the spectral centroid, so a flat noise floor (quantised `uint8`
/// samples) does not pull the estimate toward `fs/4`. `None` for silent data.
pub(super) fn estimate_center_frequency(
    samples: &[f64],
    n_samples: usize,
    fs_hz: f64,
) -> Option<f64> {
    let n_records = samples.len().checked_div(n_samples)?;
    if n_samples < 8 || n_records == 0 {
        return None;
    }
    let fft = FftPlanner::new().plan_fft_forward(n_samples);
    let half = n_samples / 2;
    let mut power = vec![0.0; half + 1];
    let take = n_records.min(64);
    let mut buf = vec![Complex64::new(0.0, 0.0); n_samples];
    for i in 0..take {
        let r = i * n_records / take;
        let rec = &samples[r * n_samples..(r + 1) * n_samples];
        let mean = rec.iter().sum::<f64>() / n_samples as f64;
        for (b, &v) in buf.iter_mut().zip(rec) {
            *b = Complex64::new(v - mean, 0.0);
        }
        fft.process(&mut buf);
        for (p, b) in power.iter_mut().zip(&buf) {
            *p += b.norm_sqr();
        }
    }
    // Smooth over about 1/64 of the band, so one noisy bin neither makes the
    // peak nor ends the band early.
    let w = (half / 64).max(1);
    let smooth: Vec<f64> = (0..=half)
        .map(|k| {
            let (a, b) = (k.saturating_sub(w), (k + w).min(half));
            power[a..=b].iter().sum::<f64>() / (b - a + 1) as f64
        })
        .collect();
    let (peak, &top) = smooth
        .iter()
        .enumerate()
        .skip(1)
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    if top <= 0.0 {
        return None;
    }
    let inside = |k: usize| smooth[k] >= top / 4.0;
    let mut lo = peak;
    while lo > 1 && inside(lo - 1) {
        lo -= 1;
    }
    let mut hi = peak;
    while hi < half && inside(hi + 1) {
        hi += 1;
    }
    Some((lo + hi) as f64 / 2.0 * fs_hz / n_samples as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unsigned_samples_are_centred_at_mid_range() {
        assert_eq!(integer_offset(NumericClass::UInt8, None).0, 128.0);
        assert_eq!(integer_offset(NumericClass::UInt16, None).0, 32768.0);
        assert_eq!(integer_offset(NumericClass::Int16, None).0, 0.0);
        assert_eq!(integer_offset(NumericClass::Single, None).0, 0.0);
        assert_eq!(integer_offset(NumericClass::UInt8, Some(0.0)).0, 0.0);
        assert!(offset_warning(&[10.0, 12.0], NumericClass::UInt8, 128.0).is_some());
        assert!(offset_warning(&[120.0, 136.0], NumericClass::UInt8, 128.0).is_none());
    }

    #[test]
    fn centre_frequency_of_a_gaussian_pulse_with_noise() {
        // 5 MHz Gaussian-windowed bursts at 40 MHz, 60 % bandwidth, plus white
        // noise at 10 % of the peak; the estimate lands within 3 % of 5 MHz.
        let (fs, fc, ns) = (40e6, 5e6, 1024);
        let mut state = 12345u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let sigma_t = 1.0 / (std::f64::consts::PI * 0.6 * fc / 2.355);
        let mut x = Vec::new();
        for r in 0..16 {
            let t0 = 5e-6 + r as f64 * 0.3e-6;
            x.extend((0..ns).map(|n| {
                let t = n as f64 / fs - t0;
                (-(t * t) / (2.0 * sigma_t * sigma_t)).exp()
                    * (2.0 * std::f64::consts::PI * fc * t).cos()
                    + 0.2 * noise()
            }));
        }
        let est = estimate_center_frequency(&x, ns, fs).unwrap();
        assert!((est - fc).abs() < 0.03 * fc, "{est}");
        assert!(estimate_center_frequency(&vec![0.0; 64], 32, fs).is_none());
    }
}
