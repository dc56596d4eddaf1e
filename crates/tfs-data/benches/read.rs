//! Reading a CSV record: the reader as it was before it read each file once (the `csv` crate's
//! records, every cell trimmed and parsed, the time column's printed resolution from its text;
//! the CLI then read each file twice, once for its header) against [`CsvTable`] (one pass of
//! its own line splitter, the resolution counted while the cell is parsed), in the same run.
//!
//! `cargo bench -p tfs-data --bench read`

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use tfs_data::{CsvOptions, CsvTable, Saturation};

/// A record like the peers' and the fixtures': `t,x,xb_acc` printed to full precision.
fn text(n: usize) -> String {
    let mut s = String::from("t,x,xb_acc\n");
    for i in 0..n {
        let t = i as f64 * 0.005;
        let x = 0.8 + 0.4 * (1.3 * t).sin() + 1e-3 * ((i * 7919) % 101) as f64;
        let u = 4.0 * (0.05 * t * t).sin();
        s.push_str(&format!("{t},{x},{u}\n"));
    }
    s
}

/// The baseline: the reader's parsing loop before this change (header checks omitted; they
/// are the same few comparisons in both), returning the columns and the time resolution.
fn baseline_parse(bytes: &[u8]) -> (Vec<Vec<f64>>, f64) {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(bytes);
    let mut records = rdr.records();
    let header = records.next().unwrap().unwrap();
    let names: Vec<String> = header.iter().map(str::to_string).collect();
    let ti = names.iter().position(|n| n == "t").unwrap();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    let mut lines = Vec::new();
    let mut resolution = f64::INFINITY;
    for rec in records {
        let rec = rec.unwrap();
        let line = rec.position().map_or(0, |p| p.line());
        assert_eq!(rec.len(), names.len());
        for (j, cell) in rec.iter().enumerate() {
            let v: f64 = cell.parse().unwrap();
            assert!(v.is_finite());
            cols[j].push(v);
        }
        resolution = resolution.min(baseline_resolution(&rec[ti]));
        lines.push(line);
    }
    (cols, resolution)
}

/// The baseline's printed resolution of a time cell (from its text, a second pass over it).
fn baseline_resolution(cell: &str) -> f64 {
    let cell = cell.trim();
    let (mant, exp) = match cell.find(['e', 'E']) {
        Some(i) => match cell[i + 1..].parse::<i32>() {
            Ok(e) => (&cell[..i], e),
            Err(_) => return 0.0,
        },
        None => (cell, 0),
    };
    let decimals = mant.split_once('.').map_or(0, |(_, d)| d.len()) as i32;
    10f64.powi(exp - decimals)
}

fn bench(c: &mut Criterion) {
    for n in [20_000usize, 200_000] {
        let t = text(n);
        let bytes = t.as_bytes();
        // Same numbers from both readers.
        let (old, _) = baseline_parse(bytes);
        let table = CsvTable::from_reader("bench", bytes).unwrap();
        let rec = table
            .into_record(&CsvOptions::default().saturation(Saturation::Allow))
            .unwrap()
            .0;
        assert_eq!(rec.t(), &old[0][..]);
        assert_eq!(rec.column("x").unwrap(), &old[1][..]);

        let mut g = c.benchmark_group(format!("parse {n} rows"));
        g.throughput(Throughput::Bytes(bytes.len() as u64));
        g.bench_function("baseline (csv crate)", |b| {
            b.iter(|| black_box(baseline_parse(black_box(bytes))))
        });
        g.bench_function("CsvTable", |b| {
            b.iter(|| black_box(CsvTable::from_reader("bench", black_box(bytes)).unwrap()))
        });
        g.finish();

        // What `tfs identify` did per file: parse for the header, then parse again to read;
        // now one parse whose names are looked at before validation.
        let opts = CsvOptions::default().require(["x", "xb_acc"]);
        let mut g = c.benchmark_group(format!("identify's read {n} rows"));
        g.throughput(Throughput::Bytes(bytes.len() as u64));
        g.bench_function("baseline (parsed twice)", |b| {
            b.iter(|| {
                black_box(baseline_parse(black_box(bytes)));
                black_box(baseline_parse(black_box(bytes)))
            })
        });
        g.bench_function("CsvTable once + validation", |b| {
            b.iter(|| {
                let table = CsvTable::from_reader("bench", black_box(bytes)).unwrap();
                black_box(table.names().len());
                black_box(table.into_record(&opts).unwrap())
            })
        });
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench
}
criterion_main!(benches);
