//! One benchmark case: draw a baseline, hide its effects, simulate and measure three training
//! records and a held-out one, then identify → diagnose → refit through the `tfs` library (as the
//! CLI does) and score the diagnosis and the held-out error.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, anyhow};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use serde_json::Value;
use tfs::data::Record;
use tfs::diagnose::{DiagnoseOptions, Explanation, PredictionScore};
use tfs::identify::{IdentifyOptions, identify, plan};
use tfs::library::{Library, Model};
use tfs::signal::noise::SnrReference;

use super::hide::{Hide, hide};
use super::size;
use super::truth::{self, Baseline, Kind};

/// What kind of case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Group {
    /// One hidden effect.
    Single,
    /// Nothing hidden.
    Control,
    /// Two hidden effects (two rounds).
    Pair,
}

/// What to run.
#[derive(Debug, Clone, Serialize)]
pub struct CaseSpec {
    /// Index in the plan.
    pub id: usize,
    /// The baseline.
    #[serde(serialize_with = "kind_key")]
    pub kind: Kind,
    /// The kind of case.
    pub group: Group,
    /// Hidden catalogue effects.
    pub hidden: Vec<String>,
    /// Target share of each (its force RMS over the RMS acceleration).
    pub sizes: Vec<f64>,
    /// SNR in dB (None: noise-free).
    pub snr: Option<f64>,
    /// Seed of everything drawn in the case.
    pub seed: u64,
}

fn kind_key<S: serde::Serializer>(k: &Kind, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(k.key())
}

/// One round of diagnose → refit.
#[derive(Debug, Clone, Serialize)]
pub struct Round {
    /// The top significant effect (`name` as `--add` takes it), if any.
    pub top: Option<String>,
    /// Its catalogue effect.
    pub top_effect: Option<String>,
    /// Its scanned parameter.
    pub top_parameter: Option<(String, f64)>,
    /// The diagnosis's verdict by equation error.
    pub verdict: String,
    /// What the simulations said when they decided the effect named (`tfs::decide`: the model
    /// fails some records, or a significant candidate makes them simulate worse), if they did.
    pub simulation: Option<String>,
    /// The five best-ranked candidates.
    pub ranked: Vec<Ranked>,
    /// Effects (`name` as `--add` takes it) the diagnosis reports as tied with the top one.
    pub tied: Vec<String>,
    /// Held-out R-MSE of the model before the round, under the case's held-out score
    /// ([`CaseResult::heldout_score`]).
    pub before: Option<f64>,
    /// Held-out R-MSE after adding the top effect (= before when nothing was added), under the
    /// same score.
    pub after: Option<f64>,
    /// The free-run held-out R-MSE before and after (`compare`'s), whatever the case's score.
    pub free_run: (Option<f64>, Option<f64>),
    /// Why a simulation failed, if one did.
    pub failure: Option<String>,
    /// Seconds spent in diagnose and refit.
    pub seconds: f64,
}

/// One ranked candidate of a round, as the diagnosis scored it.
#[derive(Debug, Clone, Serialize)]
pub struct Ranked {
    /// `name` as `--add` takes it.
    pub name: String,
    /// Passed the test, the size threshold and the prediction veto.
    pub significant: bool,
    /// Relative drop of the held-out equation error.
    pub delta: f64,
    /// Corrected p-value.
    pub p: f64,
    /// Held-out prediction R-MSE (the diagnosis's judge) without and with the candidate.
    pub r_mse: (Option<f64>, Option<f64>),
    /// Reported as tied with the top effect (the records cannot tell the two apart).
    pub tied_with_top: bool,
    /// Why it is (not) significant.
    pub reason: String,
}

/// Round 1's answer to a single-effect case, against what the held-out record says of the
/// hidden effect added by name (`refit --add <hidden>`, the oracle): found first; or missed
/// where the hidden effect predicts the held-out record better than the answer (a miss the
/// records tell); or missed where it predicts it no better (the answer, or the start model when
/// nothing was named, is at least as good a model of the record); or missed where its refit
/// does not simulate the held-out record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Answer {
    /// A hidden effect named first.
    Found,
    /// Missed; the hidden effect added by name predicts the held-out record better.
    HiddenBetter,
    /// Missed; the hidden effect added by name predicts it no better than the answer.
    NotBetter,
    /// Missed; the hidden effect added by name does not simulate the held-out record.
    HiddenFails,
}

