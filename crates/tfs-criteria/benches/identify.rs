//! T-F-S SINDy end to end versus classical SINDy on the paper's data size (Appendix B: 200,020
//! samples, a 36-column classical library), in the same run; prints the ratio. T-F-S runs with
//! the paper's 9-column library and with the 36-column classical one (the two libraries of the
//! PySINDy side by side, `cargo xtask peers`).

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
#[path = "../tests/common/synthetic.rs"]
mod synthetic;

use synthetic::{NoiseSpec, Surrogate, SweepSpec, surrogate_record};
use tfs_criteria::{IdentifySpec, identify_sindy, identify_tfs};
use tfs_data::Record;
use tfs_signal::NoiseKind;

/// Four sweeps of 50,005 samples each at 200 Hz (200,020 samples), 30 dB white noise.
fn data() -> Vec<Record> {
    let sys = Surrogate {
        c: 1.99,
        a: [12.12, -18.03, 6.56],
    };
    [
        (0.05, 1.5, 3.0),
        (0.05, 1.5, 4.0),
        (0.1, 1.2, 5.0),
        (0.05, 2.0, 6.0),
    ]
    .iter()
    .enumerate()
    .map(|(i, &(f0, f1, a))| {
        let sw = SweepSpec {
            f0,
            f1,
            duration: 250.02,
            amplitude: a,
        };
        let noise = NoiseSpec {
            snr_db: 30.0,
            kind: NoiseKind::White,
            seed: 40 + i as u64,
        };
        surrogate_record(&format!("bench{i}"), &sys, sw, 200.0, Some(noise)).unwrap()
    })
    .collect()
}

fn bench(c: &mut Criterion) {
    let recs = data();
    let total: usize = recs.iter().map(|r| r.len()).sum();
    let tfs_spec = IdentifySpec::new(&["x"], "x^1..7, x', xb_acc");
    let sindy_spec = IdentifySpec::new(&["x"], "poly(x, x'; 1..7), xb_acc");
    let tfs36_spec = IdentifySpec::new(&["x"], "poly(x, x'; 1..7), xb_acc");
    let t = Instant::now();
    let a = identify_tfs(&recs, &tfs_spec).unwrap();
    let t_tfs = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let b = identify_sindy(&recs, &sindy_spec).unwrap();
    let t_sindy = t.elapsed().as_secs_f64();
    eprintln!(
        "{total} samples: T-F-S {:.1} ms, classical SINDy ({} columns) {:.1} ms, ratio {:.1}×\n  T-F-S:  {}\n  SINDy:  {}",
        1e3 * t_tfs,
        b.trace.dofs[0].library.len(),
        1e3 * t_sindy,
        t_sindy / t_tfs,
        a.model.equation_string(),
        b.model.equation_string()
    );
    eprintln!("  T-F-S stages (ms): {:?}", a.trace.timing_ms);
    let mut g = c.benchmark_group("identify_200k");
    g.sample_size(10);
    g.bench_function("tfs", |bch| {
        bch.iter(|| identify_tfs(black_box(&recs), &tfs_spec).unwrap())
    });
    g.bench_function("tfs_36", |bch| {
        bch.iter(|| identify_tfs(black_box(&recs), &tfs36_spec).unwrap())
    });
    g.bench_function("sindy_36", |bch| {
        bch.iter(|| identify_sindy(black_box(&recs), &sindy_spec).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
