//! Criterion benchmark: basin maps by the three methods in the same run, so the ratios against
//! the original path (`Method::Scalar`, every start integrated with scalar model calls) are
//! measured on the same machine state:
//!
//! * `table1_1000`: the paper's Table 1 cell, 1000 × 1000 over x ∈ [0, 2], v ∈ [−3, 3].
//! * `double_well_1000`: `x'' = x − x³ − 0.4 x'` (compiled from a model, as the CLI runs it),
//!   1000 × 1000 over the same window.
//! * `chain_400`: a two-mass chain (monostable cell 1, double-well cell 2, compiled from a
//!   model) on the paper's slice, 400 × 400.
//!
//! Run with `cargo bench -p tfs-basin` (about a quarter of an hour: the scalar baselines take
//! tens of seconds an iteration).

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use tfs_basin::{
    BasinConfig, ChainWells, Method, Polynomial1Dof, Slice, WellInfo, basin_chain, basin_sdof,
};
use tfs_library::{CompiledModel, Model};

const METHODS: [(&str, Method); 3] = [
    ("scalar", Method::Scalar),
    ("every_cell", Method::EveryCell),
    ("refined", Method::Refined),
];

fn compiled(json: &str) -> CompiledModel {
    Model::from_json_str(json)
        .expect("model")
        .compile()
        .expect("compiles")
}

fn sdof(c: &mut Criterion) {
    let table1 = Polynomial1Dof::table1_60db();
    let t1_wells = WellInfo::from_polynomial(&table1, (-1.0, 3.0)).expect("wells");
    let cfg = BasinConfig::new(1000, 1000, (0.0, 2.0), (-3.0, 3.0));
    let mut g = c.benchmark_group("table1_1000");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(20))
        .warm_up_time(Duration::from_secs(1));
    for (name, method) in METHODS {
        let cfg = BasinConfig {
            method,
            ..cfg.clone()
        };
        g.bench_function(name, |b| {
            b.iter(|| basin_sdof(&table1, &t1_wells, &cfg, None).expect("map"))
        });
    }
    g.finish();

    let duffing = compiled(
        r#"{"format":"tfs-model/1","dofs":["x"],"equations":[{"dof":"x","terms":[
            {"term":"x","coef":1.0},{"term":"x^3","coef":-1.0},{"term":"x'","coef":-0.4}]}]}"#,
    );
    let d_wells = WellInfo::from_force(
        |x| x * x * x - x,
        |x| 0.25 * x.powi(4) - 0.5 * x * x,
        (-1.0, 3.0),
        1.0,
    )
    .expect("wells");
    let mut g = c.benchmark_group("double_well_1000");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(60))
        .warm_up_time(Duration::from_secs(1));
    for (name, method) in METHODS {
        let cfg = BasinConfig {
            method,
            ..cfg.clone()
        };
        g.bench_function(name, |b| {
            b.iter(|| basin_sdof(&duffing, &d_wells, &cfg, None).expect("map"))
        });
    }
    g.finish();
}

fn chain(c: &mut Criterion) {
    // Cell 1: x1'' ∋ −x1 − 0.5 x1³ − 0.3 x1'; cell 2 (relative r = x2 − x1): −(−r + r³) − 0.3 r'.
    let sys = compiled(
        r#"{"format":"tfs-model/1","dofs":["x1","x2"],"equations":[
        {"dof":"x1","terms":[{"term":"x1","coef":-1.0},{"term":"x1^3","coef":-0.5},
            {"term":"x1'","coef":-0.3},{"term":"(x2-x1)","coef":-1.0},
            {"term":"(x2-x1)^3","coef":1.0},{"term":"(x2-x1)'","coef":0.3}]},
        {"dof":"x2","terms":[{"term":"(x2-x1)","coef":1.0},{"term":"(x2-x1)^3","coef":-1.0},
            {"term":"(x2-x1)'","coef":-0.3}]}]}"#,
    );
    let pot = |x: &[f64]| {
        let r = x[1] - x[0];
        0.5 * x[0] * x[0] + 0.125 * x[0].powi(4) - 0.5 * r * r + 0.25 * r.powi(4)
    };
    let barrier = ChainWells::barrier_from_saddles(pot, &[vec![0.0, 0.0]]).expect("saddle");
    let wells = ChainWells::new(
        vec![vec![0.0, -1.0], vec![0.0, 1.0]],
        vec![1.0, 1.0],
        pot,
        Some(barrier),
    )
    .expect("wells");
    let slice = Slice::paper(&[0.0, -1.0]);
    let cfg = BasinConfig::new(400, 400, (-1.0, 3.0), (-3.0, 3.0));
    let mut g = c.benchmark_group("chain_400");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(30))
        .warm_up_time(Duration::from_secs(1));
    for (name, method) in METHODS {
        let cfg = BasinConfig {
            method,
            ..cfg.clone()
        };
        g.bench_function(name, |b| {
            b.iter(|| basin_chain(&sys, &wells, &slice, &cfg, None).expect("map"))
        });
    }
    g.finish();
}

criterion_group!(benches, sdof, chain);
criterion_main!(benches);
