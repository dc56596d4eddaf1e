//! Records of Bouc–Wen oscillators (`tfs_origami::BoucWenOscillator`) for the hysteresis tests
//! and the walk-through: random-phase multisines on the bins of one period and sine sweeps over
//! 5–150 Hz at 750 Hz, the benchmark's band and rate.

use tfs_data::Record;
use tfs_origami::BoucWenOscillator;
use tfs_origami::oscillator::{measured, simulate_record};
use tfs_signal::{Excitation, Multisine, Sweep, SweepKind};

/// Sampling rate (Hz).
pub const FS: f64 = 750.0;

/// A random-phase multisine over 5–150 Hz with `rms` and tones on the bins of an `n`-sample
/// period (so the record is one period of a periodic excitation).
pub fn multisine(n: usize, rms: f64, seed: u64) -> Vec<f64> {
    let df = FS / n as f64;
    let (k0, k1) = ((5.0 / df).ceil(), (150.0 / df).floor());
    let tones = (k1 - k0) as usize + 1;
    let ms = Multisine::new(k0 * df, k1 * df, tones, rms, n as f64 / FS, 0.0, seed).unwrap();
    ms.sample(&tfs_signal::time_grid(n, 1.0 / FS))
}

/// A sine sweep over 5–150 Hz of amplitude `amp`, `n` samples.
pub fn sweep(n: usize, amp: f64) -> Vec<f64> {
    let secs = n as f64 / FS;
    Sweep::new(SweepKind::Log, 5.0, 150.0, secs, amp, 0.05 * secs)
        .unwrap()
        .sample(&tfs_signal::time_grid(n, 1.0 / FS))
}

/// The record of `bw` under `u` (two periods of a multisine: the first lets the transient of
/// the start from rest die out and is dropped, as in the benchmark), measured with `snr`.
pub fn record(
    bw: &BoucWenOscillator,
    name: &str,
    u: Vec<f64>,
    snr: Option<f64>,
    seed: u64,
) -> Record {
    let x = simulate_record(bw, &u, 1.0 / FS, 0.0, (1e-10, 1e-13)).unwrap();
    measured(name, 1.0 / FS, ("x", &x), ("u", &u), snr, seed).unwrap()
}

/// Training: five multisine (or sine-sweep) records of 8192 samples; validation: a fresh
/// multisine and a sweep, noise-free (the truth the identified model should predict; at 40 dB
/// the measured records' own noise alone is ~1.4 % of their RMS).
pub fn data(
    bw: &BoucWenOscillator,
    rms: f64,
    snr: Option<f64>,
    train_on_sweeps: bool,
) -> (Vec<Record>, Record, Record) {
    let n = 8192;
    let train = (0..5)
        .map(|i| {
            let u = if train_on_sweeps {
                sweep(n, rms * 2f64.sqrt() * (0.8 + 0.1 * i as f64))
            } else {
                multisine(n, rms, 10 + i)
            };
            record(bw, &format!("train{i}"), u, snr, 100 + i)
        })
        .collect();
    let val = record(bw, "val-ms", multisine(n, rms, 77), None, 0);
    let sw = record(bw, "val-sweep", sweep(n, rms * 2f64.sqrt()), None, 0);
    (train, val, sw)
}
