//! Tests of the one decision: what diagnose names and the loop adds.

use super::*;
use tfs_diagnose::{EquationEvidence, Evidence, Judge, Significance};

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
        significance: Significance::Significant,
        evidence: Evidence::new(EquationEvidence {
            p_raw: 1e-9,
            p: 1e-8,
            tests: 10,
            delta: 0.5,
            share: 0.1,
        }),
    }
}

fn decide_default(start: &Model, ranked: &[RankedEffect], records: &[Record]) -> Decision {
    let opts = DiagnoseOptions::default();
    decide(start, ranked, records, &opts, &DecideOptions::diagnose()).unwrap()
}

/// The decision names what the loop adds: a top candidate the refit cannot make is passed over,
/// with the reason, for the next significant one (the missing dashpot, which makes the records
/// simulate better); the top one supported is what the ranking names, and its verdict stands;
/// a candidate the short horizon judged is held to the same simulations as one the free run
/// judged (the loop adds it the same way).
#[test]
fn the_decision_names_the_first_candidate_the_simulations_support() {
    let (start, records) = undamped_start();
    let ranked = vec![candidate("no-such-effect"), candidate("linear-damping")];
    let d = decide_default(&start, &ranked, &records);
    assert_eq!(d.chosen.as_deref(), Some("linear-damping"), "{d:?}");
    assert_eq!(d.reason, Reason::Supported);
    assert!(!d.ranking_stands);
    let reasons: Vec<Reason> = d.tried.iter().map(|t| t.reason).collect();
    assert_eq!(reasons, [Reason::CouldNotAdd, Reason::Supported]);
    assert!(d.tried[0].error.is_some() && d.tried[1].score.is_some());
    let added = d.added.as_ref().unwrap();
    assert_eq!(added.effect, "linear-damping");
    assert!(added.score.key() < d.before.key(), "{d:?}");
    assert!(
        d.why
            .contains("no-such-effect passed over: it could not be added")
            && d.why
                .contains("linear-damping is named of the 2 contenders"),
        "{}",
        d.why
    );
    let v = d.verdict("missing effect: no-such-effect");
    assert!(
        v.starts_with("missing effect: linear-damping (no-such-effect passed over")
            && v.ends_with("; add it with --add linear-damping"),
        "{v}"
    );
    // The top one supported: the ranking's verdict stands.
    let top = decide_default(&start, &ranked[1..], &records);
    assert_eq!(top.chosen.as_deref(), Some("linear-damping"));
    assert!(top.ranking_stands && top.reason == Reason::Supported);
    assert_eq!(top.verdict("the ranking's words"), "the ranking's words");
    // Judged by the short horizon: decided the same way.
    let mut short = ranked.clone();
    short
        .iter_mut()
        .for_each(|r| r.judge = Some(Judge::ShortHorizon));
    let d_short = decide_default(&start, &short, &records);
    assert_eq!(d_short.chosen.as_deref(), Some("linear-damping"));
    assert_eq!(d_short.why, d.why);
}