/// The outcome of one case.
#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    /// What was run.
    pub spec: CaseSpec,
    /// `ok`, `not-applicable`, `truth-failed` or `failed`.
    pub status: String,
    /// Why not ok.
    pub message: Option<String>,
    /// The baseline's drawn parameters.
    pub baseline: Value,
    /// Each hidden effect's drawn parameters.
    pub hidden_params: Vec<Value>,
    /// Each hidden effect's realised share (force RMS over acceleration RMS, training records).
    pub realised: Vec<f64>,
    /// Each hidden effect's unrepresentable part: the RMS of what the start library's best
    /// least-squares fit leaves of its force (clean training states), over the RMS
    /// acceleration (see `size::unrepresentable`).
    pub unrepresentable: Vec<f64>,
    /// The DOFs whose equation may name each hidden effect.
    pub hidden_dofs: Vec<Vec<String>>,
    /// The identified start model.
    pub start: Option<String>,
    /// Round 1 and (for pairs, or when something remains) round 2.
    pub rounds: Vec<Round>,
    /// How the held-out record is scored in this case, chosen once from the start model
    /// ([`tfs::diagnose::PredictionScore::choose`]): the free run, or short-horizon pieces
    /// where the input's own noise decides the free run.
    pub heldout_score: Option<tfs::diagnose::PredictionScore>,
    /// Held-out R-MSE after adding the hidden effect itself by name (one hidden effect), under
    /// the case's held-out score.
    pub oracle_after: Option<f64>,
    /// Held-out R-MSE of the start model under the case's held-out score (single-effect cases;
    /// `None` when it fails to simulate the record).
    pub start_heldout: Option<f64>,
    /// The free-run held-out R-MSE of the start model and of the oracle refit.
    pub oracle_free_run: (Option<f64>, Option<f64>),
    /// The oracle refit's equations, or why it failed (single-effect cases).
    pub oracle_model: Option<String>,
    /// Seconds: identify, whole case.
    pub identify_seconds: f64,
    /// Whole case.
    pub seconds: f64,
}

impl CaseResult {
    /// A result of `spec` that ran ("ok") with nothing measured yet.
    pub fn new(spec: &CaseSpec) -> Self {
        Self {
            spec: spec.clone(),
            status: "ok".into(),
            message: None,
            baseline: Value::Null,
            hidden_params: Vec::new(),
            realised: Vec::new(),
            unrepresentable: Vec::new(),
            hidden_dofs: Vec::new(),
            start: None,
            rounds: Vec::new(),
            heldout_score: None,
            oracle_after: None,
            start_heldout: None,
            oracle_free_run: (None, None),
            oracle_model: None,
            identify_seconds: 0.0,
            seconds: 0.0,
        }
    }

    /// True when the case ran to the end.
    pub fn ok(&self) -> bool {
        self.status == "ok"
    }

    /// The effect named by round `r` (catalogue name) or "none".
    pub fn found(&self, r: usize) -> String {
        self.rounds
            .get(r)
            .and_then(|x| x.top_effect.clone())
            .unwrap_or_else(|| "none".into())
    }

    /// Round 1 named a hidden effect, on a DOF whose equation may hold it.
    pub fn top1_correct(&self) -> bool {
        self.named_hidden(0).is_some()
    }

    /// Which hidden effect round `r` named (index), if it named one on an admissible DOF.
    pub fn named_hidden(&self, r: usize) -> Option<usize> {
        let round = self.rounds.get(r)?;
        self.hidden_index(round.top.as_ref()?)
    }

    /// Round 1 named a hidden effect first, or reported one as tied with the effect it named
    /// first (the records could not tell the two apart).
    pub fn top1_or_tied(&self) -> bool {
        self.top1_correct()
            || self
                .rounds
                .first()
                .is_some_and(|r| r.tied.iter().any(|t| self.hidden_index(t).is_some()))
    }

