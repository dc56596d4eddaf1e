//! The diagnosis gives the same bits on 1, 2 and 7 threads: every sum whose split could follow
//! the thread count (the candidates' size, the residual's history correlations, the held-out
//! simulations) runs in a fixed order. A Duffing oscillator with hidden dry friction at 40 dB,
//! two records of 24,000 samples (long enough for the dense library kernels to split their work
//! over threads), diagnosed inside thread pools of three sizes; the whole diagnosis, serialised,
//! must match.

mod common;

use common::*;
use tfs_diagnose::{DiagnoseOptions, diagnose, refit};
use tfs_origami::Hidden;

#[test]
fn diagnosis_is_identical_on_1_2_and_7_threads() {
    let truth = Truth {
        restoring: duffing_restoring(),
        damping: 0.63,
        hidden: vec![Hidden::DryFriction {
            force: 0.8,
            eps: 0.02,
        }],
        x0: 0.0,
    };
    let train: Vec<_> = (0..2)
        .map(|i| {
            record(
                &truth,
                &format!("r{i}"),
                0.3,
                3.0,
                4.0 * (0.8 + 0.2 * i as f64),
                120.0,
                0.005,
                70 + i as u64,
            )
        })
        .collect();
    let opts = DiagnoseOptions::default();
    let start = refit(&structure("x, x^3, x', xb_acc"), &train, &opts).unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let d = pool.install(|| diagnose(&start, &train, &opts).unwrap());
        serde_json::to_string(&d).unwrap()
    };
    let one = run(1);
    assert!(one.contains("dry-friction"), "{one}");
    for threads in [2, 7] {
        assert!(
            run(threads) == one,
            "diagnosis on {threads} threads differs from 1 thread"
        );
    }
}
