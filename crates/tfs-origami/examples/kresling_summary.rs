//! Prints the JSON summary and the Table 1 surrogate of the paper's cells.
use tfs_origami::{KreslingCell, KreslingParams, Surrogate, SurrogateSpec};

fn main() {
    for g in [30.0, 28.5, 20.0] {
        let t = std::time::Instant::now();
        let cell = KreslingCell::new(KreslingParams {
            gamma0_deg: g,
            ..KreslingParams::default()
        })
        .unwrap();
        let build = t.elapsed();
        let s = Surrogate::fit(&cell, &SurrogateSpec::default()).unwrap();
        let sum = cell.summary();
        println!(
            "γ0 = {g}: build {build:?}, b0 = {:.6}, stable {:?}, unstable {:?}, barrier {:?}, k_stop {:.1}, table_error {:.2e} (F scale {:.2})",
            sum.b0,
            sum.stable,
            sum.unstable,
            sum.barrier,
            sum.k_stop,
            sum.table_error,
            cell.force_scale()
        );
        println!(
            "  surrogate {{h^5,h^6,h^7}} on [0,1.7]: {:?} (rms residual {:.3e})",
            s.coefs, s.rms_residual
        );
        for n in [171, 1701, 17001, 170001] {
            let sp = SurrogateSpec {
                samples: n,
                ..SurrogateSpec::default()
            };
            println!(
                "    samples {n}: {:?}",
                Surrogate::fit(&cell, &sp).unwrap().coefs
            );
        }
        let t = std::time::Instant::now();
        let mut acc = 0.0;
        let n = 10_000_000;
        for i in 0..n {
            acc += cell.force(1.7 * i as f64 / n as f64);
        }
        println!(
            "  {n} force evaluations: {:?} (checksum {acc:.3})",
            t.elapsed()
        );
    }
}
