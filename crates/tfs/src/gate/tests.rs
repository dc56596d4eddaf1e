//! Tests of the simulations' say on the diagnosis and the loop.

use super::*;

#[test]
fn a_p_value_that_underflows_reads_as_a_bound() {
    assert_eq!(p_text(0.0), "p < 1e-300");
    assert_eq!(p_text(3.14e-5), "p = 3.14e-5");
}

fn s(failed: usize, mean: f64) -> SimScore {
    SimScore {
        failed,
        records: 4,
        mean_r_mse: mean,
    }
}

/// The candidate with the fewest failing records wins over one with a lower mean R-MSE on
/// fewer records; among equals the first (the diagnosis's order) wins; one that leaves as
/// many failing as the model without it is not chosen; candidates that could not be added
/// are skipped.
#[test]
fn the_candidate_that_makes_the_most_records_simulate_is_chosen() {
    let before = s(3, 1.0);
    let scores = [
        Some(s(3, 0.1)),
        None,
        Some(s(0, 6.5)),
        Some(s(2, 0.5)),
        Some(s(0, 6.5)),
    ];
    assert_eq!(fewest_failing(&before, &scores), Some(2));
    let lower = [Some(s(1, 9.0)), Some(s(1, 2.0))];
    assert_eq!(fewest_failing(&before, &lower), Some(1));
    let none_better = [Some(s(3, 0.01)), None, Some(s(4, f64::INFINITY))];
    assert_eq!(fewest_failing(&before, &none_better), None);
    assert_eq!(fewest_failing(&before, &[None, None]), None);
    // A model that simulates every record cannot be improved on in this sense.
    assert_eq!(fewest_failing(&s(0, 0.2), &[Some(s(0, 0.01))]), None);
}

/// A candidate that makes a record fail which simulated before worsens the model whatever
/// the others' R-MSE; so does one that raises the mean R-MSE with as many failing; one
/// that makes a record simulate, or lowers the mean, does not.
#[test]
fn a_candidate_that_makes_a_record_fail_or_the_error_rise_worsens_the_model() {
    assert!(worsens(&s(0, 0.1), &s(1, 0.05)));
    assert!(worsens(&s(0, 0.1), &s(0, 0.5)));
    assert!(!worsens(&s(2, 0.1), &s(1, 0.5)));
    assert!(!worsens(&s(0, 0.1), &s(0, 0.05)));
}

/// A one-DOF T-F-S model whose stop term has the interval and term test `interval`, `dof`.
fn with_stop(interval: [f64; 2], term_test: bool) -> (Model, StopRescan) {
    let test = if term_test {
        serde_json::json!({"candidates": 9, "dof": 20.0, "interval_dof": {"below(x, 0)": 5.0}})
    } else {
        serde_json::json!(null)
    };
    let json = serde_json::json!({"format": "tfs-model/1", "dofs": ["x"], "inputs": [], "method": "tfs-sindy",
        "trace": {"dofs": [{"term_test": test}]},
        "equations": [{"dof": "x", "terms": [{"term": "x", "coef": -1.0},
            {"term": "below(x, 0)", "coef": 100.0, "interval": interval}]}]});
    let model = Model::from_json_str(&json.to_string()).unwrap();
    let stop = StopRescan {
        from: "below(x, 0.01)".into(),
        to: "below(x, 0)".into(),
        coef: 100.0,
        kept: true,
        positions: 48,
        why: String::new(),
    };
    (model, stop)
}

/// T-F-S's evidence for a stop: a coefficient many standard errors from zero passes even
/// after the correction over the library and the positions; one whose interval nearly
/// reaches zero (significant alone, at 95 %) does not once corrected; the correction grows
/// with the positions scanned; without a term test there is no p value.
#[test]
fn the_stops_tfs_p_value_is_corrected_over_terms_and_positions() {
    let (tight, stop) = with_stop([95.0, 105.0], true);
    let p = tfs_stop_p_value(&tight, &stop).unwrap();
    assert!(p < 1e-6, "{p}");
    let (wide, stop) = with_stop([5.0, 195.0], true);
    let p_wide = tfs_stop_p_value(&wide, &stop).unwrap();
    assert!(p_wide > 0.01, "{p_wide}");
    let (mid, mut stop) = with_stop([60.0, 140.0], true);
    let p48 = tfs_stop_p_value(&mid, &stop).unwrap();
    stop.positions = 1;
    let p1 = tfs_stop_p_value(&mid, &stop).unwrap();
    assert!(
        p1 < p48 && (p48 / p1 - 48.0).abs() < 1e-6 * 48.0,
        "{p1} {p48}"
    );
    let (untested, stop) = with_stop([95.0, 105.0], false);
    assert!(tfs_stop_p_value(&untested, &stop).is_none());
}

