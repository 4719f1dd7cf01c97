//! Delay-and-sum throughput on the PyMUST point data (251 × 301 pixels, 128
//! elements, 3 plane waves), forward and VJP, on a rayon pool of 1 thread and of
//! all cores. Throughput counts pixel·element·transmit samples per second. Median
//! of several repeats. Run: `cargo bench -p usray-signal --bench das`.

use std::time::Instant;

use usray_signal::das::Das;
use usray_signal::demod::IqDemod;
use usray_signal::{BMode, Complex64, Demod, ImagingSettings};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time<F: FnMut()>(repeats: usize, mut f: F) -> f64 {
    f(); // warm-up
    median(
        (0..repeats)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

fn main() {
    let Some(path) = usray_testdata::data_file("peers/points.json") else {
        eprintln!("points data not found; nothing to benchmark");
        return;
    };
    let ch = usray_signal::read_channels(path).unwrap();
    let mut s = ImagingSettings::new([-12.5e-3, 12.5e-3], [5e-3, 35e-3], 0.1e-3);
    s.f_number = 0.0;
    s.demod = Demod::Iq;
    let b = BMode::new(&s, &ch.meta, ch.n_samples).unwrap();
    let das: &Das = &b.das;
    let (nz, nx) = das.image_shape();
    let work = (nz * nx * das.n_elements * das.n_transmits()) as f64;
    // IQ data once.
    let (fc, fs, ns) = (
        ch.meta.center_frequency_hz,
        ch.meta.sampling_frequency_hz,
        ch.n_samples,
    );
    let d = IqDemod::new(fc, fs, 0.77 * fc / 2.0, 5).unwrap();
    let mut iq = vec![Complex64::new(0.0, 0.0); ch.samples.len()];
    for (rec, o) in iq.chunks_mut(ns).enumerate() {
        d.forward(
            &ch.samples[rec * ns..(rec + 1) * ns],
            ch.meta.t0_for(rec / 128),
            o,
        );
    }
    let rf = ch.samples.clone();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "grid {nz}×{nx}, {} elements, {} transmits: {:.3e} pixel·element·transmit samples per pass",
        das.n_elements,
        das.n_transmits(),
        work
    );
    for threads in [1, cores] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut out = vec![Complex64::new(0.0, 0.0); nz * nx];
            let tf = time(5, || das.forward(&iq, &mut out));
            let gbar = out.clone();
            let mut back = vec![Complex64::new(0.0, 0.0); das.data_len()];
            let mut sc = back.clone();
            let tv = time(5, || das.vjp(&gbar, &mut back, &mut sc));
            let mut rf_das = das.clone();
            rf_das.rotate = false;
            let mut out_r = vec![0.0; nz * nx];
            let tr = time(5, || rf_das.forward(&rf, &mut out_r));
            let mut ws = b.workspace();
            let tb = time(3, || {
                b.forward(&ch, &mut ws).unwrap();
            });
            let dimg = vec![1e-3; nz * nx];
            let tbv = time(3, || {
                b.vjp(&mut ws, &dimg).unwrap();
            });
            println!(
                "threads {threads}: DAS IQ forward {:.1} ms ({:.3e} samples/s), DAS IQ VJP {:.1} ms ({:.3e}/s), DAS RF forward {:.1} ms ({:.3e}/s); whole B forward {:.1} ms, B VJP {:.1} ms",
                tf * 1e3, work / tf, tv * 1e3, work / tv, tr * 1e3, work / tr, tb * 1e3, tbv * 1e3
            );
        });
    }
}
