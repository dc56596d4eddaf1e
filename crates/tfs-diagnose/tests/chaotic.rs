//! A double-well Duffing oscillator `x'' = x − x³ − 0.25 x' − xb_acc` swept through chaotic
//! snap-through at 40 dB, with each effect of the catalogue hidden from the model `x, x^3, x',
//! xb_acc` in turn: the hidden effect must be reported first and significant. The free-run
//! simulation cannot rank models here (a fresh draw of the input's noise moves it as far as the
//! model's error), so the diagnosis must say it judged by something else.
//!
//! Dry friction, a Maxwell element and the cases that once failed run in CI; the whole catalogue
//! with `cargo test -p tfs-diagnose --test chaotic -- --ignored --nocapture` (another noise
//! draw: `TFS_CHAOTIC_SEED=700`). Effects the records cannot tell apart count as found when the
//! verdict names the hidden one as indistinguishable from the top one.

mod common;

use common::*;
use tfs_diagnose::{DiagnoseOptions, Judge, diagnose, refit};

/// The hidden Maxwell element's spring (see [`hidden_maxwell`]).
const MAXWELL_K: f64 = 0.15;

fn double_well(hidden: Vec<Hidden>) -> Truth {
    Truth {
        restoring: vec![(1, 1.0), (3, -1.0)],
        damping: 0.25,
        hidden,
        x0: 1.0,
    }
}

