//! Criterion benchmark: `diagnose` with the standard catalogue against the same catalogue
//! without the hysteresis candidate (the catalogue before memory effects beyond Maxwell were
//! added), and against that catalogue with the calibrated null switched off as well (the
//! diagnosis as it was before the hysteresis and chaos work), on the same records, in one run: a Duffing oscillator with hidden dry friction
//! (three 30 s sweeps at 100 Hz, 40 dB) and the Bouc–Wen benchmark oscillator (two multisine
//! periods of 8,192 samples at 750 Hz, 40 dB). Compare the lines of each group for the ratios.

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Duration;

use common::{Hidden, Truth, bouc_wen, duffing_restoring, record, structure};
use criterion::{Criterion, criterion_group, criterion_main};
use tfs_data::Record;
use tfs_diagnose::{Catalogue, DiagnoseOptions, diagnose_with, refit};
use tfs_origami::BoucWenOscillator;

/// The standard catalogue without the candidate the memory-effect work added.
fn before_memory(max_power: u32) -> Catalogue {
    let mut c = Catalogue::standard(max_power);
    c.remove("hysteresis").expect("a standard effect");
    c
}

fn duffing_records() -> Vec<Record> {
    let truth = Truth {
        restoring: duffing_restoring(),
        damping: 0.63,
        hidden: vec![Hidden::DryFriction {
            force: 2.0,
            eps: 0.02,
        }],
        x0: 0.0,
    };
    (0..3)
        .map(|i| {
            let amp = 4.0 * (0.8 + 0.2 * i as f64);
            record(&truth, &format!("d{i}"), 0.3, 3.0, amp, 30.0, 0.01, 10 + i)
        })
        .collect()
}

fn bouc_wen_records() -> Vec<Record> {
    let bw = BoucWenOscillator::benchmark();
    (0..2)
        .map(|i| {
            let u = bouc_wen::multisine(8192, 50.0, 10 + i);
            bouc_wen::record(&bw, &format!("b{i}"), u, Some(40.0), 100 + i)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let opts = DiagnoseOptions::default();
    let standard = Catalogue::standard(opts.max_power);
    let before = before_memory(opts.max_power);
    let no_null = DiagnoseOptions {
        null_draws: 0,
        ..DiagnoseOptions::default()
    };
    for (name, records, spec) in [
        (
            "duffing_dry_friction",
            duffing_records(),
            "x, x^3, x', xb_acc",
        ),
        ("bouc_wen_benchmark", bouc_wen_records(), "x, x', u"),
    ] {
        let model = refit(&structure(spec), &records, &opts).unwrap();
        let mut g = c.benchmark_group(format!("diagnose_{name}"));
        g.sample_size(10)
            .measurement_time(Duration::from_secs(20))
            .warm_up_time(Duration::from_secs(1));
        g.bench_function("standard_catalogue", |b| {
            b.iter(|| diagnose_with(&model, &records, &standard, &opts).unwrap())
        });
        g.bench_function("standard_without_null", |b| {
            b.iter(|| diagnose_with(&model, &records, &standard, &no_null).unwrap())
        });
        g.bench_function("without_hysteresis", |b| {
            b.iter(|| diagnose_with(&model, &records, &before, &opts).unwrap())
        });
        g.bench_function("without_hysteresis_or_null", |b| {
            b.iter(|| diagnose_with(&model, &records, &before, &no_null).unwrap())
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