/// A contender with which every record simulates better overrules the ranking's order: a
/// look-alike ranked first (cubic damping for a missing dashpot) is passed over for the missing
/// dashpot, also when only the dashpot's per-fold models failed to simulate (its test passed);
/// a candidate whose test did not pass does not contend.
#[test]
fn a_contender_that_makes_every_record_simulate_better_overrules_the_ranking() {
    let (start, records) = undamped_start();
    let ranked = vec![candidate("cubic-damping"), candidate("linear-damping")];
    let d = decide_default(&start, &ranked, &records);
    assert_eq!(d.chosen.as_deref(), Some("linear-damping"), "{d:?}");
    assert_eq!(d.reason, Reason::Supported);
    assert!(!d.ranking_stands);
    let reasons: Vec<Reason> = d.tried.iter().map(|t| t.reason).collect();
    assert_eq!(reasons, [Reason::SimulatesLessWell, Reason::Supported]);
    let (cubic, linear) = (d.tried[0].score.unwrap(), d.tried[1].score.unwrap());
    assert!(
        linear.key() < cubic.key() && cubic.key() < d.before.key(),
        "{d:?}"
    );
    assert!(
        d.why.contains("cubic-damping passed over: with it"),
        "{}",
        d.why
    );
    // Ranked after the one named and not beating it: not chosen, in words that say so (not
    // that every record simulates better with another).
    let reversed = vec![candidate("linear-damping"), candidate("cubic-damping")];
    let d = decide_default(&start, &reversed, &records);
    assert_eq!(d.chosen.as_deref(), Some("linear-damping"), "{d:?}");
    let reasons: Vec<Reason> = d.tried.iter().map(|t| t.reason).collect();
    assert_eq!(reasons, [Reason::Supported, Reason::NotChosen]);
    assert!(!d.why.contains("cubic-damping passed over"), "{}", d.why);
    assert_eq!(
        serde_json::to_value(&d.tried[1]).unwrap()["reason"],
        "not-chosen"
    );
    assert!(
        Reason::NotChosen
            .to_string()
            .starts_with("another candidate was named first")
    );
    // Its per-fold models could not be simulated: it still contends.
    let mut folds_failed = ranked.clone();
    (folds_failed[1].significant, folds_failed[1].significance) =
        (false, Significance::CannotBeSimulated);
    let d = decide_default(&start, &folds_failed, &records);
    assert_eq!(d.chosen.as_deref(), Some("linear-damping"), "{d:?}");
    // Its test did not pass: it does not contend, and the look-alike is named.
    let mut not_passed = ranked.clone();
    (not_passed[1].significant, not_passed[1].significance) = (false, Significance::NotSignificant);
    let d = decide_default(&start, &not_passed, &records);
    assert_eq!(d.chosen.as_deref(), Some("cubic-damping"), "{d:?}");
    assert!(d.ranking_stands && d.tried.len() == 1);
}

/// One record far better is not enough to overrule the ranking: every record must agree (a
/// multi-stable structure's record whose run settles in another well moves the geometric mean
/// by orders of magnitude either way); fewer failing records always is.
#[test]
fn every_record_must_simulate_better_to_overrule() {
    let s = |failed: usize, each: &[Option<f64>]| {
        let ok: Vec<f64> = each.iter().flatten().copied().collect();
        (
            SimScore {
                failed,
                records: each.len(),
                mean_r_mse: ok.iter().sum::<f64>() / ok.len().max(1) as f64,
                geo_mean_r_mse: tfs_diagnose::geometric_mean_r_mse(&ok),
            },
            each.to_vec(),
        )
    };
    let first = s(0, &[Some(4.9), Some(1.2e-2), Some(1.4e-3)]);
    let one_well = s(0, &[Some(2.9e-2), Some(1.1e-2), Some(1.6e-3)]);
    assert!(one_well.0.key() < first.0.key() && !beats(&one_well, &first));
    let every = s(0, &[Some(2.9e-2), Some(1.1e-2), Some(1.3e-3)]);
    assert!(beats(&every, &first) && !beats(&first, &every));
    let fewer_fail = s(0, &[Some(9.0), Some(9.0), Some(9.0)]);
    let fails = s(1, &[None, Some(1e-3), Some(1e-3)]);
    assert!(beats(&fewer_fail, &fails) && !beats(&fails, &fewer_fail));
    // The same record failing with both: the others decide.
    let fails_better = s(1, &[None, Some(1e-4), Some(1e-4)]);
    assert!(beats(&fails_better, &fails));
}

