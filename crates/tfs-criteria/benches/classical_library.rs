//! Classical SINDy's library and compression on the peers records' size (four sweeps of
//! 20,000, 12,000, 16,000 and 24,000 samples at 200 Hz: 72,000 rows × 36 columns of
//! `poly(x, x'; 1..7), xb_acc`).
//!
//! `old_path` is the way before: each record's whole library matrix, then its compression, one
//! record after the other. `new_path` builds the library a chunk of rows at a time straight
//! into the compression (`Library::evaluate_rows` into `Compressed::from_chunks`), the records
//! in parallel, as `identify_sindy` now does; the factors are checked equal to the bit.
//! `identify_sindy` is the whole classical fit on the same records. (The compression's own
//! kernels got faster in the same change and serve both paths; the whole `tfs identify` on
//! these records is timed in `docs/benchmark.md`.)
//!
//! `cargo bench -p tfs-criteria --bench classical_library`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
#[path = "../tests/common/synthetic.rs"]
mod synthetic;

use faer::{ColRef, MatMut};
use rayon::prelude::*;
use synthetic::{NoiseSpec, Surrogate, SweepSpec, surrogate_record};
use tfs_criteria::{IdentifySpec, identify_sindy};
use tfs_data::Record;
use tfs_library::{ColumnSet, Library};
use tfs_regress::Compressed;
use tfs_signal::NoiseKind;

/// The peers sweeps: (f0, f1, duration s, amplitude) at 200 Hz, 30 dB white noise.
fn data() -> Vec<Record> {
    let sys = Surrogate {
        c: 2.0,
        a: [12.145, -18.0618, 6.5625],
    };
    [
        (0.05, 1.5, 100.0, 3.0),
        (0.05, 1.5, 60.0, 4.0),
        (0.1, 1.2, 80.0, 5.0),
        (0.05, 2.0, 120.0, 6.0),
    ]
    .iter()
    .enumerate()
    .map(|(i, &(f0, f1, duration, amplitude))| {
        let sw = SweepSpec {
            f0,
            f1,
            duration,
            amplitude,
        };
        let noise = NoiseSpec {
            snr_db: 30.0,
            kind: NoiseKind::White,
            seed: 17 + i as u64,
        };
        surrogate_record(&format!("peers{i}"), &sys, sw, 200.0, Some(noise)).unwrap()
    })
    .collect()
}

/// The velocity and acceleration by central differences, as classical SINDy takes them.
fn derivatives(r: &Record) -> (Vec<f64>, Vec<f64>) {
    let x = r.column("x").unwrap();
    let dt = r.dt();
    (
        tfs_signal::central_difference(x, dt, 1).unwrap(),
        tfs_signal::central_difference(x, dt, 2).unwrap(),
    )
}

/// The path before this change: the whole library matrix of each record, then its compression.
fn old_path(recs: &[Record], lib: &Library, derivs: &[(Vec<f64>, Vec<f64>)]) -> Vec<Compressed> {
    recs.iter()
        .zip(derivs)
        .map(|(r, (v, acc))| {
            let mut cs = ColumnSet::new(r);
            cs.insert("x'", v.clone()).unwrap();
            let a = lib.evaluate(&cs).unwrap();
            let m = a.nrows() - 2;
            Compressed::from_rows(a.as_ref().subrows(1, m), &acc[1..1 + m]).unwrap()
        })
        .collect()
}

/// The path `identify_sindy` takes: chunks of rows straight into the compression, records in
/// parallel.
fn new_path(recs: &[Record], lib: &Library, derivs: &[(Vec<f64>, Vec<f64>)]) -> Vec<Compressed> {
    recs.par_iter()
        .zip(derivs)
        .map(|(r, (v, acc))| {
            let mut cs = ColumnSet::new(r);
            cs.insert("x'", v.clone()).unwrap();
            let (n, m) = (lib.len(), r.len() - 2);
            Compressed::from_chunks(n, m, |start, mut chunk: MatMut<'_, f64>| {
                let rows = 1 + start..1 + start + chunk.nrows();
                lib.evaluate_rows(&cs, rows.clone(), chunk.as_mut().get_mut(.., ..n))
                    .unwrap();
                chunk.col_mut(n).copy_from(ColRef::from_slice(&acc[rows]));
                Ok::<(), tfs_regress::RegressError>(())
            })
            .unwrap()
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let recs = data();
    let lib = Library::parse("poly(x, x'; 1..7), xb_acc", &["x".to_string()]).unwrap();
    let derivs: Vec<_> = recs.iter().map(derivatives).collect();
    let mats: Vec<_> = recs
        .iter()
        .zip(&derivs)
        .map(|(r, (v, _))| {
            let mut cs = ColumnSet::new(r);
            cs.insert("x'", v.clone()).unwrap();
            lib.evaluate(&cs).unwrap()
        })
        .collect();
    let rows: usize = mats.iter().map(|m| m.nrows()).sum();
    eprintln!("{rows} rows × {} columns", lib.len());
    assert_eq!(
        old_path(&recs, &lib, &derivs),
        new_path(&recs, &lib, &derivs),
        "the chunked path must give the same factors to the bit"
    );
    let spec = IdentifySpec::new(&["x"], "poly(x, x'; 1..7), xb_acc");
    let mut g = c.benchmark_group("classical_library_72k");
    g.sample_size(20);
    g.bench_function("old_library_only", |b| {
        b.iter(|| {
            recs.iter()
                .zip(&derivs)
                .map(|(r, (v, _))| {
                    let mut cs = ColumnSet::new(r);
                    cs.insert("x'", v.clone()).unwrap();
                    lib.evaluate(&cs).unwrap()
                })
                .collect::<Vec<_>>()
        })
    });
    g.bench_function("old_compression_only", |b| {
        b.iter(|| {
            mats.iter()
                .zip(&derivs)
                .map(|(a, (_, acc))| {
                    let m = a.nrows() - 2;
                    Compressed::from_rows(a.as_ref().subrows(1, m), &acc[1..1 + m]).unwrap()
                })
                .collect::<Vec<_>>()
        })
    });
    g.bench_function("old_path", |b| {
        b.iter(|| old_path(black_box(&recs), &lib, &derivs))
    });
    g.bench_function("new_path", |b| {
        b.iter(|| new_path(black_box(&recs), &lib, &derivs))
    });
    g.bench_function("identify_sindy", |b| {
        b.iter(|| identify_sindy(black_box(&recs), &spec).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
