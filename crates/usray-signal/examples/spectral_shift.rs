//! The spectral shift of measured channel data against a model's: each echo's
//! centre frequency in both, and the attenuation beyond the model's that the
//! difference's trend along the path implies ([`usray_signal::spectral_shift()`]).
//!
//! ```text
//! cargo run --release -p usray-signal --example spectral_shift -- MEASURED.json MODEL.json
//! ```
//!
//! MODEL is typically `usray render SCENE --out DIR`'s `DIR/channels.json`.
//! The sound speed and the centre frequency are the measured file's
//! (`sound_speed_m_s`, `center_frequency_hz`); `--speed M_S` and
//! `--centre HZ` set others. Prints one line per echo, then the fit.

use std::process::ExitCode;
use usray_signal::{read_channels, spectral_shift, SpectralShiftOptions};

fn main() -> ExitCode {
    match run(std::env::args().skip(1).collect()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("spectral_shift: {e}");
            ExitCode::from(2)
        }
    }
}

fn run(args: Vec<String>) -> Result<(), String> {
    let usage = "usage: spectral_shift MEASURED.json MODEL.json [--speed M_S] [--centre HZ]";
    let mut files = Vec::new();
    let (mut speed, mut centre) = (None, None);
    let mut it = args.into_iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| -> Result<f64, String> {
            let v = it.next().ok_or(format!("{name} needs a value; {usage}"))?;
            v.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite() && *x > 0.0)
                .ok_or(format!("{name} must be a positive number, got {v:?}"))
        };
        match a.as_str() {
            "--speed" => speed = Some(value("--speed")?),
            "--centre" => centre = Some(value("--centre")?),
            _ if a.starts_with("--") => return Err(format!("unknown option {a}; {usage}")),
            _ => files.push(a),
        }
    }
    let [measured, model] = files.as_slice() else {
        return Err(usage.to_string());
    };
    let measured = read_channels(measured).map_err(|e| e.to_string())?;
    let model = read_channels(model).map_err(|e| e.to_string())?;
    let c = speed.unwrap_or(measured.meta.sound_speed_m_s);
    let f_c = centre.unwrap_or(measured.meta.center_frequency_hz);
    let shift = spectral_shift(&measured, &model, c, f_c, &SpectralShiftOptions::default())
        .map_err(|e| e.to_string())?;
    println!("transmit  path (mm)  weight  measured (MHz)  model (MHz)");
    for e in &shift.echoes {
        println!(
            "{:>8}  {:>9.2}  {:>6.3}  {:>14.4}  {:>11.4}",
            e.transmit,
            e.path_m * 1e3,
            e.weight,
            e.measured_hz * 1e-6,
            e.model_hz * 1e-6
        );
    }
    let se = |s: Option<f64>| s.map_or("(no standard error)".to_string(), |s| format!("± {s:.3}"));
    println!(
        "offset {:+.4} {} MHz; slope {:+.4} MHz per cm of path; attenuation beyond the model's {:+.3} {} dB/(cm·MHz){}",
        shift.offset_hz * 1e-6,
        se(shift.offset_std.map(|s| s * 1e-6)),
        shift.slope_hz_per_m * 1e-8,
        shift.attenuation_db_cm_mhz,
        se(shift.attenuation_std),
        shift
            .attenuation_z()
            .map_or(String::new(), |z| format!(", {z:+.1} standard errors"))
    );
    Ok(())
}