/// A decision that names nothing says why in its verdict when significant candidates were
/// passed over, and keeps the ranking's words when nothing was significant; the reasons read
/// as words and as kebab-case names in JSON.
#[test]
fn a_decision_that_names_nothing_says_why() {
    let (start, records) = undamped_start();
    let mut quiet = candidate("linear-damping");
    (quiet.significant, quiet.significance) = (false, Significance::NoFall);
    quiet.delta_heldout = -0.1;
    let d = decide_default(&start, &[quiet], &records);
    assert!(
        d.chosen.is_none() && d.added.is_none() && d.tried.is_empty(),
        "{d:?}"
    );
    assert_eq!(d.reason, Reason::NothingSignificant);
    assert!(d.ranking_stands);
    assert_eq!(
        d.verdict("no significant missing effect"),
        "no significant missing effect"
    );
    let passed = Decision {
        reason: Reason::NoneSupported,
        ranking_stands: false,
        why: "maxwell passed over".into(),
        ..d
    };
    assert_eq!(
        passed.verdict("missing effect: maxwell"),
        "no missing effect that the simulations support (maxwell passed over)"
    );
    let json = serde_json::to_value(&passed).unwrap();
    assert_eq!(json["reason"], "none-supported");
    assert_eq!(json["ranking_stands"], false);
    assert_eq!(
        Reason::WorsensSimulation.to_string(),
        "significant, but the records simulate worse with it: passed over"
    );
    assert_eq!(
        serde_json::to_value(Reason::StopByTfs).unwrap(),
        "stop-by-tfs"
    );
}

/// A candidate is a contact by the terms it adds (a one-sided `below` or `above` factor), not
/// by its name.
#[test]
fn a_contact_is_recognised_by_its_terms() {
    let dofs = vec!["x1".to_string(), "x2".to_string()];
    let with = |terms: &[&str]| {
        let mut r = candidate("anything");
        r.terms = terms.iter().map(|t| t.to_string()).collect();
        r
    };
    assert!(adds_contact(&with(&["below((x2-x1), 0.1)"]), &dofs));
    assert!(adds_contact(&with(&["above(x1, -0.25)"]), &dofs));
    assert!(!adds_contact(&with(&["x1'^3", "tanh(x1', 0.01)"]), &dofs));
    assert!(!adds_contact(&with(&["not a term"]), &dofs));
}

/// A model that fails to simulate only because its coefficients are off (nothing is missing
/// from its terms: the cubic spring's sign is flipped, so the records carry it out of its
/// well) is not given an effect for curing the failure: every candidate's model is the start's
/// terms refitted with it, and those terms refitted alone already make the records simulate.
/// Without that control any candidate that can be added would be chosen.
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
    // Candidates whose held-out equation error falls, none significant.
    let ranked: Vec<RankedEffect> = ["cubic-damping", "dry-friction"]
        .into_iter()
        .map(|n| RankedEffect {
            significant: false,
            significance: Significance::NotSignificant,
            ..candidate(n)
        })
        .collect();
    let d = decide_default(&start, &ranked, &records);
    let refitted = d.refitted.unwrap();
    assert_eq!(refitted.failed, 0, "{d:?}");
    // The candidates make the records simulate too, but no better than the refit alone.
    assert!(
        d.tried
            .iter()
            .any(|t| t.score.is_some_and(|s| s.failed < d.before.failed)),
        "{d:?}"
    );
    assert!(
        d.tried.iter().all(|t| t.reason == Reason::CuresLess),
        "{d:?}"
    );
    assert!(d.chosen.is_none(), "{d:?}");
    assert_eq!(d.reason, Reason::NothingSignificant);
    assert!(d.why.contains("the start fit's"), "{}", d.why);
}

