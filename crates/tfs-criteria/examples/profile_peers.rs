//! Times `identify_tfs` on the records written by `cargo xtask peers` (profiling aid).
//!
//! `cargo run --release -p tfs-criteria --example profile_peers -- target/peers/data/white30 [reps] [classical]`

use std::time::Instant;

use tfs_criteria::{IdentifySpec, identify_sindy, identify_tfs};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let dir = args
        .get(1)
        .cloned()
        .unwrap_or_else(|| "target/peers/data/white30".into());
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    let classical = args.get(3).is_some_and(|s| s == "classical");
    let recs = (1..=4)
        .map(|i| tfs_data::read_csv(format!("{dir}/train{i}.csv")))
        .collect::<Result<Vec<_>, _>>()?;
    let lib = if classical {
        "poly(x, x'; 1..7), xb_acc"
    } else {
        "x^1..7, x', xb_acc"
    };
    let spec = IdentifySpec::new(&["x"], lib);
    for _ in 0..reps {
        let t = Instant::now();
        let id = identify_tfs(&recs, &spec)?;
        let el = t.elapsed().as_secs_f64() * 1e3;
        println!("tfs {el:.1} ms: {}", id.model.equation_string());
        for (k, v) in &id.trace.timing_ms {
            println!("   {k}: {v:.1}");
        }
        for d in &id.trace.dofs {
            if let Some(c1) = &d.criterion1 {
                println!(
                    "   κ = {:.2}, κ0 = {:.2}, high {}",
                    c1.kappa.standardised, c1.kappa0, c1.high_snr
                );
            }
            println!(
                "   settings δ {} w {}",
                d.settings.delta, d.settings.windows
            );
            for b in &d.bins {
                println!(
                    "   bins {} cutoff {:.2} band {:?}",
                    b.kept_bins, b.cutoff_hz, b.band_hz
                );
            }
            for a in &d.assembly {
                println!(
                    "   step n_terms {} rows {} mu {:.4} sigma {:.4}",
                    a.n_terms, a.rows, a.mu, a.sigma
                );
            }
            println!("   verdict {}", d.assembly_verdict);
        }
    }
    let t = Instant::now();
    let s = identify_sindy(
        &recs,
        &IdentifySpec::new(&["x"], "poly(x, x'; 1..7), xb_acc"),
    )?;
    println!(
        "sindy {:.1} ms: {}",
        t.elapsed().as_secs_f64() * 1e3,
        s.model.equation_string()
    );
    Ok(())
}
