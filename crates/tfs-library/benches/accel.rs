//! Compiled-model acceleration (the inner loop of simulation and basin grids) against the
//! slow per-term evaluation of the same model, and library evaluation at the paper's size.

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use tfs_data::Record;
use tfs_library::{ColumnSet, Library, Model, evaluate_term};

fn model() -> Model {
    let lib = Library::parse("x', x^5, x^6, x^7, xb_acc, tanh(x'/0.01)", &["x"]).unwrap();
    Model::from_coefficients(
        &lib,
        &[vec![-1.99, -12.12, 18.03, -6.56, -1.0, -0.1]],
        "bench",
    )
    .unwrap()
}

fn bench(c: &mut Criterion) {
    let m = model();
    let fast = m.compile().unwrap();
    let states: Vec<(f64, f64)> = (0..1000)
        .map(|i| {
            let s = i as f64 / 1000.0;
            (1.7 * s - 0.1, (7.0 * s).sin())
        })
        .collect();
    c.bench_function("compiled accel x1000", |b| {
        b.iter(|| {
            let mut sum = 0.0;
            let mut out = [0.0];
            for &(x, v) in &states {
                fast.accel(&[x], &[v], &[0.3], &mut out);
                sum += out[0];
            }
            black_box(sum)
        })
    });
    c.bench_function("slow per-term accel x1000", |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for &(x, v) in &states {
                let rec = Record::new(
                    "s",
                    vec![0.0],
                    vec![("x".into(), vec![x]), ("xb_acc".into(), vec![0.3])],
                )
                .unwrap();
                let cols = ColumnSet::new(&rec).with("x'", vec![v]).unwrap();
                for t in &m.equations[0].terms {
                    sum += t.coef * evaluate_term(&t.term, &cols).unwrap()[0];
                }
            }
            black_box(sum)
        })
    });
    let n = 200_020;
    let x: Vec<f64> = (0..n).map(|i| (i as f64 * 1e-3).sin()).collect();
    let v: Vec<f64> = (0..n).map(|i| (i as f64 * 1e-3).cos()).collect();
    let rec = Record::new(
        "big",
        (0..n).map(|i| i as f64).collect(),
        vec![("x".into(), x)],
    )
    .unwrap();
    let cols = ColumnSet::new(&rec).with("x'", v).unwrap();
    let lib = Library::parse("poly(x, x'; 0..7)", &["x"]).unwrap();
    c.bench_function("evaluate poly(x,x';0..7) on 200020 rows", |b| {
        b.iter(|| black_box(lib.evaluate(&cols).unwrap()))
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
