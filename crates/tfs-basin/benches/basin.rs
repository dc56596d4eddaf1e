//! Criterion benchmark: 1000×1000 S-DOF basin of the paper's Table 1 model
//! (x ∈ [−1, 2.5], v ∈ [−3, 3]) with early exit (dt = 0.02 and 0.01) and without it.

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use tfs_basin::{BasinConfig, Polynomial1Dof, WellInfo, basin_sdof};

fn bench(c: &mut Criterion) {
    let model = Polynomial1Dof::table1_60db();
    let wells = WellInfo::from_polynomial(&model, (-3.0, 3.0)).expect("wells");
    let mut cfg = BasinConfig::new(1000, 1000, (-1.0, 2.5), (-3.0, 3.0));
    cfg.t_max = 100.0;
    let mut g = c.benchmark_group("basin_1000x1000");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(10))
        .warm_up_time(Duration::from_secs(1));
    for dt in [0.02, 0.01] {
        cfg.dt = dt;
        g.bench_function(format!("early_exit_dt{dt}"), |b| {
            b.iter(|| basin_sdof(&model, &wells, &cfg, None).expect("map"))
        });
    }
    let mut full = cfg.clone();
    full.dt = 0.02;
    full.early_exit = false;
    full.t_max = 20.0;
    g.bench_function("no_early_exit_dt0.02_t20", |b| {
        b.iter(|| basin_sdof(&model, &wells, &full, None).expect("map"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
