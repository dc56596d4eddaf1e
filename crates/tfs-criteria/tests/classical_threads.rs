//! Classical SINDy compresses its records in parallel: the model and the trace's numbers must
//! not depend on the number of threads.

mod common;
use common::train;
use tfs_criteria::{IdentifySpec, identify_sindy};
use tfs_signal::NoiseKind;

#[test]
fn classical_sindy_is_the_same_on_1_2_and_7_threads() {
    let recs = train(Some((60.0, NoiseKind::White)), 0.5, 3);
    // The threshold chosen on the held-out record, and one given (the merged fit).
    let chosen = IdentifySpec::new(&["x"], "x^1..7, x', xb_acc");
    let mut given = IdentifySpec::new(&["x"], "poly(x, x'; 1..7), xb_acc");
    given.sindy.threshold = Some(0.05);
    let run = |threads: usize, spec: &IdentifySpec| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| identify_sindy(&recs, spec).unwrap())
    };
    // Not an empty model, so the comparison compares coefficients.
    assert!(!run(1, &given).model.equations[0].terms.is_empty());
    for spec in [&chosen, &given] {
        let one = run(1, spec);
        for threads in [2, 7] {
            let other = run(threads, spec);
            assert_eq!(one.model, other.model, "{threads} threads");
            assert_eq!(
                one.trace.dofs[0].settings.threshold, other.trace.dofs[0].settings.threshold,
                "{threads} threads"
            );
        }
    }
}
