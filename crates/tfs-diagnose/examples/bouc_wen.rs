//! Writes the hysteresis walk-through's records: the Bouc–Wen benchmark oscillator (m = 2,
//! c = 10, k = 5e4, α = 5e4, β = 1e3, γ = 0.8, δ = −1.1, ν = 1) under five random-phase
//! multisines of 8,192 samples at 750 Hz (5–150 Hz, 50 N RMS; `train0.csv` … `train4.csv`),
//! and two held-out records, a multisine (`val-ms.csv`) and a sine sweep (`val-sweep.csv`), all
//! noise-free. With `--snr-db N` the training records carry white noise at N dB on `x` and `u`
//! (the held-out ones stay noise-free: the response the model should predict).
//! Usage: `cargo run -p tfs-diagnose --example bouc_wen -- OUT_DIR [--snr-db 40]`.

#[path = "../tests/common/mod.rs"]
mod common;

use common::bouc_wen::data;
use tfs_origami::BoucWenOscillator;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = std::path::PathBuf::from(args.first().cloned().unwrap_or_else(|| "bw".into()));
    let snr = match args.iter().position(|a| a == "--snr-db") {
        Some(i) => Some(
            args.get(i + 1)
                .ok_or("--snr-db needs a value in dB")?
                .parse::<f64>()
                .map_err(|e| format!("--snr-db: {e}"))?,
        ),
        None => None,
    };
    std::fs::create_dir_all(&dir)?;
    let (train, val, sweep) = data(&BoucWenOscillator::benchmark(), 50.0, snr, false);
    for (i, r) in train.iter().enumerate() {
        tfs_data::write_csv(dir.join(format!("train{i}.csv")), r)?;
    }
    tfs_data::write_csv(dir.join("val-ms.csv"), &val)?;
    tfs_data::write_csv(dir.join("val-sweep.csv"), &sweep)?;
    println!("wrote {}", dir.display());
    Ok(())
}
