//! Tied chain identification on the two-cell Kresling chain with the truss truth (paper §3.2).

use tfs_criteria::{IdentifySpec, MassChoice, TieOptions, chain_ties, identify_tfs_tied};
use tfs_data::Record;
use tfs_library::{Model, Term};
use tfs_origami::{
    CellSpec, DatasetConfig, Excitation, KreslingParams, NoiseKind, SystemSpec, Truth,
    build_system, generate,
};

const LIB1: &str = "x1^1..7, x1', (x2-x1)^1..7, (x2-x1)', xb_acc";
const LIB2: &str = "(x2-x1)^1..7, (x2-x1)', xb_acc";
/// Largest allowed distance between an identified and a true stable state of a cell.
const TOL: f64 = 0.05;

fn spec() -> SystemSpec {
    let cell = |g: f64| CellSpec {
        params: KreslingParams {
            gamma0_deg: g,
            ..Default::default()
        },
        truth: Truth::Truss,
        ..Default::default()
    };
    SystemSpec::Chain {
        cells: vec![cell(20.0), cell(28.5)],
    }
}

/// Base-acceleration sweeps (f0, f1, duration, amplitude) that carry cell 2 across its barrier.
const SWEEPS: [(f64, f64, f64, f64); 4] = [
    (0.05, 1.5, 50.0, 1.5),
    (0.05, 1.5, 30.0, 2.0),
    (0.1, 1.2, 40.0, 2.5),
    (0.05, 2.0, 60.0, 3.0),
];

fn records(snr: f64, seed: u64) -> Vec<Record> {
    SWEEPS
        .iter()
        .enumerate()
        .map(|(i, &(f0, f1, d, a))| {
            let cfg = DatasetConfig {
                system: spec(),
                excitations: vec![Excitation::Sweep {
                    f0,
                    f1,
                    amplitude: a,
                    log: false,
                    ramp: 0.0,
                }],
                duration: d,
                dt: 0.005,
                snr_db: Some(snr),
                noise: NoiseKind::White,
                seed: seed + 31 * i as u64,
                x0: None,
                v0: None,
                rtol: 1e-9,
            };
            generate(&cfg).unwrap().records.remove(0)
        })
        .collect()
}

fn coef(m: &Model, dof: &str, term: &str) -> f64 {
    let t = Term::parse(term, &["x1", "x2"]).unwrap();
    m.coef(dof, &t).unwrap_or(0.0)
}

fn pw(v: &str, k: usize) -> String {
    if k == 1 {
        v.to_string()
    } else {
        format!("{v}^{k}")
    }
}

/// Restoring force per unit mass of cell `c` in the model: minus the cell's own polynomial terms
/// (`x1^k` in x1'', `(x2-x1)^k` in x2'').
fn model_force(m: &Model, c: usize, h: f64) -> f64 {
    (1..=7)
        .map(|k| {
            let a = if c == 0 {
                coef(m, "x1", &pw("x1", k))
            } else {
                coef(m, "x2", &pw("(x2-x1)", k))
            };
            -a * h.powi(k as i32)
        })
        .sum()
}

/// Stable states of a force law on a grid: zeros where the force rises through zero.
fn stable_states(f: impl Fn(f64) -> f64, lo: f64, hi: f64) -> Vec<f64> {
    let n = 4000;
    let h = |i: usize| lo + (hi - lo) * i as f64 / n as f64;
    let mut out = Vec::new();
    for i in 0..n {
        let (a, b) = (f(h(i)), f(h(i + 1)));
        if a < 0.0 && b >= 0.0 {
            // Bisection.
            let (mut l, mut r) = (h(i), h(i + 1));
            for _ in 0..60 {
                let mid = 0.5 * (l + r);
                if f(mid) < 0.0 { l = mid } else { r = mid }
            }
            out.push(0.5 * (l + r));
        }
    }
    out
}

/// Range of cell `c`'s relative displacement in the measured records.
fn visited(recs: &[Record], c: usize) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for r in recs {
        let x1 = r.column("x1").unwrap();
        let x2 = r.column("x2").unwrap();
        for (a, b) in x1.iter().zip(x2) {
            let h = if c == 0 { *a } else { b - a };
            lo = lo.min(h);
            hi = hi.max(h);
        }
    }
    (lo, hi)
}