    /// The hidden effect (index) that `name` (`effect` or `effect@dof`) stands for, on a DOF
    /// whose equation may hold it.
    fn hidden_index(&self, name: &str) -> Option<usize> {
        let (effect, dof) = match name.split_once('@') {
            Some((e, d)) => (e, Some(d)),
            None => (name, None),
        };
        self.spec.hidden.iter().enumerate().find_map(|(i, h)| {
            let dof_ok = match dof {
                None => true,
                Some(d) => self.hidden_dofs[i].iter().any(|x| x == d),
            };
            (h == effect && dof_ok).then_some(i)
        })
    }

    /// Round 1's answer against the hidden effect added by name, on the held-out record
    /// ([`Answer`]). Only for single-effect cases that ran.
    pub fn answer(&self) -> Answer {
        if self.top1_correct() {
            return Answer::Found;
        }
        let Some(oracle) = self.oracle_after else {
            return Answer::HiddenFails;
        };
        // `after` is the start model's own error when nothing was named; `None` when the
        // refit with the named effect failed to simulate, which the hidden effect beats.
        match self.rounds.first().and_then(|r| r.after) {
            Some(given) if oracle >= given => Answer::NotBetter,
            _ => Answer::HiddenBetter,
        }
    }

    /// Held-out error factor of round `r` (before / after).
    pub fn drop(&self, r: usize) -> Option<f64> {
        let round = self.rounds.get(r)?;
        Some(round.before? / round.after?)
    }
}

/// The start library of each DOF: the baseline's, less the terms an effect's presence removes.
fn libraries(b: &Baseline, hides: &[Hide]) -> Result<Vec<String>> {
    let dofs: Vec<&str> = b.dofs.iter().map(String::as_str).collect();
    b.libraries
        .iter()
        .map(|spec| {
            let lib = Library::parse(spec, &dofs)?;
            let kept: Vec<String> = lib
                .terms()
                .iter()
                .map(ToString::to_string)
                .filter(|t| !hides.iter().any(|h| h.drop.contains(t)))
                .collect();
            Ok(kept.join(", "))
        })
        .collect()
}

/// One diagnosis round on `model`: what it names and the model with that effect added. Its
/// held-out scores are filled in by [`score_round`] once the case's ruler is chosen.
fn round(
    model: &Model,
    train: &[Record],
    offsets: &tfs::report::OffsetsReport,
) -> Result<(Round, Option<Model>)> {
    let t0 = Instant::now();
    // The ranking `tfs diagnose` prints (its comparison and residual maps are not scored).
    let opts = DiagnoseOptions::default();
    let d: Explanation = tfs::diagnose::explain(
        model,
        train,
        &tfs::diagnose::Catalogue::standard(opts.max_power),
        &opts,
    )
    .context("diagnose")?;
    // What `tfs diagnose` names and `refit --until-clean` adds first: one decision
    // (`tfs::decide`).
    let decision = tfs::decide::decide(
        model,
        &d.ranked,
        train,
        &opts,
        &tfs::decide::DecideOptions::diagnose(),
    )
    .context("diagnose: simulating the candidates")?;
    let top = decision
        .chosen
        .as_ref()
        .and_then(|n| d.ranked.iter().find(|r| &r.name == n));
    let mut refitted = None;
    if let Some(t) = top {
        let r = tfs::refit::refit(
            model,
            std::slice::from_ref(&t.name),
            train,
            false,
            Vec::new(),
            offsets,
        )
        .with_context(|| format!("refit --add {}", t.name))?;
        refitted = Some(r.model);
    }
    Ok((
        Round {
            top: top.map(|t| t.name.clone()),
            top_effect: top.map(|t| t.effect.clone()),
            top_parameter: top.and_then(|t| t.parameter.clone()),
            verdict: d.verdict.clone(),
            simulation: (!decision.ranking_stands).then(|| decision.why.clone()),
            ranked: d
                .ranked
                .iter()
                .take(5)
                .map(|r| Ranked {
                    name: r.name.clone(),
                    significant: r.significant,
                    delta: r.delta_heldout,
                    p: r.p_value,
                    r_mse: (r.r_mse_before, r.r_mse_after),
                    tied_with_top: r.tied_with_top,
                    reason: r.reason.clone(),
                })
                .collect(),
            tied: d
                .ranked
                .iter()
                .filter(|r| r.tied_with_top)
                .map(|r| r.name.clone())
                .collect(),
            before: None,
            after: None,
            free_run: (None, None),
            failure: None,
            seconds: t0.elapsed().as_secs_f64(),
        },
        refitted,
    ))
}