/// Two clean records of `x'' = −x − 0.1·x' − 0.5·x³ + u` under multisines, and the model
/// without the dashpot fitted to them.
fn undamped_start() -> (Model, Vec<Record>) {
    let truth = Model::from_json_str(
        &serde_json::json!({"format": "tfs-model/1", "dofs": ["x"], "inputs": ["u"],
            "equations": [{"dof": "x", "terms": [{"term": "x", "coef": -1.0},
                {"term": "x'", "coef": -0.1}, {"term": "x^3", "coef": -0.5},
                {"term": "u", "coef": 1.0}]}]})
        .to_string(),
    )
    .unwrap();
    let dt = 0.02;
    let t: Vec<f64> = (0..2000).map(|k| k as f64 * dt).collect();
    let records: Vec<Record> = [(0.7, 1.3), (0.5, 1.9)]
        .iter()
        .enumerate()
        .map(|(i, &(f1, f2))| {
            let u: Vec<f64> = t
                .iter()
                .map(|&t| (f1 * t).sin() + 0.6 * (f2 * t + 0.4).sin())
                .collect();
            let tr = crate::simulate::simulate_model(&truth, &t, vec![u.clone()], &[0.0], &[0.0])
                .unwrap();
            let cols = vec![("x".to_string(), tr.x[0].clone()), ("u".to_string(), u)];
            Record::new(format!("r{i}"), t.clone(), cols).unwrap()
        })
        .collect();
    let mut start = truth.clone();
    start.equations[0]
        .terms
        .retain(|t| t.term.to_string() != "x'");
    let start = tfs_diagnose::refit(&start, &records, &DiagnoseOptions::default()).unwrap();
    (start, records)
}

/// A significant candidate as the free run judged it.
fn candidate(name: &str) -> RankedEffect {
    RankedEffect {
        name: name.into(),
        effect: name.into(),
        dof: "x".into(),
        parameter: None,
        terms: Vec::new(),
        significant: true,
        p_value_raw: 1e-9,
        p_value: 1e-8,
        delta_heldout: 0.5,
        coef: 0.0,
        interval: [0.0, 0.0],
        share: 0.1,
        judge: Some(Judge::FreeRun),
        r_mse_before: None,
        r_mse_after: None,
        tied_with_top: false,
        reason: String::new(),
    }
}

/// The diagnosis names what the loop would add: a top candidate the refit cannot make is
/// passed over, with the reason, for the next significant one (the missing dashpot, which
/// makes the records simulate better); when the top one is supported the simulations have
/// nothing to add to the ranking; candidates the free run did not judge are not simulated.
#[test]
fn the_diagnosis_names_the_first_candidate_the_simulations_support() {
    let (start, records) = undamped_start();
    let opts = DiagnoseOptions::default();
    let cat = Catalogue::standard(opts.max_power);
    let ranked = vec![candidate("no-such-effect"), candidate("linear-damping")];
    let (report, chosen) = supported_choice(&start, &ranked, &records, &cat, &opts).unwrap();
    let chosen = chosen.unwrap();
    assert_eq!(chosen.effect, "linear-damping");
    assert_eq!(report.tried.len(), 2);
    assert!(report.tried[0].error.is_some() && report.tried[1].score.is_some());
    assert!(chosen.score.key() < report.before.key(), "{report:?}");
    assert!(
        report
            .why
            .contains("no-such-effect passed over: it could not be added")
            && report
                .why
                .contains("linear-damping is the next significant"),
        "{}",
        report.why
    );
    let gate = (report, Some(chosen));
    assert_eq!(named(&ranked, Some(&gate)), Some("linear-damping"));
    // The top one supported: the ranking's verdict stands.
    assert!(supported_choice(&start, &ranked[1..], &records, &cat, &opts).is_none());
    // Not judged by the free run: nothing is simulated.
    let mut short = ranked.clone();
    short
        .iter_mut()
        .for_each(|r| r.judge = Some(Judge::ShortHorizon));
    assert!(supported_choice(&start, &short, &records, &cat, &opts).is_none());
}

