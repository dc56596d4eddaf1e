//! `cargo xtask diagnose-bench --rescore DIR`: the scores of a finished run again, from its
//! `results.json`, with the current scoring (a run of hundreds of cases takes half an hour; its
//! cases do not change when a score is added or defined better).

use std::path::Path;

use anyhow::{Context, Result, anyhow};
use serde_json::Value;

use super::case::{CaseResult, CaseSpec, Group, Round};
use super::truth::Kind;

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect())
        .unwrap_or_default()
}

fn strings(v: &Value) -> Vec<String> {
    v.as_array()
        .map(|a| {
            a.iter()
                .filter_map(|x| x.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default()
}

fn opt_string(v: &Value) -> Option<String> {
    v.as_str().map(String::from)
}

/// One case of `results.json` as far as the scores read it (each round's ranked candidates
/// are left out).
fn case(v: &Value) -> Result<CaseResult> {
    let s = &v["spec"];
    let key = s["kind"].as_str().context("spec.kind")?;
    let kind = Kind::ALL
        .into_iter()
        .find(|k| k.key() == key)
        .ok_or_else(|| anyhow!("unknown baseline '{key}'"))?;
    let group = match s["group"].as_str() {
        Some("single") => Group::Single,
        Some("control") => Group::Control,
        Some("pair") => Group::Pair,
        other => return Err(anyhow!("unknown group {other:?}")),
    };
    let spec = CaseSpec {
        id: s["id"].as_u64().context("spec.id")? as usize,
        kind,
        group,
        hidden: strings(&s["hidden"]),
        sizes: f64s(&s["sizes"]),
        snr: s["snr"].as_f64(),
        seed: s["seed"].as_u64().context("spec.seed")?,
    };
    let mut c = CaseResult::new(&spec);
    c.status = v["status"].as_str().context("status")?.to_string();
    c.message = opt_string(&v["message"]);
    c.baseline = v["baseline"].clone();
    c.realised = f64s(&v["realised"]);
    c.unrepresentable = f64s(&v["unrepresentable"]);
    c.hidden_dofs = v["hidden_dofs"]
        .as_array()
        .map(|a| a.iter().map(strings).collect())
        .unwrap_or_default();
    c.start = opt_string(&v["start"]);
    c.oracle_after = v["oracle_after"].as_f64();
    c.start_heldout = v["start_heldout"].as_f64();
    c.heldout_score = serde_json::from_value(v["heldout_score"].clone()).ok();
    c.oracle_free_run = pair(&v["oracle_free_run"]);
    c.oracle_model = opt_string(&v["oracle_model"]);
    c.identify_seconds = v["identify_seconds"].as_f64().unwrap_or(f64::NAN);
    c.seconds = v["seconds"].as_f64().unwrap_or(f64::NAN);
    c.rounds = v["rounds"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|r| Round {
                    top: opt_string(&r["top"]),
                    top_effect: opt_string(&r["top_effect"]),
                    top_parameter: r["top_parameter"].as_array().and_then(|p| {
                        Some((p.first()?.as_str()?.to_string(), p.get(1)?.as_f64()?))
                    }),
                    verdict: r["verdict"].as_str().unwrap_or_default().to_string(),
                    simulation: opt_string(&r["simulation"]),
                    ranked: Vec::new(),
                    tied: strings(&r["tied"]),
                    before: r["before"].as_f64(),
                    after: r["after"].as_f64(),
                    free_run: pair(&r["free_run"]),
                    failure: opt_string(&r["failure"]),
                    seconds: r["seconds"].as_f64().unwrap_or(f64::NAN),
                })
                .collect()
        })
        .unwrap_or_default();
    Ok(c)
}

/// A pair of optional numbers written as a two-element array (`[null, null]` when absent).
fn pair(v: &Value) -> (Option<f64>, Option<f64>) {
    (v[0].as_f64(), v[1].as_f64())
}

/// The cases, catalogue and total seconds of the run whose `results.json` is in `dir`.
pub fn load(dir: &Path) -> Result<(Vec<CaseResult>, Vec<String>, f64)> {
    let path = dir.join("results.json");
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let v: Value =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
    let catalogue = strings(&v["catalogue"]);
    let cases = v["cases"]
        .as_array()
        .with_context(|| format!("{}: no \"cases\" array", path.display()))?
        .iter()
        .enumerate()
        .map(|(i, c)| case(c).with_context(|| format!("{}: case {i}", path.display())))
        .collect::<Result<Vec<_>>>()?;
    Ok((cases, catalogue, v["seconds"].as_f64().unwrap_or(f64::NAN)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dbench::summary::{GROUPS, Measure, Summary};

    /// A case written as the run writes it and read back scores the same.
    #[test]
    fn results_read_back_score_the_same() {
        let spec = CaseSpec {
            id: 3,
            kind: Kind::Rig,
            group: Group::Single,
            hidden: vec!["maxwell".into()],
            sizes: vec![0.2],
            snr: Some(40.0),
            seed: u64::MAX - 5,
        };
        let mut c = CaseResult::new(&spec);
        c.realised = vec![0.25];
        c.unrepresentable = vec![0.04];
        c.hidden_dofs = vec![vec!["x".into()]];
        c.oracle_after = Some(0.5);
        c.oracle_free_run = (Some(0.9), None);
        c.heldout_score = Some(tfs::diagnose::PredictionScore {
            horizon: Some(40),
            why: "w".into(),
        });
        c.rounds.push(Round {
            top: Some("maxwell".into()),
            top_effect: Some("maxwell".into()),
            top_parameter: Some(("tau".into(), 0.01)),
            verdict: "v".into(),
            simulation: None,
            ranked: Vec::new(),
            tied: vec!["hysteresis".into()],
            before: Some(2.0),
            after: Some(0.5),
            free_run: (Some(1.1), Some(0.7)),
            failure: None,
            seconds: 1.0,
        });
        let cat = vec!["maxwell".to_string(), "hysteresis".to_string()];
        let dir = std::env::temp_dir().join(format!("dbench-rescore-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let json = serde_json::json!({"catalogue": cat, "seconds": 12.5, "cases": [c]});
        std::fs::write(dir.join("results.json"), json.to_string()).unwrap();
        let (back, cat_back, secs) = load(&dir).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!((cat_back, secs, back.len()), (cat.clone(), 12.5, 1));
        let b = &back[0];
        assert_eq!(b.spec.seed, spec.seed);
        assert_eq!(b.rounds[0].top_parameter, Some(("tau".into(), 0.01)));
        assert_eq!(b.rounds[0].free_run, (Some(1.1), Some(0.7)));
        assert_eq!(
            (&b.heldout_score, b.oracle_free_run),
            (&c.heldout_score, c.oracle_free_run)
        );
        let (s0, s1) = (
            Summary::new(std::slice::from_ref(&c), &cat),
            Summary::new(&back, &cat),
        );
        let g = GROUPS[0].1;
        assert_eq!(s0.top1(g, None, None), s1.top1(g, None, None));
        assert_eq!(s0.top1_or_tied(g), s1.top1_or_tied(g));
        assert_eq!(s0.drop(g, None).0, s1.drop(g, None).0);
        assert_eq!(s0.oracle_drop(g, "maxwell"), s1.oracle_drop(g, "maxwell"));
        assert_eq!(s0.answers(g, false), s1.answers(g, false));
        let (l0, l1) = (
            s0.limit(g, "maxwell", Measure::Unrepresentable),
            s1.limit(g, "maxwell", Measure::Unrepresentable),
        );
        assert_eq!((l0.at, l0.above), (l1.at, l1.above));
        assert_eq!(s0.cases_csv(), s1.cases_csv());
    }
}
