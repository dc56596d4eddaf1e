//! Never-worse property, unstable starts and bad-input errors.

mod common;

use common::*;
use proptest::prelude::*;
use tfs_data::Record;
use tfs_refine::{RefineError, RefineOptions, choose_by_validation, refine};
use tfs_signal::Multisine;

const DT: f64 = 1e-3;

fn linear_truth() -> tfs_library::Model {
    let w = 2.0 * std::f64::consts::PI * 100.0;
    model(&[
        ("x", -w * w),
        ("x'", -0.06 * w),
        ("x^3", -2.0e4),
        ("u", 8.0e4),
    ])
}

fn train(seed: u64, n: usize) -> Record {
    let ms = Multisine::new(5.0, 200.0, 60, 1.0, n as f64 * DT, 0.1, seed).unwrap();
    measure(
        "train",
        &linear_truth(),
        sample(&ms, n, DT),
        DT,
        50.0,
        (0.0, 0.0),
        seed,
    )
}

fn quick() -> RefineOptions {
    RefineOptions {
        max_iterations: 15,
        ..RefineOptions::default()
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]
    #[test]
    fn never_worse_than_start(seed in 0u64..1000, pk in -0.3f64..0.3, pc in -0.9f64..2.0, p3 in -1.0f64..1.0, pg in -0.4f64..0.4) {
        let w = 2.0 * std::f64::consts::PI * 100.0;
        let start = model(&[("x", -w * w * (1.0 + pk)), ("x'", -0.06 * w * (1.0 + pc)), ("x^3", -2.0e4 * (1.0 + p3)), ("u", 8.0e4 * (1.0 + pg))]);
        let r = train(seed, 3000);
        let before = sim_rms(&start, &r);
        let out = refine(&start, std::slice::from_ref(&r), &quick()).unwrap();
        let after = sim_rms(&out.model, &r);
        prop_assert!(out.final_cost <= out.initial_cost);
        prop_assert!(after <= before, "after {} before {}", after, before);
        prop_assert_eq!(out.per_record[0].1, before);
        prop_assert_eq!(out.per_record[0].2, after);
        // Structure kept: same terms in the same order.
        let names = |m: &tfs_library::Model| m.equations[0].terms.iter().map(|t| t.term.clone()).collect::<Vec<_>>();
        prop_assert_eq!(names(&out.model), names(&start));
    }
}

#[test]
fn unstable_start_is_handled_without_panic() {
    // Negative damping: the start blows up in free run; multiple shooting keeps segments short.
    let w = 2.0 * std::f64::consts::PI * 100.0;
    let start = model(&[
        ("x", -w * w),
        ("x'", 0.5 * w),
        ("x^3", -2.0e4),
        ("u", 8.0e4),
    ]);
    let r = train(3, 3000);
    assert!(sim_rms(&start, &r).is_infinite() || sim_rms(&start, &r) > 1.0);
    let out = refine(&start, std::slice::from_ref(&r), &RefineOptions::default()).unwrap();
    println!(
        "unstable start: {} {:?}\n{:#}",
        out.message,
        out.per_record,
        out.model.history.last().unwrap().details
    );
    assert!(out.final_cost <= out.initial_cost);
    let c = -out.model.coef("x", &term("x'")).unwrap();
    assert!(c > 0.0, "damping {c} should become positive");
}

#[test]
fn returns_start_when_start_is_already_optimal_or_nothing_helps() {
    // With noise-free data and the true model the start cannot be beaten by much; whatever
    // happens, the cost must not increase and the message must say what was returned.
    let truth = linear_truth();
    let ms = Multisine::new(5.0, 200.0, 60, 1.0, 2.0, 0.1, 5).unwrap();
    let r = measure(
        "clean",
        &truth,
        sample(&ms, 2000, DT),
        DT,
        200.0,
        (0.0, 0.0),
        9,
    );
    let out = refine(&truth, std::slice::from_ref(&r), &quick()).unwrap();
    assert!(out.final_cost <= out.initial_cost);
    assert!(!out.message.is_empty());
    assert_eq!(
        out.model.history.last().unwrap().step,
        "refine (simulation error)"
    );
}

#[test]
fn bad_input_gives_clear_errors() {
    let m = linear_truth();
    let r = train(1, 500);
    // Empty record list.
    let e = refine(&m, &[], &RefineOptions::default()).unwrap_err();
    assert!(matches!(e, RefineError::Invalid { .. }), "{e}");
    assert!(e.to_string().contains("train"), "{e}");
    // Missing input column, named.
    let t = r.t().to_vec();
    let no_u = Record::new(
        "no_u",
        t.clone(),
        vec![("x".into(), r.column("x").unwrap().to_vec())],
    )
    .unwrap();
    let e = refine(&m, &[no_u], &RefineOptions::default()).unwrap_err();
    match &e {
        RefineError::MissingColumn { column, record, .. } => {
            assert_eq!(column, "u");
            assert_eq!(record, "no_u");
        }
        other => panic!("wrong error {other}"),
    }
    assert!(e.to_string().contains("'u'"));
    // DOF mismatch: the record calls the displacement "y".
    let wrong_dof = Record::new(
        "wrong_dof",
        t.clone(),
        vec![
            ("y".into(), r.column("x").unwrap().to_vec()),
            ("u".into(), r.column("u").unwrap().to_vec()),
        ],
    )
    .unwrap();
    let e = refine(
        &m,
        std::slice::from_ref(&wrong_dof),
        &RefineOptions::default(),
    )
    .unwrap_err();
    assert!(
        matches!(&e, RefineError::MissingColumn { column, .. } if column == "x"),
        "{e}"
    );
    let e = choose_by_validation(&m, &m, &[wrong_dof]).unwrap_err();
    assert!(e.to_string().contains("'x'"), "{e}");
    // Non-finite data: names column and row.
    let mut x = r.column("x").unwrap().to_vec();
    x[17] = f64::NAN;
    let nan = Record::new(
        "nan",
        t,
        vec![
            ("x".into(), x),
            ("u".into(), r.column("u").unwrap().to_vec()),
        ],
    )
    .unwrap();
    let e = refine(&m, &[nan], &RefineOptions::default()).unwrap_err();
    assert!(
        matches!(&e, RefineError::NonFinite { column, row: 17, .. } if column == "x"),
        "{e}"
    );
    // Too short and bad options.
    let short = r.slice(0..3).unwrap();
    assert!(refine(&m, &[short], &RefineOptions::default()).is_err());
    let bad = RefineOptions {
        substeps: 0,
        ..RefineOptions::default()
    };
    let e = refine(&m, std::slice::from_ref(&r), &bad).unwrap_err();
    assert!(e.to_string().contains("substeps"), "{e}");
    let bad = RefineOptions {
        defect_weights: vec![f64::NAN],
        ..RefineOptions::default()
    };
    assert!(refine(&m, std::slice::from_ref(&r), &bad).is_err());
    // Validation with no records.
    assert!(choose_by_validation(&m, &m, &[]).is_err());
}
