use super::*;

fn eq(p: f64, delta: f64, share: f64) -> EquationEvidence {
    EquationEvidence {
        p_raw: p / 10.0,
        p,
        tests: 10,
        delta,
        share,
    }
}

fn prediction(before: f64, after: Option<f64>) -> PredictionEvidence {
    PredictionEvidence {
        judge: Judge::FreeRun,
        before: Some(before),
        after,
        worse: None,
        better_by: None,
        floor: 0.0,
        removes_most: false,
        judged_at: None,
    }
}

fn with(e: EquationEvidence, p: Option<PredictionEvidence>, n: Option<NullEvidence>) -> Evidence {
    let mut ev = Evidence::new(e);
    if let Some(p) = p {
        ev.record_prediction(p);
    }
    if let Some(n) = n {
        ev.record_null(n);
    }
    ev
}

/// By equation error alone the three conditions decide, the fall first, then the test, then
/// the size; each failure has its own reason and words.
#[test]
fn the_equation_error_decides_alone_without_simulations() {
    let o = DiagnoseOptions::default();
    let cases = [
        (
            eq(1e-5, 0.3, 0.1),
            Significance::Significant,
            "held-out equation error falls 30.0 %",
        ),
        (
            eq(1e-5, -0.1, 0.1),
            Significance::NoFall,
            "held-out equation error does not fall",
        ),
        (
            eq(0.5, 0.3, 0.1),
            Significance::NotSignificant,
            "not significant: corrected p",
        ),
        (
            eq(1e-5, 0.3, 0.001),
            Significance::TooSmall,
            "significant but too small",
        ),
    ];
    for (e, want, words) in cases {
        let ev = Evidence::new(e);
        assert_eq!(ev.significance(&o), want);
        assert_eq!(
            ev.significance(&o).is_significant(),
            want == Significance::Significant
        );
        assert!(ev.reason(&o).starts_with(words), "{}", ev.reason(&o));
    }
}

/// The judge takes significance from an effect that predicts worse or cannot be simulated, and
/// gives it to one under the size whose model predicts better: neither clears the other's part.
#[test]
fn the_judge_vetoes_a_worse_model_and_admits_a_small_force_large_on_the_motion() {
    let o = DiagnoseOptions::default();
    let worse = PredictionEvidence {
        worse: Some(true),
        ..prediction(0.1, Some(0.3))
    };
    let ev = with(eq(1e-5, 0.3, 0.1), Some(worse.clone()), None);
    assert_eq!(ev.significance(&o), Significance::PredictsWorse);
    assert!(ev.reason(&o).contains(
        "predicts the held-out data worse (free-run simulation R-MSE 3.000e-1 vs 1.000e-1)"
    ));
    // The scan's part is still there, untouched.
    assert_eq!(ev.equation().share, 0.1);
    let failed = PredictionEvidence {
        worse: Some(true),
        ..prediction(0.1, None)
    };
    let ev = with(eq(1e-5, 0.3, 0.1), Some(failed), None);
    assert_eq!(ev.significance(&o), Significance::CannotBeSimulated);
    // Worse, but not significant by equation error: the veto has nothing to take.
    let ev = with(eq(0.5, 0.3, 0.1), Some(worse), None);
    assert_eq!(ev.significance(&o), Significance::NotSignificant);
    // Under the size, but better on the motion.
    let better = PredictionEvidence {
        better_by: Some(0.05),
        ..prediction(0.1, Some(0.01))
    };
    let ev = with(eq(1e-5, 0.3, 0.001), Some(better.clone()), None);
    assert_eq!(ev.significance(&o), Significance::SignificantOnTheMotion);
    assert!(
        ev.reason(&o)
            .contains("better by 5.0 % of the motion's RMS"),
        "{}",
        ev.reason(&o)
    );
    // Better on the motion needs the test and the fall all the same.
    let ev = with(eq(0.5, 0.3, 0.001), Some(better.clone()), None);
    assert_eq!(ev.significance(&o), Significance::NotSignificant);
    // Worse by the free run's score and better by the rescue's (short-horizon tests can say
    // both): the better prediction admits it.
    let both = PredictionEvidence {
        worse: Some(true),
        ..better
    };
    let ev = with(eq(1e-5, 0.3, 0.1), Some(both), None);
    assert_eq!(ev.significance(&o), Significance::SignificantOnTheMotion);
}