/// Scores round `r` on the held-out record under `score`: `before` is the model the round
/// started from, `after` the model with its named effect (`None` when nothing was named).
fn score_round(
    r: &mut Round,
    score: &PredictionScore,
    before: &Model,
    after: Option<&Model>,
    heldout: &Record,
) {
    let opts = DiagnoseOptions::default();
    let b = score.r_mse(before, heldout, &opts);
    r.failure = b.as_ref().err().map(|e| format!("before: {e}"));
    r.before = b.ok();
    r.free_run.0 = tfs::diagnose::r_mse(before, heldout).ok();
    let Some(m) = after else {
        r.after = r.before;
        r.free_run.1 = r.free_run.0;
        return;
    };
    r.after = match score.r_mse(m, heldout, &opts) {
        Ok(v) => Some(v),
        Err(e) => {
            r.failure = Some(format!("after: {e}"));
            None
        }
    };
    r.free_run.1 = tfs::diagnose::r_mse(m, heldout).ok();
}

/// Runs one case; failures are recorded in the result, not returned.
/// With `keep`, the case's records and start model are also written into a folder of its own
/// under `keep` ([`Args::keep_records`](super::Args)).
/// `reference` is what the noise level is relative to.
pub fn run(spec: &CaseSpec, keep: Option<&Path>, reference: SnrReference) -> CaseResult {
    run_with(spec, keep, reference, true)
}

/// [`run`], with the diagnosis rounds only when `diagnose` (without, a single-effect case
/// measures only the start model and the oracle refit on the held-out record).
pub fn run_with(
    spec: &CaseSpec,
    keep: Option<&Path>,
    reference: SnrReference,
    diagnose: bool,
) -> CaseResult {
    let t0 = Instant::now();
    let mut out = CaseResult::new(spec);
    if let Err(e) = run_into(spec, &mut out, keep, reference, diagnose) {
        if out.status == "ok" {
            out.status = "failed".into();
        }
        out.message = Some(format!("{e:#}"));
    }
    out.seconds = t0.elapsed().as_secs_f64();
    out
}

/// A case's truth, hidden effects and records, drawn as [`run`] draws them.
struct Drawn {
    baseline: Baseline,
    hides: Vec<Hide>,
    /// The noise-free responses, training records first.
    clean: Vec<truth::Clean>,
    /// The start library of each DOF.
    libs: Vec<String>,
    train: Vec<Record>,
    heldout: Record,
}