/// The rival that outdoes a contact is the one with which the records simulate best, and only
/// when strictly better than the contact: fewer failing records first, then the lower mean
/// R-MSE; a rival that could not be added is no rival; a tie goes to the contact.
#[test]
fn a_contact_is_outdone_only_by_a_rival_that_simulates_strictly_better() {
    let (start, records) = undamped_start();
    let opts = DiagnoseOptions::default();
    let catalogue = Catalogue::standard(opts.max_power);
    let score = |failed, mean_r_mse| SimScore {
        failed,
        records: 2,
        mean_r_mse,
        geo_mean_r_mse: mean_r_mse,
    };
    let chosen = |name: &str, s: SimScore| Chosen {
        effect: name.into(),
        model: start.clone(),
        stops: Vec::new(),
        warnings: Vec::new(),
        score: s,
        each: vec![Some(s.geo_mean_r_mse); 2],
    };
    let mut made = Made {
        model: &start,
        records: &records,
        catalogue: &catalogue,
        opts: &opts,
        made: HashMap::new(),
    };
    let entries = [
        ("worse", Ok(chosen("worse", score(0, 0.3)))),
        ("fails-less", Ok(chosen("fails-less", score(0, 0.25)))),
        ("best", Ok(chosen("best", score(0, 0.05)))),
        ("broken", Err(NotMade::Failed("could not be added".into()))),
        ("nothing", Err(NotMade::AddsNothing)),
    ];
    for (n, m) in entries {
        made.made.insert(n.to_string(), m);
    }
    let contact = score(0, 0.2);
    let all = ["worse", "fails-less", "best", "broken", "nothing"];
    let (name, s) = outdone_by(&mut made, &all, &contact).unwrap();
    assert_eq!((name.as_str(), s.mean_r_mse), ("best", 0.05));
    // Only rivals no better than the contact, or ones not made: not outdone.
    assert!(outdone_by(&mut made, &["worse", "broken", "nothing"], &contact).is_none());
    // A candidate not made is recorded by why: it could not be added, or it adds nothing.
    assert_eq!(
        made.trial("broken", Reason::CouldNotAdd).error.as_deref(),
        Some("could not be added")
    );
    assert_eq!(not_made_reason(made.get("broken")), Reason::CouldNotAdd);
    assert_eq!(not_made_reason(made.get("nothing")), Reason::AddsNothing);
    // A tie goes to the contact.
    assert!(outdone_by(&mut made, &["best"], &score(0, 0.05)).is_none());
    // A rival with which fewer records fail outdoes a contact with a lower mean R-MSE.
    assert!(outdone_by(&mut made, &["worse"], &score(1, 0.01)).is_some());
    assert_eq!(
        serde_json::to_value(Reason::StopOutdone).unwrap(),
        "stop-outdone"
    );
}

/// Every reason the decision gives is in docs/diagnosis.md under its JSON name, so the page
/// lists the reasons in force.
#[test]
fn the_docs_list_every_reason() {
    // Exhaustive: a reason added to the enum fails to compile here until it is listed.
    let index = |r: Reason| match r {
        Reason::CuresFailures => 0,
        Reason::CuresLess => 1,
        Reason::Supported => 2,
        Reason::SimulatesLessWell => 3,
        Reason::NotChosen => 4,
        Reason::WorsensSimulation => 5,
        Reason::CouldNotAdd => 6,
        Reason::AddsNothing => 7,
        Reason::StopByTfs => 8,
        Reason::StopNotByTfs => 9,
        Reason::StopOutdone => 10,
        Reason::NothingSignificant => 11,
        Reason::NoneSupported => 12,
    };
    let all = [
        Reason::CuresFailures,
        Reason::CuresLess,
        Reason::Supported,
        Reason::SimulatesLessWell,
        Reason::NotChosen,
        Reason::WorsensSimulation,
        Reason::CouldNotAdd,
        Reason::AddsNothing,
        Reason::StopByTfs,
        Reason::StopNotByTfs,
        Reason::StopOutdone,
        Reason::NothingSignificant,
        Reason::NoneSupported,
    ];
    let mut seen: Vec<usize> = all.iter().map(|&r| index(r)).collect();
    seen.sort_unstable();
    assert_eq!(seen, (0..all.len()).collect::<Vec<_>>());
    let docs = include_str!("../../../../docs/diagnosis.md");
    for r in all {
        let name = serde_json::to_value(r).unwrap();
        let name = name.as_str().unwrap();
        assert!(
            docs.contains(&format!("`{name}`")),
            "docs/diagnosis.md lacks `{name}`"
        );
    }
}
