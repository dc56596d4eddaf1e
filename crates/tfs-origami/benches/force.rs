//! Cost of one tabulated truss force evaluation versus a direct torque-free solve (the baseline).
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use tfs_origami::{KreslingCell, KreslingParams};

fn bench(c: &mut Criterion) {
    let cell = KreslingCell::new(KreslingParams::default()).unwrap();
    let hs: Vec<f64> = (0..1000).map(|i| 1.7 * i as f64 / 999.0).collect();
    c.bench_function("tabulated force x1000", |b| {
        b.iter(|| hs.iter().map(|&h| cell.force(black_box(h))).sum::<f64>())
    });
    c.bench_function("direct branch solve x1000", |b| {
        b.iter(|| {
            hs.iter()
                .map(|&h| cell.branch_point(black_box(h)).unwrap().force)
                .sum::<f64>()
        })
    });
    c.bench_function("build cell (table + checks)", |b| {
        b.iter(|| KreslingCell::new(black_box(KreslingParams::default())).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