/// Draws case `spec`'s baseline and hidden effects and measures its records; a case that
/// cannot run sets `out.status` (`not-applicable`, `truth-failed`) and returns the error.
fn draw(spec: &CaseSpec, out: &mut CaseResult, reference: SnrReference) -> Result<Drawn> {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let b = truth::draw(spec.kind, &mut rng)?;
    out.baseline = b.params.clone();
    let pilot = truth::simulate(&b, 0, &[], &[]).context("pilot")?;
    let mut hides = Vec::new();
    for (name, &size) in spec.hidden.iter().zip(&spec.sizes) {
        match hide(name, &b, &pilot, size, &mut rng)? {
            Some(h) => hides.push(h),
            None => {
                out.status = "not-applicable".into();
                return Err(anyhow!("no truth for '{name}' on {}", spec.kind.key()));
            }
        }
    }
    out.hidden_params = hides.iter().map(|h| h.params.clone()).collect();
    out.hidden_dofs = hides.iter().map(|h| h.dofs.clone()).collect();
    let placed: Vec<_> = hides.iter().flat_map(|h| h.placed.clone()).collect();
    let exciter: Vec<_> = hides.iter().flat_map(|h| h.exciter.clone()).collect();
    let mut clean = Vec::new();
    for i in 0..b.excitations.len() {
        match truth::simulate(&b, i, &placed, &exciter) {
            Ok(c) => clean.push(c),
            Err(e) => {
                out.status = "truth-failed".into();
                return Err(e);
            }
        }
    }
    let libs = libraries(&b, &hides)?;
    let mut records = Vec::new();
    for (i, c) in clean.iter().enumerate() {
        let name = if i < 3 {
            format!("train{i}")
        } else {
            "heldout".into()
        };
        records.push(truth::measure(
            &b,
            &name,
            c,
            spec.snr,
            reference,
            spec.seed ^ (0x5eed + 7919 * i as u64),
        )?);
    }
    let heldout = records.pop().ok_or_else(|| anyhow!("no held-out record"))?;
    Ok(Drawn {
        baseline: b,
        hides,
        clean,
        libs,
        train: records,
        heldout,
    })
}

/// The start model identified on `train` as `tfs identify --library ... --offsets ...` does
/// (a chain's coupling law tied between its two equations, as `tfs identify` fits a chain by
/// default).
fn identify_start(
    b: &Baseline,
    libs: &[String],
    train: &[Record],
) -> Result<tfs::identify::Identification> {
    let opts = IdentifyOptions {
        library: Some(libs[0].clone()),
        dofs: b.dofs.clone(),
        offsets: b.offsets,
        tie: tfs::identify::Tie::Auto,
        ..Default::default()
    };
    let cols: Vec<String> = train[0].names().to_vec();
    let mut p = plan(&opts, &cols, "train0")?;
    if libs.len() > 1 {
        p.spec.dof_libraries = libs.to_vec();
    }
    identify(train.to_vec(), Vec::new(), &opts, &p).context("identify")
}

/// A case's training records and the start model identified on them, as [`run`] makes them:
/// what a test gives the diagnosis and the loop. `None` when the case does not apply (no truth
/// for its effect on its baseline).
#[cfg(test)]
pub struct Start {
    /// The training records.
    pub train: Vec<Record>,
    /// The identified start model and its offsets report.
    pub id: tfs::identify::Identification,
}

/// [`Start`] of case `spec` (`None`: the case does not apply, or its truth fails).
#[cfg(test)]
pub fn start(spec: &CaseSpec, reference: SnrReference) -> Result<Option<Start>> {
    let mut out = CaseResult::new(spec);
    let drawn = match draw(spec, &mut out, reference) {
        Ok(d) => d,
        Err(_) if out.status != "ok" => return Ok(None),
        Err(e) => return Err(e),
    };
    let id = identify_start(&drawn.baseline, &drawn.libs, &drawn.train)?;
    Ok(Some(Start {
        train: drawn.train,
        id,
    }))
}

