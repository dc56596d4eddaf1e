//! Tests of what the model does when simulated: the scores, their order, T-F-S's stop test.

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
        geo_mean_r_mse: mean,
    }
}

/// The candidate with the fewest failing records wins over one with a lower geometric-mean R-MSE on
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
/// the others' R-MSE; so does one that raises the geometric-mean R-MSE with as many failing; one
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
        geo_mean_r_mse: 0.25,
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

/// A candidate that predicts two multi-stable records hundreds of times better and loses a
/// third one further than the model without it does not worsen the model: every record's factor
/// counts alike (the geometric mean falls about 60x), where the arithmetic mean (4.0 → 15.8) would
/// be decided by the record whose run settles in the other well either way.
#[test]
fn one_lost_record_does_not_outvote_the_others() {
    let before = SimScore::from_parts(3, &[5.06, 5.22, 1.71]);
    let after = SimScore::from_parts(3, &[1.05e-2, 4.1e-4, 47.4]);
    assert!(after.mean_r_mse > before.mean_r_mse);
    assert!(!worsens(&before, &after));
    assert!(after.describe().contains("geometric-mean R-MSE"));
    // The same factor lost on every record worsens it.
    let doubled = SimScore::from_parts(3, &[10.12, 10.44, 3.42]);
    assert!(worsens(&before, &doubled));
}