/// When the simulations pass over every significant candidate of a model that simulates
/// its records, the verdict names none and says why; when the model fails some records
/// and no candidate helps, the ranking's top one is still what the verdict names.
#[test]
fn a_verdict_whose_candidates_were_all_passed_over_names_none() {
    let ranked = vec![candidate("maxwell")];
    let report = |failed| GateReport {
        before: s(failed, 0.1),
        refitted: None,
        tried: Vec::new(),
        chosen: None,
        then: Vec::new(),
        why: "maxwell passed over".into(),
    };
    let passed = (report(0), None);
    assert_eq!(named(&ranked, Some(&passed)), None);
    let failing = (report(2), None);
    assert_eq!(named(&ranked, Some(&failing)), Some("maxwell"));
    assert_eq!(named(&ranked, None), Some("maxwell"));
    let d = Diagnosis {
        ranked,
        verdict: "missing effect: maxwell".into(),
        residual_summary: Vec::new(),
        records: Vec::new(),
        localisation: Vec::new(),
        tests: 1,
        cutoff_hz: Vec::new(),
    };
    let v = verdict(&d, Some(&passed));
    assert!(
        v.starts_with("no missing effect that the simulations support (maxwell passed over"),
        "{v}"
    );
    assert_eq!(verdict(&d, Some(&failing)), d.verdict);
}

/// The words say how many records fail of how many, and the mean where there is one.
#[test]
fn the_score_is_described_in_words() {
    assert!(s(0, 0.25).describe().starts_with("all 4 records simulate"));
    assert_eq!(
        s(4, f64::INFINITY).describe(),
        "all 4 records fail to simulate"
    );
    let one = SimScore {
        failed: 0,
        records: 1,
        mean_r_mse: 0.25,
    };
    assert_eq!(one.describe(), "the record simulates (R-MSE 2.5000e-1)");
    let one = SimScore { failed: 1, ..one };
    assert_eq!(one.describe(), "the record fails to simulate");
    let two = s(2, 0.5).describe();
    assert!(
        two.starts_with("2 of 4 records fail") && two.contains("5.0000e-1"),
        "{two}"
    );
}

/// A model that fails to simulate only because its coefficients are off (nothing is missing
/// from its terms: the cubic spring's sign is flipped, so the records carry it out of its
/// well) is not given an effect: every candidate's model is the start's terms refitted with
/// it, and those terms refitted alone already make the records simulate. Without that control
/// any candidate that can be added would be chosen.
#[test]
fn a_failure_that_the_refit_alone_cures_names_no_effect() {
    let (fitted, records) = undamped_start();
    let opts = DiagnoseOptions::default();
    let cat = Catalogue::standard(opts.max_power);
    let mut notes = crate::refit::AddNotes::default();
    let mut start =
        crate::refit::add_one(&fitted, "linear-damping", &records, &cat, &opts, &mut notes)
            .unwrap();
    start.history.clear();
    for t in &mut start.equations[0].terms {
        if t.term.to_string() == "x^3" {
            t.coef = -t.coef;
        }
    }
    assert!(SimScore::of(&start, &records).failed > 0);
    let ranked = vec![candidate("cubic-damping"), candidate("dry-friction")];
    let (report, chosen) = simulation_choice(&start, &ranked, &records, &cat, &opts, true)
        .unwrap()
        .unwrap();
    let refitted = report.refitted.unwrap();
    assert_eq!(refitted.failed, 0, "{report:?}");
    // The candidates make the records simulate too, but no better than the refit alone.
    assert!(
        report
            .tried
            .iter()
            .any(|t| t.score.is_some_and(|s| s.failed < report.before.failed)),
        "{report:?}"
    );
    assert!(chosen.is_none(), "{report:?}");
    assert!(report.why.contains("the start fit's"), "{}", report.why);
}
