//! The diagnosis loop on Bouc–Wen hysteretic oscillators (`tfs_origami::BoucWenOscillator`):
//! the benchmark's published parameters and other sets, random-phase multisine training records,
//! a held-out multisine and a sine sweep for validation, noise-free and at 40 dB. Starting from
//! `x, x', u`, `diagnose` must rank hysteresis first without calling the residual noise; after
//! adding it and refining by simulation error the held-out sweep's free-run RMS error must be
//! below 0.5 % of its RMS, and α, βγ, βδ within 5 % of the truth.
//!
//! The full study (four parameter sets × two noise levels) is `#[ignore]`d for CI time; run it
//! with `cargo test -p tfs-diagnose --test hysteresis -- --ignored --nocapture`.

mod common;

use common::bouc_wen::data;

use tfs_data::Record;
use tfs_diagnose::{DiagnoseOptions, add_effect, diagnose, refit};
use tfs_dynamics::{SimulateOptions, rms_error, simulate_model_on_record};
use tfs_library::{Library, Model, StateLaw, Term};
use tfs_origami::BoucWenOscillator;
use tfs_refine::{RefineOptions, refine};

fn term(s: &str) -> Term {
    Term::parse(s, &["x"]).unwrap()
}

/// The identified physical parameters of a refined model `x'' = c_u u + c_v x' + c_x x + c_z z`
/// with `z = bouc_wen(x', a, b)`: (m, c, k, α, βγ, βδ) with `m = 1/c_u`.
fn physical(m: &Model) -> Option<[f64; 6]> {
    let eq = &m.equations[0];
    let cu = m.coef("x", &term("u")).ok()?;
    let mass = 1.0 / cu;
    let (mut cz, mut law) = (0.0, None);
    for t in &eq.terms {
        if let Some((_, l)) = t.term.states().first() {
            cz = t.coef;
            law = Some(**l);
        }
    }
    let Some(StateLaw::BoucWen { a, b, .. }) = law else {
        return None;
    };
    Some([
        mass,
        -m.coef("x", &term("x'")).ok()? * mass,
        -m.coef("x", &term("x")).ok()? * mass,
        -cz * mass,
        a,
        b,
    ])
}

struct Outcome {
    top: String,
    top_significant: bool,
    residual: String,
    sweep_error_share: f64,
    multisine_error_share: f64,
    params: Option<[f64; 6]>,
}

fn run(
    label: &str,
    bw: &BoucWenOscillator,
    rms: f64,
    snr: Option<f64>,
    train_on_sweeps: bool,
) -> Outcome {
    let (train, val, sw) = data(bw, rms, snr, train_on_sweeps);
    let opts = DiagnoseOptions::default();
    let lib = Library::parse("x, x', u", &["x"]).unwrap();
    let start = Model::from_coefficients(&lib, &[vec![1.0; 3]], "start").unwrap();
    let start = refit(&start, &train, &opts).unwrap();
    let t0 = std::time::Instant::now();
    let d = diagnose(&start, &train, &opts).unwrap();
    println!("{label}: diagnose {:.2} s", t0.elapsed().as_secs_f64());
    for r in d.ranked.iter().take(4) {
        println!(
            "{label}:   {:<16} sig={} delta={:.3} p={:.1e} terms={:?} judge={:?} {:?} -> {:?}",
            r.name,
            r.significant,
            r.delta_heldout,
            r.p_value,
            r.terms,
            r.judge,
            r.r_mse_before,
            r.r_mse_after
        );
    }
    println!("{label}: {}", d.verdict);
    println!("{label}: residual {}", d.residual_summary[0]);
    let added = add_effect(&start, "hysteresis", &train).unwrap();
    println!("{label}: added {}", added.equation_string());
    let refined = refine(&added, &train, &RefineOptions::default()).unwrap();
    println!(
        "{label}: refined {} ({})",
        refined.model.equation_string(),
        refined.message
    );
    let share = |m: &Model, r: &Record| {
        let tr = simulate_model_on_record(m, r, &SimulateOptions::default()).unwrap();
        let x = r.column("x").unwrap();
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let rms = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
        rms_error(x, &tr.x[0]).unwrap() / rms
    };
    let sweep_error_share = share(&refined.model, &sw);
    let multisine_error_share = share(&refined.model, &val);
    let params = physical(&refined.model);
    println!(
        "{label}: held-out noise-free sweep: free-run RMS error {:.3} % of its RMS (start {:.3} %), multisine {:.3} %; params {:?} truth [m {}, c {}, k {}, α {}, βγ {}, βδ {}]",
        100.0 * sweep_error_share,
        100.0 * share(&start, &sw),
        100.0 * multisine_error_share,
        params,
        bw.m,
        bw.c,
        bw.k,
        bw.alpha,
        bw.beta * bw.gamma,
        bw.beta * bw.delta
    );
    Outcome {
        top: d.ranked[0].name.clone(),
        top_significant: d.ranked[0].significant,
        residual: d.residual_summary[0].clone(),
        sweep_error_share,
        multisine_error_share,
        params,
    }
}

