//! `tfs diagnose` and `tfs refit --until-clean` name the same first effect on every case of
//! `diagnose-bench --quick`: the diagnosis as the CLI and the Python package make it (the full
//! diagnosis, then the decision with its further steps) against the loop's first round as
//! `refit --until-clean` runs it (its own ranking, then the decision), on the quick benchmark's
//! own cases (its plan, truths, records and start models).

use rayon::prelude::*;
use tfs::decide::{DecideOptions, decide};
use tfs::diagnose::{Catalogue, DiagnoseOptions};
use tfs::refit::{RefitRequest, refit_with};
use tfs::signal::noise::SnrReference;

use super::{Args, case, plan};

/// The arguments of `cargo xtask diagnose-bench --quick`.
fn quick() -> Args {
    Args {
        quick: true,
        out: "unused".into(),
        seed: 1,
        only: Vec::new(),
        effects: Vec::new(),
        noise: Vec::new(),
        rescore: None,
        keep_records: None,
        snr_reference: SnrReference::MeanSquare,
        oracle_only: false,
    }
}

/// One case: the effect `tfs diagnose` names and the one `refit --until-clean` adds first
/// (`None` for the case: it does not apply to its baseline).
fn named_and_added(spec: &case::CaseSpec) -> Option<(String, Option<String>, Option<String>)> {
    let label = format!(
        "case {} ({}, hidden {:?}, {:?} dB)",
        spec.id,
        spec.kind.key(),
        spec.hidden,
        spec.snr
    );
    let start =
        case::start(spec, SnrReference::MeanSquare).unwrap_or_else(|e| panic!("{label}: {e:#}"))?;
    let (model, train) = (&start.id.model, &start.train);
    let opts = DiagnoseOptions::default();
    let d = tfs::diagnose::diagnose(model, train, &opts)
        .unwrap_or_else(|e| panic!("{label}: diagnose: {e}"));
    let named = decide(model, &d.ranked, train, &opts, &DecideOptions::diagnose())
        .unwrap_or_else(|e| panic!("{label}: decide: {e}"))
        .chosen;
    let req = RefitRequest {
        until_clean: Some(1),
        ..Default::default()
    };
    let looped = refit_with(model, train, &req, &start.id.offsets)
        .unwrap_or_else(|e| panic!("{label}: refit --until-clean: {e}"));
    let added = looped.rounds.first().and_then(|r| r.added.clone());
    Some((label, named, added))
}

#[test]
fn diagnose_and_the_loop_name_the_same_first_effect_on_the_quick_bench() {
    let catalogue = Catalogue::standard(DiagnoseOptions::default().max_power).names();
    let specs = plan(&quick(), &catalogue).unwrap();
    assert!(specs.len() >= 12, "{} cases", specs.len());
    let outcomes: Vec<_> = specs.par_iter().filter_map(named_and_added).collect();
    assert!(outcomes.len() >= 12, "{} cases ran", outcomes.len());
    let disagree: Vec<String> = outcomes
        .iter()
        .filter(|(_, named, added)| named != added)
        .map(|(label, named, added)| {
            format!("{label}: diagnose names {named:?}, the loop adds {added:?}")
        })
        .collect();
    assert!(disagree.is_empty(), "{}", disagree.join("\n"));
    // The benchmark's cases name effects (not only nothing), so the agreement is tested on both.
    assert!(
        outcomes.iter().any(|(_, named, _)| named.is_some())
            && outcomes.iter().any(|(_, named, _)| named.is_none()),
        "{outcomes:?}"
    );
}