/// The null takes significance only from a candidate the judge left significant, says why in
/// its own words, and an exempt or cleared candidate keeps its significance with the null's
/// words appended.
#[test]
fn the_null_vetoes_within_its_draws_and_annotates_the_rest() {
    let o = DiagnoseOptions::default();
    let passed = prediction(0.1, Some(0.09));
    let within = NullEvidence::Tested {
        draws: 8,
        mean: 0.25,
        sd: 0.05,
        p: 0.4,
    };
    let ev = with(eq(1e-5, 0.3, 0.1), Some(passed.clone()), Some(within));
    assert_eq!(ev.judged(&o), Significance::Significant);
    assert_eq!(ev.significance(&o), Significance::WithinTheNull);
    assert_eq!(
        ev.reason(&o),
        "held-out equation error falls 30.0 %, but on 8 simulations of the start model with the estimated measurement noise it falls 25.0 ± 5.0 %: not beyond what the equation error's own bias gives with nothing missing (corrected p = 4.00e-1 >= alpha = 0.01)"
    );
    let beyond = NullEvidence::Tested {
        draws: 8,
        mean: 0.02,
        sd: 0.01,
        p: 1e-6,
    };
    let ev = with(eq(1e-5, 0.3, 0.1), Some(passed.clone()), Some(beyond));
    assert_eq!(ev.significance(&o), Significance::Significant);
    assert!(
        ev.reason(&o)
            .ends_with("falls 2.0 ± 1.0 % (corrected p = 1.00e-6)"),
        "{}",
        ev.reason(&o)
    );
    let cleared = NullEvidence::Clears {
        draws: 8,
        largest: 1.0,
        measured: 4.0,
    };
    let ev = with(eq(1e-5, 0.3, 0.1), Some(passed.clone()), Some(cleared));
    assert_eq!(ev.significance(&o), Significance::Significant);
    assert!(
        ev.reason(&o)
            .contains("(at most 25.0 % of the measured one)")
    );
    let ev = with(
        eq(1e-5, 0.3, 0.1),
        Some(passed),
        Some(NullEvidence::RemovesMost),
    );
    assert!(
        ev.reason(&o)
            .contains("the calibrated null does not re-judge it")
    );
    assert_eq!(ev.significance(&o), Significance::Significant);
}

/// The judge's choice of a shortlisted variant is said after the judge's words, whatever the
/// decision.
#[test]
fn a_judged_alternative_is_named_in_the_reason() {
    let o = DiagnoseOptions::default();
    let at = PredictionEvidence {
        judged_at: Some(JudgedAt {
            parameter: ("position".into(), 0.25),
            shortlist: 3,
        }),
        ..prediction(0.1, Some(0.09))
    };
    let ev = with(eq(0.5, 0.3, 0.1), Some(at), None);
    assert!(ev.reason(&o).ends_with("; judged at position = 0.25, of the 3 values with the lowest held-out residual the one whose model predicts the held-out data best (`refit` chooses it so)"), "{}", ev.reason(&o));
}

/// The typed reason reads as kebab-case in JSON and in words in reports.
#[test]
fn the_typed_reason_serialises_in_kebab_case() {
    let json = serde_json::to_string(&Significance::SignificantOnTheMotion).unwrap();
    assert_eq!(json, "\"significant-on-the-motion\"");
    assert_eq!(
        Significance::WithinTheNull.to_string(),
        "within what the equation error's bias gives"
    );
}

/// A stage writes its part once: a second write is a bug in the orchestration.
#[test]
#[cfg(debug_assertions)]
#[should_panic(expected = "writes its part once")]
fn a_stage_writes_its_part_once() {
    let mut ev = Evidence::new(eq(1e-5, 0.3, 0.1));
    ev.record_null(NullEvidence::RemovesMost);
    ev.record_null(NullEvidence::RemovesMost);
}