fn check(snr: f64, seed: u64) {
    let recs = records(snr, seed);
    let mut sp = IdentifySpec::new(&["x1", "x2"], LIB1);
    sp.dof_libraries = vec![LIB1.to_string(), LIB2.to_string()];
    let ties = chain_ties(&sp).unwrap();
    assert_eq!(ties.len(), 8, "seven (x2-x1)^k and (x2-x1)' are shared");
    let id = identify_tfs_tied(&recs, &sp, &TieOptions::default()).unwrap();
    let m = &id.model;
    eprintln!("{snr} dB:\n{}", m.equation_string());
    // The tied fit reports Criterion 1 per DOF, like the single-DOF pipeline, and finds the data
    // sufficient for the library at these noise levels.
    for d in &id.trace.dofs {
        let c1 = d
            .criterion1
            .as_ref()
            .expect("criterion 1 in the tied trace");
        assert!(c1.kappa0 > 0.0 && c1.kappa.get(c1.variant) > 0.0);
        assert!(c1.support.is_supported(), "{}: {}", d.dof, c1.support);
    }
    // Tied: every (x2-x1) term of x1'' is minus its coefficient in x2''.
    for t in &ties {
        let (a, b) = (coef(m, "x1", &t.term), coef(m, "x2", &t.term));
        assert!(
            (a + b).abs() <= 1e-12 * b.abs().max(1.0),
            "{}: {a} vs {b}",
            t.term
        );
    }
    let truth = build_system(&spec()).unwrap();
    for c in 0..2 {
        // A polynomial model only speaks for the range of relative displacement the training
        // data visited (measured, noisy signals); search its stable states there.
        let (lo, hi) = visited(&recs, c);
        assert!(
            lo < 0.05 && hi > 1.6,
            "cell {} visited only [{lo}, {hi}]",
            c + 1
        );
        let (want, _) = truth.cells()[c].force_law().equilibria();
        let got = stable_states(|h| model_force(m, c, h), lo, hi);
        eprintln!("cell {}: truth {want:?}, model {got:?}", c + 1);
        assert_eq!(
            got.len(),
            want.len(),
            "cell {} stable states {got:?} vs truth {want:?}",
            c + 1
        );
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (g - w).abs() <= TOL,
                "cell {} stable state {g} vs truth {w}",
                c + 1
            );
        }
    }
}

#[test]
fn chain_60db_cell1_monostable_cell2_bistable() {
    check(60.0, 500);
}

#[test]
fn chain_30db_cell1_monostable_cell2_bistable() {
    check(30.0, 600);
}

fn chain_spec() -> IdentifySpec {
    let mut sp = IdentifySpec::new(&["x1", "x2"], LIB1);
    sp.dof_libraries = vec![LIB1.to_string(), LIB2.to_string()];
    sp
}

#[test]
fn ties_are_cell_2_terms_owned_by_x2() {
    let ties = chain_ties(&chain_spec()).unwrap();
    let mut names: Vec<String> = ties.iter().map(|t| t.term.clone()).collect();
    names.sort();
    let mut want: Vec<String> = (1..=7).map(|k| pw("(x2-x1)", k)).collect();
    want.push("(x2-x1)'".into());
    want.sort();
    assert_eq!(names, want);
    assert!(ties.iter().all(|t| t.owner == 1 && t.partner == 0));
    // A library without the coupling in x1's equation has nothing to tie.
    let mut sp = chain_spec();
    sp.dof_libraries[0] = "x1^1..7, x1', xb_acc".into();
    assert!(chain_ties(&sp).unwrap().is_empty());
}

#[test]
fn untieable_spec_and_bad_masses_are_errors() {
    let recs = records(60.0, 700);
    let mut sp = chain_spec();
    sp.dof_libraries[0] = "x1^1..7, x1', xb_acc".into();
    let e = identify_tfs_tied(&recs, &sp, &TieOptions::default()).unwrap_err();
    assert!(e.to_string().contains("identify_tfs"), "{e}");
    for m in [
        MassChoice::Given(vec![1.0]),
        MassChoice::Given(vec![1.0, -1.0]),
        MassChoice::Estimate { candidates: vec![] },
    ] {
        let e = identify_tfs_tied(&recs, &chain_spec(), &TieOptions::new(m)).unwrap_err();
        assert!(e.to_string().contains("tie.masses"), "{e}");
    }
}

#[test]
fn mass_scan_finds_equal_masses_and_given_ratio_scales_the_tie() {
    let recs = records(60.0, 800);
    let sp = chain_spec();
    // Ratios a factor of two apart: the scan's held-out errors separate those clearly, while
    // 0.8 and 1.0 score within 0.1 % of each other on these records (the scan cannot resolve
    // a mass ratio more finely than that).
    let id = identify_tfs_tied(
        &recs,
        &sp,
        &TieOptions::new(MassChoice::Estimate {
            candidates: vec![0.5, 1.0, 2.0],
        }),
    )
    .unwrap();
    assert_eq!(id.trace.tied.as_ref().unwrap().masses, vec![1.0, 1.0]);
    // With m2/m1 = 2 given, every tied coefficient of x1'' is −2 × its x2'' value.
    let id = identify_tfs_tied(
        &recs,
        &sp,
        &TieOptions::new(MassChoice::Given(vec![1.0, 2.0])),
    )
    .unwrap();
    for t in chain_ties(&sp).unwrap() {
        let (a, b) = (
            coef(&id.model, "x1", &t.term),
            coef(&id.model, "x2", &t.term),
        );
        assert!(
            (a + 2.0 * b).abs() <= 1e-12 * b.abs().max(1.0),
            "{}: {a} vs {b}",
            t.term
        );
    }
}