fn check(label: &str, bw: &BoucWenOscillator, o: &Outcome) {
    assert_eq!(o.top, "hysteresis", "{label}");
    assert!(o.top_significant, "{label}");
    assert!(
        !o.residual.contains("noise —") && !o.residual.contains("consistent with noise"),
        "{label}: {}",
        o.residual
    );
    assert!(
        o.sweep_error_share < 5e-3,
        "{label}: sweep error {}",
        o.sweep_error_share
    );
    let p = o.params.expect("a Bouc-Wen term");
    let truth = [bw.alpha, bw.beta * bw.gamma, bw.beta * bw.delta];
    for (name, (got, want)) in ["alpha", "beta*gamma", "beta*delta"]
        .iter()
        .zip(p[3..].iter().zip(truth))
    {
        assert!(
            ((got - want) / want).abs() < 0.05,
            "{label}: {name} {got} vs {want}"
        );
    }
}

/// The benchmark's parameters, noise-free: the CI-sized case.
#[test]
fn benchmark_noise_free() {
    let bw = BoucWenOscillator::benchmark();
    let o = run("benchmark/clean", &bw, 50.0, None, false);
    check("benchmark/clean", &bw, &o);
    assert!(o.multisine_error_share < 5e-3);
}

/// The benchmark's parameters at 40 dB on the displacement and the force.
#[test]
fn benchmark_40_db() {
    let bw = BoucWenOscillator::benchmark();
    let o = run("benchmark/40dB", &bw, 50.0, Some(40.0), false);
    check("benchmark/40dB", &bw, &o);
}

/// Three other parameter sets with saturating loops (γ + δ > 0, unlike the benchmark's
/// hardening one), resonances 19–32 Hz, forces chosen so the loop is well developed
/// (a·X of order 1 with X the displacement RMS), noise-free and at 40 dB; and the benchmark
/// trained on sine sweeps instead of multisines.
#[test]
#[ignore = "full study, about two minutes; run with --ignored"]
fn other_parameter_sets() {
    let sets = [
        (
            "soft",
            BoucWenOscillator {
                m: 1.0,
                c: 2.0,
                k: 1e4,
                alpha: 3e4,
                beta: 2e3,
                gamma: 0.6,
                delta: 0.4,
                nu: 1.0,
            },
            16.0,
        ),
        (
            "strong",
            BoucWenOscillator {
                m: 5.0,
                c: 20.0,
                k: 2e4,
                alpha: 8e4,
                beta: 5e3,
                gamma: 0.5,
                delta: 0.5,
                nu: 1.0,
            },
            40.0,
        ),
        (
            "light",
            BoucWenOscillator {
                m: 0.5,
                c: 1.0,
                k: 2e3,
                alpha: 5e3,
                beta: 500.0,
                gamma: 1.0,
                delta: -0.2,
                nu: 1.0,
            },
            7.0,
        ),
    ];
    for (name, bw, rms) in sets {
        for snr in [None, Some(40.0)] {
            let label = format!(
                "{name}/{}",
                snr.map_or("clean".into(), |s| format!("{s} dB"))
            );
            let o = run(&label, &bw, rms, snr, false);
            check(&label, &bw, &o);
        }
    }
    let bw = BoucWenOscillator::benchmark();
    for snr in [None, Some(40.0)] {
        let label = format!(
            "benchmark-sweeps/{}",
            snr.map_or("clean".into(), |s| format!("{s} dB"))
        );
        let o = run(&label, &bw, 50.0, snr, true);
        check(&label, &bw, &o);
    }
}

/// The benchmark noise-free on two training records at a time: fewer records leave the
/// calibrated null's synthetic draws fewer (some leave the records' range) and more spread, and
/// its prediction test alone could no longer tell a 99 % drop from the equation error's bias;
/// hysteresis must still be named first and significant on every pair.
#[test]
fn benchmark_noise_free_on_two_records() {
    let bw = BoucWenOscillator::benchmark();
    let (train, _, _) = data(&bw, 50.0, None, false);
    let opts = DiagnoseOptions::default();
    let lib = Library::parse("x, x', u", &["x"]).unwrap();
    for pair in [[0, 1], [1, 2], [3, 4]] {
        let recs: Vec<Record> = pair.iter().map(|&i| train[i].clone()).collect();
        let start = Model::from_coefficients(&lib, &[vec![1.0; 3]], "start").unwrap();
        let start = refit(&start, &recs, &opts).unwrap();
        let d = diagnose(&start, &recs, &opts).unwrap();
        let top = &d.ranked[0];
        println!(
            "{pair:?}: {} sig={} {}",
            top.name, top.significant, top.reason
        );
        assert_eq!(top.name, "hysteresis", "records {pair:?}: {}", d.verdict);
        assert!(top.significant, "records {pair:?}: {}", top.reason);
    }
}
