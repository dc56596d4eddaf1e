//! The errors-in-variables correction as an estimator: with the data-dependent steps pinned (cut-off,
//! δ, window count, no gate, no reweighting, no selection), the noise left in the reconstruction
//! attenuates the damping coefficient by several per cent, and the corrected least squares removes
//! most of it. Noise on `x` only, so the attenuation is the correction's own target (it does not
//! model input noise). Repeated draws, fixed seeds.

mod common;

use common::synthetic::{NoiseSpec, SweepSpec, surrogate_record};
use tfs_criteria::{IdentifySpec, TfsOptions, identify_tfs};
use tfs_data::Record;
use tfs_library::Term;
use tfs_signal::NoiseKind;

fn draw(seed: u64, snr_db: f64) -> Vec<Record> {
    common::TRAIN
        .iter()
        .enumerate()
        .map(|(i, &(f0, f1, d, a))| {
            let sw = SweepSpec {
                f0,
                f1,
                duration: 0.5 * d,
                amplitude: a,
            };
            let noise = NoiseSpec {
                snr_db,
                kind: NoiseKind::White,
                seed: 7_000 + 100 * seed + i as u64,
            };
            let noisy = surrogate_record("n", &common::TRUTH, sw, 200.0, Some(noise)).unwrap();
            let clean = surrogate_record("c", &common::TRUTH, sw, 200.0, None).unwrap();
            Record::new(
                format!("r{i}"),
                clean.t().to_vec(),
                vec![
                    ("x".into(), noisy.column("x").unwrap().to_vec()),
                    ("xb_acc".into(), clean.column("xb_acc").unwrap().to_vec()),
                ],
            )
            .unwrap()
        })
        .collect()
}

/// Mean of the (damping, input gain) coefficients over `seeds` draws, with `draws` noise draws
/// of the correction (0 = off), and the correction notes of the first fit.
fn mean_coefs(seeds: u64, draws: usize) -> ([f64; 2], String) {
    let mut spec = IdentifySpec::new(&["x"], "x^5..7, x', xb_acc");
    spec.tfs.fit.threshold = Some(0.0);
    spec.tfs.uncertainty.elimination_rounds = 0;
    spec.tfs.uncertainty.bagging = 0;
    spec.tfs.criterion3.cutoff_hz = Some(3.0);
    spec.tfs.criterion3.deltas = vec![0.3];
    spec.tfs.criterion3.window_counts = vec![3];
    spec.tfs.criterion3.min_bin_snr = None;
    spec.tfs.criterion3.reweight = 0;
    spec.tfs.fit.noise_correction_draws = draws;
    let dofs = ["x".to_string()];
    let mut sum = [0.0; 2];
    let mut note = String::new();
    for s in 0..seeds {
        let id = identify_tfs(&draw(s, 10.0), &spec).unwrap();
        for (k, t) in ["x'", "xb_acc"].iter().enumerate() {
            sum[k] += id.model.coef("x", &Term::parse(t, &dofs).unwrap()).unwrap();
        }
        if s == 0 {
            note = id.trace.dofs[0]
                .settings
                .why
                .iter()
                .find(|w| w.contains("errors-in-variables correction"))
                .cloned()
                .unwrap_or_default();
        }
    }
    (sum.map(|v| v / seeds as f64), note)
}

#[test]
fn correction_removes_the_damping_attenuation_with_pinned_settings() {
    let seeds = 6;
    let (plain, off_note) = mean_coefs(seeds, 0);
    let (fixed, on_note) = mean_coefs(seeds, TfsOptions::default().fit.noise_correction_draws);
    let truth = -common::TRUTH.c;
    let (e_plain, e_fixed) = (plain[0] / truth - 1.0, fixed[0] / truth - 1.0);
    eprintln!(
        "10 dB white on x, mean of {seeds} draws: damping plain {:.4} ({:+.2}%), corrected {:.4} ({:+.2}%); input gain {:.4} / {:.4}\n  {on_note}",
        plain[0],
        100.0 * e_plain,
        fixed[0],
        100.0 * e_fixed,
        plain[1],
        fixed[1]
    );
    assert!(
        off_note.contains("noise_correction_draws = 0"),
        "{off_note}"
    );
    assert!(
        on_note.contains("errors-in-variables correction applied"),
        "{on_note}"
    );
    // Plain least squares is attenuated (towards zero) well beyond the scatter of the mean;
    // the corrected estimate removes most of it.
    assert!(e_plain < -0.04, "plain damping error {e_plain}");
    assert!(
        e_fixed.abs() < 0.4 * e_plain.abs(),
        "corrected damping error {e_fixed} vs plain {e_plain}"
    );
}