fn run_into(
    spec: &CaseSpec,
    out: &mut CaseResult,
    keep: Option<&Path>,
    reference: SnrReference,
    diagnose: bool,
) -> Result<()> {
    let Drawn {
        baseline: b,
        hides,
        clean,
        libs,
        train,
        heldout,
    } = draw(spec, out, reference)?;
    out.realised = size::realised(&b, &hides, &clean[..3]);
    out.unrepresentable =
        size::unrepresentable(&b, &hides, &libs, &clean[..3]).context("unrepresentable part")?;
    let t1 = Instant::now();
    let id = identify_start(&b, &libs, &train)?;
    out.identify_seconds = t1.elapsed().as_secs_f64();
    out.start = Some(id.model.equation_string());
    if let Some(keep) = keep {
        keep_records(keep, spec, &train, &heldout, &id.model)?;
    }
    let mut models: Vec<Model> = Vec::new();
    if diagnose {
        let (r1, m1) = round(&id.model, &train, &id.offsets)?;
        out.rounds.push(r1);
        if let Some(m1) = m1 {
            if spec.group == Group::Pair {
                let (r2, m2) = round(&m1, &train, &id.offsets)?;
                out.rounds.push(r2);
                models.push(m1);
                models.extend(m2);
            } else {
                models.push(m1);
            }
        }
    }
    let mut oracle = None;
    if spec.group == Group::Single && !hides.is_empty() {
        let h = &hides[0];
        let name = if b.dofs.len() > 1 {
            format!("{}@{}", h.effect, h.dofs[h.dofs.len() - 1])
        } else {
            h.effect.clone()
        };
        match tfs::refit::refit(&id.model, &[name], &train, false, Vec::new(), &id.offsets) {
            Ok(r) => {
                let anchor = r.model.history.last().and_then(|h| {
                    h.details["variants"][0]["anchor"]
                        .as_str()
                        .map(String::from)
                });
                let train = |i: usize| r.ladder.get(i).map_or(f64::NAN, |l| l.mean_r_mse);
                out.oracle_model = Some(format!(
                    "{} (fit records {:.4e} -> {:.4e}): {}",
                    anchor.as_deref().unwrap_or("-"),
                    train(0),
                    train(r.ladder.len().saturating_sub(1)),
                    r.model.equation_string()
                ));
                oracle = Some(r.model);
            }
            Err(e) => out.oracle_model = Some(format!("failed: {e:#}")),
        }
    }
    // One ruler for every model compared on the held-out record, chosen once per case from
    // the start model and the models it is compared with.
    let opts = DiagnoseOptions::default();
    let others: Vec<&Model> = models.iter().chain(oracle.as_ref()).collect();
    let score = PredictionScore::choose(&id.model, &others, &heldout, &opts)
        .unwrap_or_else(|_| PredictionScore::free_run());
    let mut from = &id.model;
    for (k, r) in out.rounds.iter_mut().enumerate() {
        let after = r.top.is_some().then(|| &models[k]);
        score_round(r, &score, from, after, &heldout);
        if let Some(m) = after {
            from = m;
        }
    }
    if spec.group == Group::Single && !hides.is_empty() {
        out.start_heldout = score.r_mse(&id.model, &heldout, &opts).ok();
        out.oracle_free_run.0 = tfs::diagnose::r_mse(&id.model, &heldout).ok();
        if let Some(m) = &oracle {
            out.oracle_after = score.r_mse(m, &heldout, &opts).ok();
            out.oracle_free_run.1 = tfs::diagnose::r_mse(m, &heldout).ok();
        }
    }
    out.heldout_score = Some(score);
    Ok(())
}

/// Whether the oracle refit of single-effect case `c` predicts the held-out record better than
/// the start model (`None` when the case did not run, or is not a single-effect one). A refit
/// that fails to simulate the record is not better; one that simulates it where the start
/// model does not is.
pub fn oracle_better(c: &CaseResult) -> Option<bool> {
    if !c.ok() || c.spec.group != Group::Single {
        return None;
    }
    let start = c
        .start_heldout
        .or_else(|| c.rounds.first().and_then(|r| r.before));
    Some(match (c.oracle_after, start) {
        (Some(o), Some(s)) => o < s,
        (Some(_), None) => true,
        (None, _) => false,
    })
}

/// Writes case `spec`'s training and held-out records and its start model into
/// `keep/case<id>-<baseline>-<hidden effects>-<noise>/` (each file atomically).
fn keep_records(
    keep: &Path,
    spec: &CaseSpec,
    train: &[Record],
    heldout: &Record,
    start: &Model,
) -> Result<()> {
    let hidden = if spec.hidden.is_empty() {
        "control".to_string()
    } else {
        spec.hidden.join("+")
    };
    let dir = keep.join(format!(
        "case{:03}-{}-{hidden}-{}",
        spec.id,
        spec.kind.key(),
        super::noise_key(spec.snr)
    ));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    for r in train.iter().chain(std::iter::once(heldout)) {
        let path = dir.join(format!("{}.csv", r.source()));
        tfs::data::write_csv(&path, r).with_context(|| format!("writing {}", path.display()))?;
    }
    let path = dir.join("start.json");
    tfs::data::write_atomic(&path, start.to_json_string()?)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
