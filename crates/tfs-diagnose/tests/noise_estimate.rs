//! The diagnosis' noise estimate against the noise's own effect: the residual of a model on
//! 40 dB records and on the same records without noise, at one cut-off, differ by what the
//! noise leaves; the estimate, made from the noisy records alone, must say about as much.

mod common;

use common::*;
use tfs_diagnose::{DiagnoseOptions, localise, refit};

/// A Duffing oscillator swept to amplitudes where its cubic term sets most of the local
/// stiffness, the model its own structure refitted on the noisy records: the estimated share
/// of `x''` the noise leaves is within a factor 1.5 of the measured one at every cut-off tried.
#[test]
fn the_noise_estimate_is_the_noise_s_own_share_on_a_nonlinear_model() {
    let truth = Truth {
        restoring: duffing_restoring(),
        damping: 0.63,
        hidden: vec![],
        x0: 0.0,
    };
    let amp = |i: u64| 4.0 * (0.8 + 0.2 * i as f64);
    let noisy: Vec<_> = (0..3)
        .map(|i| {
            record(
                &truth,
                &format!("r{i}"),
                0.3,
                3.0,
                amp(i),
                30.0,
                0.01,
                70 + i,
            )
        })
        .collect();
    let clean: Vec<_> = (0..3)
        .map(|i| clean_named(&truth, &format!("c{i}"), 0.3, 3.0, amp(i), 30.0, 0.01).0)
        .collect();
    let model = refit(
        &structure("x, x^3, x', xb_acc"),
        &noisy,
        &DiagnoseOptions::default(),
    )
    .unwrap();
    for fc in [4.0, 6.0, 9.0] {
        let opts = DiagnoseOptions {
            cutoff_hz: Some(fc),
            ..Default::default()
        };
        let on_noisy = &localise(&model, &noisy, &opts).unwrap()[0];
        let on_clean = &localise(&model, &clean, &opts).unwrap()[0];
        let (n, c) = (on_noisy.relative_rms, on_clean.relative_rms);
        let measured = (n * n - c * c).max(0.0).sqrt();
        let ratio = on_noisy.relative_noise / measured;
        println!(
            "cut-off {fc} Hz: residual {n:.4} on the noisy records, {c:.4} on the clean; noise's share {measured:.4}, estimated {:.4}",
            on_noisy.relative_noise
        );
        assert!(
            (0.67..1.5).contains(&ratio),
            "cut-off {fc} Hz: estimated {:.4} against {measured:.4}",
            on_noisy.relative_noise
        );
    }
}
