//! A Kresling surrogate cell that sits in its folded well (about h = 0, where h^5..7 are flat and
//! the restoring force is a few per cent of the acceleration), measured at 25 dB: T-F-S's
//! selection keeps no displacement term, and `identify` fits the library's displacement terms
//! back because the training records simulate better with them. The model that comes out must
//! predict a record it was not fitted on better than the model without a restoring force, on
//! each of three noise draws. (Measured over six draws each: at 30 dB the selection keeps the
//! terms itself; at 25 dB five of six lose them and all five come back, the held-out R-MSE
//! falling from about 1 to 0.013–0.041; at 20 dB six of six come back and five of them predict
//! better, one worse, 1.29 → 2.09, both no better than the record's mean.)

#[path = "common/run.rs"]
mod run;

use std::path::PathBuf;

use tfs::identify::{IdentifyOptions, identify, plan};
use tfs::records::{Clipped, read_records};

/// Three training sweeps and a held-out one of the surrogate cell at `snr` dB, noise seed `seed`.
fn records(dir: &std::path::Path, snr: &str, seed: &str) -> Vec<PathBuf> {
    run::ok(
        dir,
        &[
            "simulate",
            "kresling",
            "--excitation",
            "sweep:0.2:2.5:3",
            "--excitation",
            "sweep:0.2:2.5:2.7",
            "--excitation",
            "sweep:0.2:2.5:3.3",
            "--excitation",
            "sweep:0.2:2.5:3.1",
            "--duration",
            "30",
            "--dt",
            "0.01",
            "--snr-db",
            snr,
            "--seed",
            seed,
            "--out",
            "k.csv",
        ],
    );
    (1..=4).map(|i| dir.join(format!("k-{i}.csv"))).collect()
}

#[test]
fn a_restoring_force_selection_dropped_comes_back_when_it_predicts_better() {
    let lib = "x^5..7, x', xb_acc";
    for (snr, seed) in [("25", "1"), ("25", "2"), ("25", "3")] {
        let dir = tempfile::tempdir().unwrap();
        let paths = records(dir.path(), snr, seed);
        let opts = IdentifyOptions {
            library: Some(lib.into()),
            dofs: vec!["x".into()],
            ..Default::default()
        };
        let cols = ["t", "x", "xb_acc"].map(String::from).to_vec();
        let p = plan(&opts, &cols, "k-1.csv").unwrap();
        let (mut all, _) = read_records(&paths, &p.required, Clipped::Error).unwrap();
        let held_out = all.pop().unwrap();
        // The selection alone: no displacement term (what this case is about).
        let plain = tfs::criteria::identify_tfs(&all, &p.spec).unwrap();
        let disp = |m: &tfs::library::Model| {
            m.equations[0]
                .terms
                .iter()
                .any(|t| t.term.to_string().starts_with("x^"))
        };
        assert!(
            !disp(&plain.model),
            "{snr} dB: the selection kept a displacement term; the case no longer tests the restore"
        );
        let id = identify(all, vec![], &opts, &p).unwrap();
        assert!(disp(&id.model), "{snr} dB: no restoring force came back");
        assert!(
            id.warnings.iter().any(|w| w.contains("fitted back")),
            "{snr} dB: the warnings do not say so: {:?}",
            id.warnings
        );
        let score = |m: &tfs::library::Model| {
            tfs::compare::score(m, &held_out)
                .map(|s| s.r_mse)
                .unwrap_or(f64::INFINITY)
        };
        let (before, after) = (score(&plain.model), score(&id.model));
        assert!(
            after < before,
            "{snr} dB: held-out R-MSE {after:.4e} with the restoring force, {before:.4e} without"
        );
    }
}
