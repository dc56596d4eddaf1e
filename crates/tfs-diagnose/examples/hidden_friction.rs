//! Writes a demonstration of the diagnosis loop: three sweep records (and one held-out record) of a
//! Duffing oscillator with hidden dry friction, 40 dB noise, plus a starting model fitted without
//! friction. Usage: `cargo run -p tfs-diagnose --example hidden_friction -- OUT_DIR`, then
//! `tfs diagnose --model OUT_DIR/start.json OUT_DIR/train*.csv`.

#[path = "../tests/common/mod.rs"]
mod common;

use common::*;
use tfs_diagnose::{DiagnoseOptions, refit};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "demo".into()));
    std::fs::create_dir_all(&dir)?;
    let truth = Truth {
        restoring: duffing_restoring(),
        damping: 0.63,
        hidden: vec![Hidden::DryFriction {
            force: 2.0,
            eps: 0.02,
        }],
        x0: 0.0,
    };
    let mut train = Vec::new();
    for i in 0..3 {
        let r = record(
            &truth,
            &format!("train{i}"),
            0.3,
            3.0,
            4.0 * (0.8 + 0.2 * i as f64),
            30.0,
            0.01,
            10 + i,
        );
        tfs_data::write_csv(dir.join(format!("train{i}.csv")), &r)?;
        train.push(r);
    }
    let test = record(&truth, "test", 0.3, 3.0, 3.6, 30.0, 0.01, 99);
    tfs_data::write_csv(dir.join("test.csv"), &test)?;
    let start = refit(
        &structure("x, x^3, x', xb_acc"),
        &train,
        &DiagnoseOptions::default(),
    )?;
    start.write_path(dir.join("start.json"))?;
    println!("{}", start.equation_string());
    println!("wrote {}", dir.display());
    Ok(())
}