/// The first noise seed of the three records: 500, or `TFS_CHAOTIC_SEED` to repeat the study on
/// another noise draw.
fn first_seed() -> u64 {
    std::env::var("TFS_CHAOTIC_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(500)
}

/// Three 200 s sweeps 0.05 → 0.4 Hz of base acceleration (amplitudes 0.40, 0.45, 0.50) at
/// 20 samples a second, 40 dB on displacement and input (noise seeds `seed`, `seed + 1`, …).
fn records(truth: &Truth, seed: u64) -> Vec<tfs_data::Record> {
    (0..3)
        .map(|i| {
            record(
                truth,
                &format!("sweep{i}"),
                0.05,
                0.4,
                0.40 + 0.05 * i as f64,
                200.0,
                0.05,
                seed + i as u64,
            )
        })
        .collect()
}

/// What the diagnosis said about one hidden effect.
struct Outcome {
    top: String,
    significant: bool,
    /// The expected effect is significant and indistinguishable from the top one.
    tied: bool,
    judge: Option<Judge>,
    verdict: String,
}

impl Outcome {
    /// The hidden effect is reported first and significant, alone or with effects the records
    /// cannot tell from it (named in the verdict).
    fn found(&self, expect: &str) -> bool {
        (self.top == expect && self.significant) || self.tied
    }
}

fn row(label: &str, r: &tfs_diagnose::RankedEffect) {
    println!(
        "{label}:   {:<18} sig={} tied={} delta={:.3} p={:.1e} share={:.3} {:?} judge={:?} {:?} -> {:?}",
        r.name,
        r.significant,
        r.tied_with_top,
        r.delta_heldout,
        r.p_value,
        r.share,
        r.terms,
        r.judge,
        r.r_mse_before,
        r.r_mse_after
    );
}

/// Diagnoses the truth hiding `hidden` (expected to be found as `expect`) on the noise draw
/// `seed`.
fn case(label: &str, hidden: Hidden, expect: &str, seed: u64) -> Outcome {
    let train = records(&double_well(vec![hidden]), seed);
    let opts = DiagnoseOptions::default();
    let start = refit(&structure("x, x^3, x', xb_acc"), &train, &opts).unwrap();
    let t0 = std::time::Instant::now();
    let d = diagnose(&start, &train, &opts).unwrap();
    println!(
        "{label}: {:.1} s; {}",
        t0.elapsed().as_secs_f64(),
        d.verdict
    );
    for r in d.ranked.iter().take(6) {
        row(label, r);
    }
    if let Some(r) = d.ranked.iter().skip(6).find(|r| r.name == expect) {
        row(label, r);
        println!("{label}:     {}", r.reason);
    }
    println!("{label}: residual {}", d.residual_summary[0]);
    let top = &d.ranked[0];
    Outcome {
        top: top.name.clone(),
        significant: top.significant,
        tied: d.ranked.iter().any(|r| r.name == expect && r.tied_with_top),
        judge: top.judge,
        verdict: d.verdict.clone(),
    }
}

fn check(label: &str, hidden: Hidden, expect: &str, seed: u64) -> Outcome {
    let o = case(label, hidden, expect, seed);
    assert!(o.found(expect), "{label}: {}", o.verdict);
    // Whatever judged, the verdict names it when it is not the free run.
    if o.judge != Some(Judge::FreeRun) {
        assert!(o.verdict.contains("ranked by"), "{label}: {}", o.verdict);
    }
    o
}

#[test]
fn hidden_dry_friction() {
    check(
        "chaotic/dry-friction",
        Hidden::DryFriction {
            force: 0.05,
            eps: 0.01,
        },
        "dry-friction",
        500,
    );
}

/// The Maxwell spring is 0.15 (it was 0.1): on the noise-free records, a Maxwell element of
/// 0.1 changes the fitted force by 1.95 % of the force RMS when it joins the start library (its
/// part that `x` and `x'` cannot hold), below the diagnosis's 2 % minimum size, so it was found
/// at 40 dB only through a size the noise inflated (2.7 %); with the nonlinear columns band
/// limited like the acceleration the noisy records measure 1.7 %. At 0.15 the noise-free part is
/// 3.1 % and the 40 dB records measure 2.9 %.
#[test]
fn hidden_maxwell() {
    check(
        "chaotic/maxwell",
        Hidden::Maxwell {
            k: MAXWELL_K,
            tau: 1.0,
        },
        "maxwell",
        500,
    );
}

/// On the second noise draw the short-horizon judge's mean over the pieces was higher with dry
/// friction than without (2.78 against 2.28), and that vetoed it; the pieces do not bear the
/// difference out (paired tests), so it is no veto.
#[test]
fn hidden_dry_friction_second_draw() {
    check(
        "chaotic/dry-friction@700",
        Hidden::DryFriction {
            force: 0.05,
            eps: 0.01,
        },
        "dry-friction",
        700,
    );
}

/// Quadratic and cubic damping are nearly collinear over this motion (each hidden, the other
/// lowers the held-out equation error about as much). While the columns kept the harmonics the
/// smoothed acceleration had lost, the equation error tied them (cubic damping came first
/// without the short-horizon tie-break); with the columns band-limited like the acceleration,
/// the held-out equation error falls 70.0 % with quadratic damping and 67.4 % with cubic, and the
/// paired block test tells them apart. Either way the hidden one must come first, and cubic
/// damping, if significant, must be reported tied with it or behind it on the equation error.
#[test]
fn hidden_quadratic_damping_is_named_first() {
    let train = records(&double_well(vec![Hidden::Quadratic(0.3)]), 500);
    let opts = DiagnoseOptions::default();
    let start = refit(&structure("x, x^3, x', xb_acc"), &train, &opts).unwrap();
    let d = diagnose(&start, &train, &opts).unwrap();
    let top = &d.ranked[0];
    assert_eq!(top.name, "quadratic-damping", "{}", d.verdict);
    assert!(top.significant, "{}", d.verdict);
    let cubic = d.ranked.iter().find(|r| r.name == "cubic-damping").unwrap();
    assert!(
        !cubic.significant || cubic.tied_with_top || cubic.delta_heldout < top.delta_heldout,
        "{}",
        d.verdict
    );
    if cubic.tied_with_top {
        assert!(d.verdict.contains("indistinguishable"), "{}", d.verdict);
    }
}

/// No record is dominated by the input noise here, so the free run judges; but every
/// significant candidate's free run is worse than predicting the mean position (R-MSE above
/// 1), so it cannot order them: the equation error does (the end stop came first by free run).
#[test]
fn hidden_input_delay_with_a_free_run_without_skill() {
    check(
        "chaotic/input-delay",
        Hidden::Delay(0.3),
        "input-delay",
        500,
    );
}

/// The end stop's free run is worse than the model's without it (R-MSE 0.96 against 0.70), by
/// less than a fresh draw of the input's noise moves it: no veto.
#[test]
fn hidden_stop_within_the_free_run_resolution() {
    check(
        "chaotic/stop",
        Hidden::Stop { k: 20.0, at: -1.2 },
        "stop",
        500,
    );
}

/// The free run judges (no record is dominated by the input noise), but neither the start model
/// nor the one with the offset shows skill (R-MSE 3.5 and 5.4, both worse than predicting the
/// mean position): which is higher says where each run lost the motion, so it is no veto. With
/// the veto, nothing was reported here.
#[test]
fn hidden_offset_with_free_runs_without_skill() {
    check("chaotic/offset@1500", Hidden::Offset(0.05), "offset", 1500);
}

/// One of the three records is dominated by the input noise: the free-run mean carries that
/// noise, so the short horizon judges (by free run hysteresis came first, cubic damping's R-MSE
/// was 4.1).
#[test]
fn hidden_cubic_damping_second_draw() {
    check(
        "chaotic/cubic-damping@700",
        Hidden::CubicDamping(0.3),
        "cubic-damping",
        700,
    );
}

/// Every effect of the catalogue, hidden in turn, on the noise draw `TFS_CHAOTIC_SEED` (500).
#[test]
#[ignore = "full study, a few minutes; run with --ignored"]
fn every_catalogue_effect() {
    let cases = [
        (
            Hidden::DryFriction {
                force: 0.05,
                eps: 0.01,
            },
            "dry-friction",
        ),
        (
            Hidden::Maxwell {
                k: MAXWELL_K,
                tau: 1.0,
            },
            "maxwell",
        ),
        (Hidden::Quadratic(0.3), "quadratic-damping"),
        (Hidden::CubicDamping(0.3), "cubic-damping"),
        (Hidden::AmplitudeDamping(0.3), "amplitude-damping"),
        (
            Hidden::Stiffness {
                power: 2,
                coef: 0.15,
            },
            "stiffness-x^2",
        ),
        (Hidden::Offset(0.05), "offset"),
        (
            Hidden::BoucWen {
                k: 0.3,
                a: 2.0,
                b: 1.0,
                nu: 1.0,
            },
            "hysteresis",
        ),
        (Hidden::Delay(0.3), "input-delay"),
        (Hidden::InputFilter(0.3), "input-filter"),
        (Hidden::Stop { k: 20.0, at: -1.2 }, "stop"),
    ];
    let mut failures = Vec::new();
    for (hidden, expect) in cases {
        let label = format!("chaotic/{expect}");
        let o = case(&label, hidden, expect, first_seed());
        println!(
            "{label}: top {} sig {} tied {} judge {:?}",
            o.top, o.significant, o.tied, o.judge
        );
        if !o.found(expect) {
            failures.push(format!("{label}: {}", o.verdict));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Fits the double well with nothing hidden on the noise draw `seed` and prints the top rows.
fn control(seed: u64) -> tfs_diagnose::Diagnosis {
    let train = records(&double_well(Vec::new()), seed);
    let opts = DiagnoseOptions::default();
    let start = refit(&structure("x, x^3, x', xb_acc"), &train, &opts).unwrap();
    let d = diagnose(&start, &train, &opts).unwrap();
    println!("chaotic/control@{seed}: {}", d.verdict);
    for r in d.ranked.iter().take(3) {
        row(&format!("chaotic/control@{seed}"), r);
    }
    d
}

/// The double well with nothing hidden: no stiffness power is significant. A fifth or seventh
/// power lowers the held-out equation error by 3-7 % on every draw (corrected p 2e-3..8e-3) and
/// was reported while the short-horizon pieces were two dominant periods long — on this record
/// 400 s, the whole held-out record, where every prediction has lost its skill. Over the
/// start model's own predictability horizon (about 20-30 s here) it predicts worse and is
/// vetoed.
#[test]
fn control_reports_no_stiffness_power() {
    for seed in [500, 700] {
        let d = control(seed);
        let powers: Vec<&str> = d
            .ranked
            .iter()
            .filter(|r| r.significant && r.effect.starts_with("stiffness-x^"))
            .map(|r| r.name.as_str())
            .collect();
        assert!(
            powers.is_empty(),
            "control@{seed}: {powers:?}; {}",
            d.verdict
        );
        // The short horizon judged (the verdict names its pieces only when it reports an
        // effect).
        assert!(
            d.ranked
                .iter()
                .all(|r| r.judge == Some(Judge::ShortHorizon)),
            "{}",
            d.verdict
        );
    }
}

/// The double well with nothing hidden, on four noise draws: nothing is significant. A stop near
/// the largest displacement (`above(x, 1.43)`) lowers the held-out equation error by 1.6-3.1 % on
/// every draw (corrected block-test p 5e-7..2e-5, 2.5 % of the force RMS) and was reported:
/// the model holds the truth's terms exactly, so that drop is a bias of the equation error on
/// this motion. The same scan on the start model's own simulations of the records with the
/// estimated measurement noise finds the same drop or more, so the calibrated null takes it
/// back. `TFS_CONTROL_PRINT_ONLY=1` prints without asserting.
#[test]
fn control_has_no_significant_effect() {
    for seed in [700, 900, 1100, 500] {
        let d = control(seed);
        if std::env::var("TFS_CONTROL_PRINT_ONLY").is_err() {
            assert!(
                d.ranked.iter().all(|r| !r.significant),
                "control@{seed}: {}",
                d.verdict
            );
        }
    }
}
