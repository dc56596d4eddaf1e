//! The T-F-S SINDy pipeline in the order of its stages. Per record: blocks and band-limited
//! reconstruction ([`crate::blocks`]). Per DOF: Criterion 1 ([`crate::criterion1`]), Criterion 2
//! ([`crate::criterion2`]), Criterion 3 transforms and settings ([`crate::criterion3`]),
//! Criterion 4 with data assembly ([`crate::criterion4`]), the fit of the chosen structure
//! ([`crate::fit`], [`crate::eiv`]), its uncertainty ([`crate::uncertainty`]) and the verdict
//! ([`crate::verdict`]). Then backward elimination by significance ([`crate::elimination`]).

use std::borrow::Cow;
use std::time::Instant;

use faer::Mat;
use tfs_data::Record;
use tfs_library::{Equation, Library, Model, ModelTerm};

use crate::blocks::{Prepared, blocks_of, columns_of, record_bins, time_domain_blocks};
use crate::criterion1::kappa::Criterion1;
use crate::criterion1::{Criterion1Out, criterion1_stage};
use crate::criterion2::criterion2_stage;
use crate::criterion3::settings::{
    BlockRows, choose_setting, close_calls, cluster_counts, compress_settings,
    eligible_by_clusters, grid, held_out_scores, merged,
};
use crate::criterion3::{Transforms, transforms_for};
use crate::criterion4::{StepResult, StopRule, assemble, residual_stats};
use crate::elimination::{FirstPass, Shared};
use crate::error::Result;
use crate::fit::{
    FinalFit, Reselected, Selection, Setting, best_eligible, constant_position, eiv_why,
    fill_constant, final_fit, reselect_for_support,
};
use crate::options::{Checked, IdentifySpec};
use crate::prepared::Preparation;
use crate::swap::fit_select_swapped;
use crate::trace::{
    AssemblyStep, AssemblyVerdict, ChosenSettings, Criterion4Outcome, DofTrace, Identified, Method,
    Trace,
};
use crate::uncertainty::{Uncertainty, uncertainty_stage};
use crate::verdict::{SupportInput, inputs_offered_kept, no_input_term, support_verdict};

/// Milliseconds since `t`.
pub(crate) fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// T-F-S SINDy (criteria 1–4 with data assembly), then backward elimination by significance
/// ([`crate::UncertaintyOptions::elimination_rounds`]). See the crate documentation.
pub fn identify_tfs(records: &[Record], spec: &IdentifySpec) -> Result<Identified> {
    let spec = &spec.check()?;
    // The records and their band-limited reconstructions do not depend on the library: every
    // pass of the elimination below shares them.
    let blocks = blocks_of(records)?;
    let prep = Preparation::new(&blocks, spec, true)?;
    identify_prepared(spec, &prep)
}

/// [`identify_tfs`] on records already prepared (`prep`, made with options that match `spec`'s;
/// [`crate::PreparedRecords`] checks that).
pub(crate) fn identify_prepared(spec: &Checked<'_>, prep: &Preparation<'_>) -> Result<Identified> {
    let offered = &spec.libraries;
    let (blocks, preps, recon_ms, noise) = (prep.blocks, &prep.preps, prep.recon_ms, &prep.noise);
    let rounds = spec.tfs.uncertainty.elimination_rounds;
    let candidates: Vec<usize> = offered
        .iter()
        .map(|l| l.terms().iter().filter(|t| !t.is_constant()).count())
        .collect();
    let pass_on = |libs: &[Library], c1: Option<&[Criterion1]>, final_pass, shared: &Shared<'_>| {
        let pass = PassInput {
            blocks,
            preps,
            recon_ms,
            spec,
            given_c1: c1,
            final_pass,
            shared,
        };
        identify_tfs_once(&pass, libs)
    };
    // The noise draws of the errors-in-variables correction are made alongside the first pass
    // (it needs them only at its end), filling the gaps its own parallel work leaves.
    let (first, ()) = rayon::join(
        || {
            let shared = Shared {
                noise,
                first: None,
                keep_products: rounds > 0,
                candidates: &candidates,
            };
            pass_on(offered, None, rounds == 0, &shared)
        },
        || noise.prefill(preps, &spec.dofs, &spec.tfs),
    );
    let (id, first_pass) = first?;
    if rounds == 0 {
        return Ok(id);
    }
    let id = {
        let shared = Shared {
            noise,
            first: Some(&first_pass),
            keep_products: false,
            candidates: &candidates,
        };
        let rerun = |libs: &[Library], c1: Option<&[Criterion1]>, final_pass: bool| {
            Ok(pass_on(libs, c1, final_pass, &shared)?.0)
        };
        crate::elimination::run(
            id,
            offered,
            &spec.dofs,
            rounds,
            spec.tfs.criterion2.prune,
            &rerun,
        )?
    };
    Ok(id)
}

/// What one pass of the pipeline reads: the records cut to blocks and their reconstructions
/// (made once, `recon_ms` long, for every pass), the spec, Criterion 1 per DOF to report instead
/// of computing it (the elimination's re-runs), whether this is the final pass, and what the
/// passes share.
pub(crate) struct PassInput<'a> {
    pub blocks: &'a [Record],
    pub preps: &'a [Prepared<'a>],
    pub recon_ms: f64,
    pub spec: &'a Checked<'a>,
    pub given_c1: Option<&'a [Criterion1]>,
    pub final_pass: bool,
    pub shared: &'a Shared<'a>,
}

/// One pass of the T-F-S pipeline on the libraries `libs` (one per DOF). A pass that is not
/// final may be followed by an elimination round; where it will be (a kept term fails the term
/// test), its bootstrap inclusion probabilities are not computed, since the next pass replaces
/// its model. The products this pass keeps for later ones (per DOF) are returned with its
/// result.
fn identify_tfs_once(
    pass: &PassInput<'_>,
    libs: &[Library],
) -> Result<(Identified, Vec<FirstPass>)> {
    let t_all = Instant::now();
    let spec = pass.spec;
    let mut timing = vec![("band-limited reconstruction".to_string(), pass.recon_ms)];
    let mut equations = Vec::new();
    let mut dof_traces: Vec<DofTrace> = Vec::new();
    let mut products = Vec::new();
    // Whether some library offers an input term, and whether some equation keeps one.
    let (mut inputs_offered, mut inputs_kept) = (false, false);
    for (d, lib) in libs.iter().enumerate() {
        let fit = fit_dof(pass, d, lib, &mut timing)?;
        inputs_offered |= fit.inputs.0;
        inputs_kept |= fit.inputs.1;
        equations.push(fit.equation);
        dof_traces.push(fit.trace);
        products.extend(fit.product);
    }
    if inputs_offered && !inputs_kept {
        no_input_term(&mut dof_traces);
    }
    let id = finish(
        Method::TfsSindy,
        &spec.dofs,
        equations,
        dof_traces,
        timing,
        t_all,
    )?;
    Ok((id, products))
}

/// The identified model and its trace, the total time added to the trace's timings.
pub(crate) fn finish(
    method: Method,
    dofs: &[String],
    equations: Vec<Equation>,
    dof_traces: Vec<DofTrace>,
    mut timing: Vec<(String, f64)>,
    t_all: Instant,
) -> Result<Identified> {
    timing.push(("total".to_string(), ms(t_all)));
    let trace = Trace {
        method,
        dofs: dof_traces,
        timing_ms: timing,
        tied: None,
    };
    let model = Model::new(dofs.to_vec(), equations, method.name())?;
    Ok(Identified { model, trace })
}

/// Per-record time-domain blocks `(Θ, x'')` of one DOF (band-limited, trimmed): this pass's own,
/// or the first pass's (whose library includes this one's; see `cols`).
pub(crate) struct DofData<'a> {
    /// The blocks.
    pub td: Cow<'a, [(Mat<f64>, Vec<f64>)]>,
    /// The column of `td` that holds each library term.
    pub cols: Vec<usize>,
}

impl DofData<'_> {
    /// The columns of `td` of the library terms `keep`.
    pub fn columns(&self, keep: &[usize]) -> Vec<usize> {
        keep.iter().map(|&j| self.cols[j]).collect()
    }
}

/// What every stage of one DOF's fit in one pass reads.
pub(crate) struct DofContext<'a> {
    /// The records cut to blocks.
    pub blocks: &'a [Record],
    /// Their reconstructions.
    pub preps: &'a [Prepared<'a>],
    /// The spec.
    pub spec: &'a Checked<'a>,
    /// The DOF's index.
    pub d: usize,
    /// The pass's library of the DOF.
    pub lib: &'a Library,
    /// Its term names.
    pub names: Vec<String>,
    /// Where the first pass's products hold this library's columns (elimination re-runs).
    pub reuse: Option<(&'a FirstPass, Vec<usize>)>,
    /// The time-domain blocks.
    pub data: DofData<'a>,
    /// The settings `(window count, δ)` searched.
    pub grid: Vec<(usize, usize)>,
    /// Whether this is the pass's final one.
    pub final_pass: bool,
    /// What the passes share.
    pub shared: &'a Shared<'a>,
}

/// The library columns a regression uses, the constant's position among them and their columns
/// in the time-domain blocks.
pub(crate) struct Regression {
    /// Library columns.
    pub keep: Vec<usize>,
    /// Position of the constant term among `keep`.
    pub const_j: Option<usize>,
    /// Columns of the time-domain blocks.
    pub td_keep: Vec<usize>,
}

impl Regression {
    fn new(ctx: &DofContext<'_>, keep: Vec<usize>) -> Self {
        Self {
            const_j: constant_position(ctx.lib, &keep),
            td_keep: ctx.data.columns(&keep),
            keep,
        }
    }
}

/// Criterion 3's products and the settings search of one pass on one DOF.
struct Search {
    /// Decimation per record.
    qs: Vec<usize>,
    /// Reweighted windowed transforms per window count and record.
    transforms: Transforms,
    /// Compressed rows per window count, δ and record.
    compressed: Vec<Vec<Vec<BlockRows>>>,
    /// Held-out error of every setting (window count, δ), in grid order.
    scores: Vec<f64>,
    /// Clusters of bins of every setting (intervals, term test), in grid order.
    clusters: Vec<usize>,
    /// Milliseconds spent on the transforms and on the compression and scores.
    ms: (f64, f64),
}

/// Criterion 3 and the choice of settings on the regression columns of `reg`: windowed
/// transforms, their rows compressed per setting and record, and each setting's held-out error.
fn search(ctx: &DofContext<'_>, reg: &Regression) -> Result<Search> {
    let opt = &ctx.spec.tfs;
    let reuse = ctx.reuse.as_ref().map(|(fp, cols)| (*fp, &cols[..]));
    let (qs, transforms, tr_ms) =
        transforms_for(ctx.preps, ctx.spec, ctx.d, ctx.lib, reuse, &reg.keep)?;
    let t0 = Instant::now();
    let compressed = compress_settings(&transforms, opt, &reg.keep, ctx.preps.len())?;
    let scores = held_out_scores(
        &compressed,
        &ctx.grid,
        &ctx.data.td,
        &reg.td_keep,
        reg.const_j,
        &|train, held| {
            Ok(fit_select_swapped(
                train,
                held,
                opt.fit.threshold,
                opt.fit.n_thresholds,
                reg.const_j,
            )?
            .0)
        },
    )?;
    let clusters = cluster_counts(&ctx.grid, &transforms, opt);
    Ok(Search {
        qs,
        transforms,
        compressed,
        scores,
        clusters,
        ms: (tr_ms, ms(t0)),
    })
}

/// One DOF's result of a pass.
struct DofFit {
    equation: Equation,
    trace: DofTrace,
    product: Option<FirstPass>,
    /// Whether the library offers an input term, and whether the model keeps one.
    inputs: (bool, bool),
}

/// The stages of one DOF in order (see the module docs), their times appended to `timing`.
fn fit_dof(
    pass: &PassInput<'_>,
    d: usize,
    lib: &Library,
    timing: &mut Vec<(String, f64)>,
) -> Result<DofFit> {
    let spec = pass.spec;
    let opt = &spec.tfs;
    let dof = &spec.dofs[d];
    // The first pass's products where this pass's terms are among its own.
    let reuse: Option<(&FirstPass, Vec<usize>)> = pass
        .shared
        .first
        .and_then(|f| f.get(d))
        .and_then(|fp| fp.columns(lib).map(|c| (fp, c)));
    // ---- Time-domain blocks on the reconstruction (the held-out checks); a re-run reads the
    // first pass's blocks through a column map instead of copying them.
    let t0 = Instant::now();
    let data = match &reuse {
        Some((fp, cols)) => DofData {
            td: Cow::Borrowed(&fp.td[..]),
            cols: cols.clone(),
        },
        None => DofData {
            td: Cow::Owned(time_domain_blocks(pass.preps, &spec.dofs, d, lib)?),
            cols: (0..lib.len()).collect(),
        },
    };
    let td_ms = ms(t0);
    let ctx = DofContext {
        blocks: pass.blocks,
        preps: pass.preps,
        spec,
        d,
        lib,
        names: lib.names(),
        reuse,
        data,
        grid: grid(opt),
        final_pass: pass.final_pass,
        shared: pass.shared,
    };
    // ---- Criterion 1 (given by the first pass in the elimination's re-runs).
    let given = pass.given_c1.and_then(|c| c.get(d));
    let c1_stage = || -> Result<(Criterion1Out, f64)> {
        let t0 = Instant::now();
        let c1 = criterion1_stage(given, ctx.blocks, ctx.preps, spec, d, lib)?;
        Ok((c1, td_ms + ms(t0)))
    };
    let all = Regression::new(&ctx, (0..lib.len()).collect());
    // Without pruning, Criteria 3 and the settings search do not depend on Criterion 1's
    // outcome (only the final verdict does): both run at once.
    let (c1_out, early) = if opt.criterion2.prune {
        (c1_stage()?, None)
    } else {
        let (a, b) = rayon::join(c1_stage, || search(&ctx, &all));
        (a?, Some(b?))
    };
    let (c1_out, c1_ms) = c1_out;
    if d + 1 == spec.dofs.len() {
        // No Criterion 1 after the last DOF's needs the spectra the band searches kept.
        pass.preps.iter().for_each(|p| p.release_spectra());
    }
    timing.push((format!("{dof}: criterion 1"), c1_ms));
    // ---- Criterion 2.
    let t0 = Instant::now();
    let (keep, c2) = criterion2_stage(&c1_out, &ctx.names, opt)?;
    let c1 = c1_out.verdict;
    timing.push((format!("{dof}: criterion 2"), ms(t0)));
    // ---- Criterion 3 and the settings by leave-one-block-out held-out error.
    let reg = Regression::new(&ctx, keep);
    let found = match early {
        Some(t) => t,
        None => search(&ctx, &reg)?,
    };
    timing.push((format!("{dof}: criterion 3 transforms"), found.ms.0));
    let t0 = Instant::now();
    let (candidates, best_err, first_setting) = choose_setting(
        &ctx.grid,
        &found.scores,
        &eligible_by_clusters(&found.clusters, 0),
        opt,
    );
    timing.push((format!("{dof}: settings selection"), found.ms.1 + ms(t0)));
    let fitted = fit_structure(&ctx, &reg, &found, first_setting, timing)?;
    let (equation, trace, inputs) = report(
        &ctx,
        &reg,
        (c1, c2),
        &found,
        &fitted,
        (candidates, best_err, first_setting),
    );
    let product = pass.shared.keep_products.then(|| FirstPass {
        terms: lib.terms().to_vec(),
        td: ctx.data.td.into_owned(),
        qs: found.qs,
        transforms: found.transforms,
    });
    Ok(DofFit {
        equation,
        trace,
        product,
        inputs,
    })
}

/// What Criterion 4 and the fit after it produced for one DOF.
struct Fitted {
    /// The structure Criterion 4 accepted.
    accepted: Accepted,
    /// The settings chosen again for the coefficients.
    reselected: Option<Reselected>,
    /// The setting the coefficients were estimated at.
    at: (usize, usize),
    /// The final coefficients.
    fit: FinalFit,
    /// Their intervals, inclusion and term test.
    unc: Uncertainty,
}

/// Criterion 4 with data assembly at the setting `first` of `found`, the settings chosen again
/// for the accepted structure's coefficients, their final fit, and its uncertainty.
fn fit_structure(
    ctx: &DofContext<'_>,
    reg: &Regression,
    found: &Search,
    first: (usize, usize),
    timing: &mut Vec<(String, f64)>,
) -> Result<Fitted> {
    let dof = &ctx.spec.dofs[ctx.d];
    let t0 = Instant::now();
    let accepted = criterion4_stage(ctx, reg, &found.compressed[first.0][first.1])?;
    let resamplable = eligible_by_clusters(&found.clusters, 0);
    let mut reselected =
        reselect_for_support(ctx, reg, &found.compressed, &resamplable, &accepted.coef)?;
    let mut at_setting = reselected.as_ref().map_or(first, |r| r.setting);
    let assembly_ms = ms(t0);
    let (mut fit, mut unc, mut spent) = fit_at(ctx, reg, found, at_setting, &accepted)?;
    // A kept term that fails a test whose clusters do not outnumber the kept coefficients is
    // not removed on it: the coefficients are estimated and tested again at the best setting
    // whose clusters do (see `untestable_failure`).
    if let Some(r) = reselected.as_mut()
        && let Some(kept) = untestable_failure(ctx, reg, &fit.coef, &unc)
    {
        let (k, e) = best_eligible(&r.scores, &eligible_by_clusters(&found.clusters, kept));
        if ctx.grid[k] != at_setting {
            let clusters = unc.term_test.as_ref().map_or(0, |t| t.dof as usize + 1);
            at_setting = ctx.grid[k];
            (r.setting, r.error) = (at_setting, e);
            r.retested = Some((clusters, kept));
            let again;
            (fit, unc, again) = fit_at(ctx, reg, found, at_setting, &accepted)?;
            spent = (spent.0 + again.0, spent.1 + again.1);
        }
    }
    timing.push((
        format!("{dof}: assembly and criterion 4"),
        assembly_ms + spent.0,
    ));
    timing.push((format!("{dof}: intervals and inclusion"), spent.1));
    Ok(Fitted {
        accepted,
        reselected,
        at: at_setting,
        fit,
        unc,
    })
}

/// The final fit of the accepted structure at the setting `(wi, di)` of `found`, its intervals,
/// inclusion and term test, and the milliseconds each took.
fn fit_at(
    ctx: &DofContext<'_>,
    reg: &Regression,
    found: &Search,
    (wi, di): (usize, usize),
    accepted: &Accepted,
) -> Result<(FinalFit, Uncertainty, (f64, f64))> {
    let t0 = Instant::now();
    let at = Setting {
        rows: &found.compressed[wi][di],
        transforms: &found.transforms[wi],
        qs: &found.qs,
        delta: ctx.spec.tfs.criterion3.deltas[di],
    };
    let fit = final_fit(ctx, reg, &at, &accepted.coef, accepted.used)?;
    let fit_ms = ms(t0);
    let t0 = Instant::now();
    let unc = uncertainty_stage(
        ctx,
        reg,
        &found.transforms[wi],
        accepted.used,
        at.delta,
        &fit.coef,
        accepted.thr,
    )?;
    Ok((fit, unc, (fit_ms, ms(t0))))
}

/// The number of kept coefficients (the constant aside: the jackknife holds it fixed) when a
/// kept term fails the term test of `unc` and that test's clusters do not outnumber them:
/// with `C` clusters the jackknife's covariance has rank `C − 1`, so at `C` no greater than the
/// coefficients one cluster leads every coefficient's variance (effective degrees of freedom 1)
/// and the test on `C − 1` degrees of freedom has no power (critical `t` 9.9 at three clusters
/// and five candidates; a short stiff Duffing record lost an `x^3` estimated within 4 % that
/// way). `None` when every kept term passes or the test has the clusters to decide.
fn untestable_failure(
    ctx: &DofContext<'_>,
    reg: &Regression,
    coef: &[f64],
    unc: &Uncertainty,
) -> Option<usize> {
    let test = unc.term_test.as_ref()?;
    let kept: Vec<usize> = (0..coef.len())
        .filter(|&j| coef[j] != 0.0 && Some(j) != reg.const_j)
        .collect();
    let clusters = test.dof + 1.0;
    let fails = kept.iter().any(|&j| {
        unc.intervals[j].is_some_and(|iv| !test.passes(&ctx.names[reg.keep[j]], coef[j], iv))
    });
    (fails && clusters <= kept.len() as f64).then_some(kept.len())
}

/// One DOF's verdict, equation and trace: Criteria 1 and 2 as run (`c1`, `c2`), the search
/// `found` with its candidates, best error and best setting (`choice`), and the fit.
fn report(
    ctx: &DofContext<'_>,
    reg: &Regression,
    (mut c1, c2): (Criterion1, Option<crate::criterion2::Criterion2>),
    found: &Search,
    fitted: &Fitted,
    (candidates, best_err, first): (Vec<crate::trace::SettingScore>, f64, (usize, usize)),
) -> (Equation, DofTrace, (bool, bool)) {
    let opt = &ctx.spec.tfs;
    let (lib, dof) = (ctx.lib, &ctx.spec.dofs[ctx.d]);
    let (accepted, unc, coef) = (&fitted.accepted, &fitted.unc, &fitted.fit.coef);
    let (wi, di) = fitted.at;
    // ---- Does the data support the library? (the verdict the CLI prints)
    support_verdict(
        &SupportInput {
            dof,
            lib,
            keep: &reg.keep,
            coef,
            intervals: &unc.intervals,
            term_test: unc.term_test.as_ref(),
        },
        &mut c1,
    );
    let inputs = inputs_offered_kept(lib, &reg.keep, coef);
    let equation = model_equation(ctx, reg, coef, unc);
    let why = why_lines(
        ctx,
        reg,
        &c1,
        (found, fitted),
        &Chosen {
            best_err,
            first,
            reselected: fitted.reselected.as_ref(),
            at: (wi, di),
        },
    );
    let settings = ChosenSettings {
        form: opt.criterion3.form,
        delta: opt.criterion3.deltas[di],
        windows: opt.criterion3.window_counts[wi],
        threshold: accepted.thr,
        candidates,
        coefficient_candidates: fitted
            .reselected
            .as_ref()
            .map(|r| setting_scores(ctx, &r.scores))
            .unwrap_or_default(),
        why,
    };
    let mut verdict = AssemblyVerdict::new(accepted.outcome.clone());
    if !c1.support.is_supported() {
        verdict.qualify(c1.support.clone());
    }
    let hold = ctx.blocks.len() - 1;
    let trace = DofTrace {
        dof: dof.clone(),
        library: ctx.names.clone(),
        offered_library: None,
        criterion1: Some(c1),
        criterion2: c2,
        regression_library: reg.keep.iter().map(|&j| ctx.names[j].clone()).collect(),
        bins: record_bins(
            ctx.blocks,
            ctx.preps,
            ctx.d,
            &found.qs,
            found.compressed[wi][di].iter().map(|c| &c.freqs[..]),
        ),
        settings,
        assembly: accepted.steps.clone(),
        assembly_verdict: verdict,
        held_out_record: ctx.blocks[hold].source().to_string(),
        term_test: unc.term_test.clone(),
    };
    (equation, trace, inputs)
}

/// What Criterion 4 accepted: the coefficients of the structure (per regression column), the
/// STLSQ threshold, how many records the final fit uses, the assembly's steps and its verdict.
struct Accepted {
    coef: Vec<f64>,
    thr: f64,
    used: usize,
    steps: Vec<AssemblyStep>,
    outcome: Criterion4Outcome,
}

/// Data assembly and Criterion 4 on the rows `cb` (one per record) of the chosen setting: the
/// model from the first `k` records is scored on the held-out last one. Once the criterion is
/// met, the structure it settled is refit on every record when
/// [`crate::Criterion4Options::refit_all_records`]; when the records run out, the last step's
/// support is refit on every record.
fn criterion4_stage(ctx: &DofContext<'_>, reg: &Regression, cb: &[BlockRows]) -> Result<Accepted> {
    let opt = &ctx.spec.tfs;
    let nb = ctx.blocks.len();
    let hold = nb - 1;
    let held_out = ctx.blocks[hold].source();
    let (ha, hy) = &ctx.data.td[hold];
    let hak = columns_of(ha, &reg.td_keep);
    // Step k: the model from the first k records, scored on the held-out one.
    let step = |k: usize| -> StepResult<Selection> {
        let (mut coef, thr) = fit_select_swapped(
            &merged(&cb[..k])?,
            &cb[hold].rows,
            opt.fit.threshold,
            opt.fit.n_thresholds,
            reg.const_j,
        )?;
        if let Some(cj) = reg.const_j {
            fill_constant(&mut coef, cj, &ctx.data.td[..k], &reg.td_keep);
        }
        let (mu, sigma) = residual_stats(hak.as_ref(), hy, &coef);
        let st = AssemblyStep {
            records: ctx.blocks[..k]
                .iter()
                .map(|r| r.source().to_string())
                .collect(),
            rows: cb[..k].iter().map(|c| c.count).sum(),
            n_terms: coef.iter().filter(|c| **c != 0.0).count(),
            mu,
            sigma,
        };
        Ok(((coef, thr), vec![st]))
    };
    let rule = StopRule {
        mu0: opt.criterion4.mu0,
        sigma0: opt.criterion4.sigma0,
        previous_nonempty: true,
    };
    let mut run = assemble(hold, 1, &rule, step)?;
    let steps = std::mem::take(&mut run.steps)
        .into_iter()
        .next()
        .unwrap_or_default();
    let (coef, thr, used, outcome) = match run.accepted() {
        Some((k, (c, t))) => {
            let refit = opt.criterion4.refit_all_records && k < nb;
            let outcome = Criterion4Outcome::Met {
                after: k,
                mu: steps[k - 1].mu,
                sigma: steps[k - 1].sigma,
                held_out: held_out.to_string(),
                refit_on: refit.then_some(nb),
            };
            (c, t, if refit { nb } else { k }, outcome)
        }
        None => {
            // Records ran out: keep the last support, refit on every block.
            let (c, t) = run.last_or((vec![0.0; reg.keep.len()], 0.0));
            let outcome = Criterion4Outcome::RanOut {
                mu: steps.last().map_or(f64::NAN, |s| s.mu),
                sigma: steps.last().map_or(f64::NAN, |s| s.sigma),
                records: nb,
            };
            (c, t, nb, outcome)
        }
    };
    Ok(Accepted {
        coef,
        thr,
        used,
        steps,
        outcome,
    })
}

/// The model's equation of the DOF: its kept terms with coefficients, intervals and inclusion.
fn model_equation(
    ctx: &DofContext<'_>,
    reg: &Regression,
    coef: &[f64],
    unc: &Uncertainty,
) -> Equation {
    let terms = reg
        .keep
        .iter()
        .enumerate()
        .filter(|(j, _)| coef[*j] != 0.0)
        .map(|(j, &col)| {
            let mut mt = ModelTerm::new(ctx.lib.terms()[col].clone(), coef[j]);
            mt.interval = unc.intervals[j];
            mt.inclusion = unc.inclusion[j];
            mt
        })
        .collect();
    Equation {
        dof: ctx.spec.dofs[ctx.d].clone(),
        terms,
    }
}

/// Every setting's score for the coefficients (grid order).
fn setting_scores(ctx: &DofContext<'_>, scores: &[f64]) -> Vec<crate::trace::SettingScore> {
    let opt = &ctx.spec.tfs;
    ctx.grid
        .iter()
        .zip(scores)
        .map(|(&(wi, di), &e)| crate::trace::SettingScore {
            delta: opt.criterion3.deltas[di],
            windows: opt.criterion3.window_counts[wi],
            held_out_error: e,
        })
        .collect()
}

/// The settings chosen: the best setting for selecting terms and its error, the reselection
/// for the coefficients, and the setting the coefficients were estimated at.
struct Chosen<'r> {
    best_err: f64,
    first: (usize, usize),
    reselected: Option<&'r Reselected>,
    at: (usize, usize),
}

/// The trace's plain-language reasons for one DOF's settings and results.
fn why_lines(
    ctx: &DofContext<'_>,
    reg: &Regression,
    c1: &Criterion1,
    (found, fitted): (&Search, &Fitted),
    chosen: &Chosen<'_>,
) -> Vec<String> {
    let opt = &ctx.spec.tfs;
    let (accepted, unc) = (&fitted.accepted, &fitted.unc);
    let (wi0, di0) = chosen.first;
    let (wi, di) = chosen.at;
    let (delta, windows, best_err) = (
        opt.criterion3.deltas[di],
        opt.criterion3.window_counts[wi],
        chosen.best_err,
    );
    let thr = accepted.thr;
    let hold = ctx.blocks.len() - 1;
    let selection_why = match chosen.reselected {
        Some(r) if r.setting != (wi0, di0) => format!(
            "terms selected with δ = {} and {} window(s) per record (lowest mean held-out residual of the λ-path fits, {best_err:.3e}, each record in turn left out; time-domain residual on its band-limited reconstruction); their coefficients estimated with δ = {delta} and {windows} window(s), where least squares on the selected terms has the lowest held-out residual ({:.3e})",
            opt.criterion3.deltas[di0], opt.criterion3.window_counts[wi0], r.error
        ),
        _ => format!(
            "δ = {delta} and {windows} window(s) per record: lowest mean held-out residual ({best_err:.3e}) when each record in turn is left out (time-domain residual on its band-limited reconstruction)"
        ),
    };
    let selection_why = match chosen.reselected.and_then(|r| r.retested) {
        Some((c, k)) => format!(
            "{selection_why}; at the setting with the lowest held-out residual a kept term failed the term test on {c} clusters of bins, no more than the {k} kept coefficients (the jackknife's covariance has rank {} there, and one cluster leads every variance), so the coefficients were estimated and tested at the best setting with more clusters than coefficients",
            c.saturating_sub(1)
        ),
        None => selection_why,
    };
    let mut why = vec![
        selection_why,
        match opt.fit.threshold {
            Some(t) => format!("STLSQ threshold {t} given by the user"),
            None => format!(
                "STLSQ threshold {thr:.4} (scaled): BIC of the frequency-domain rows of the held-out record '{}' along a λ path of {} thresholds (more where the library's columns cancel one another)",
                ctx.blocks[hold].source(),
                opt.fit.n_thresholds
            ),
        },
        format!(
            "reconstruction cut-off per record chosen from the spectrum (noise floor vs signal, extended to harmonics above the floor), form {:?}",
            opt.criterion3.form
        ),
        match opt.criterion3.min_bin_snr {
            Some(g) => format!(
                "bins used only where |x''|² ≥ {g} × the variance the estimated displacement noise gives there"
            ),
            None => "no per-bin noise gate".to_string(),
        },
    ];
    why.extend(close_calls(
        &ctx.grid,
        opt,
        (&found.scores, chosen.first),
        chosen.reselected.map(|r| (&r.scores[..], r.setting)),
    ));
    why.push(unc.note.clone());
    if let Some(t) = &unc.term_test {
        why.push(format!(
            "term test: a kept term needs |coefficient| ≥ {:.2}·SE, the two-sided {:.4} quantile of t on {:.0} degrees of freedom: 5% shared among the {} candidate terms STLSQ chose from (Bonferroni), as the picked terms are the ones that fit the noise best",
            t.t_critical, t.level, t.dof, t.candidates
        ));
    }
    why.push(eiv_why(&fitted.fit.eiv, &ctx.names, &reg.keep));
    if let (crate::SnrVerdict::ModelError { .. }, true) =
        (c1.snr, unc.intervals.iter().any(Option::is_some))
    {
        why.push(format!(
            "Criterion 1: κ {:.2} < κ0 {:.2} from model error, not noise: the intervals cover the scatter of the residual, not the bias a law missing from the library leaves in the coefficients",
            c1.kappa.get(c1.variant),
            c1.kappa0
        ));
    }
    let noise_possible = matches!(
        c1.snr,
        crate::SnrVerdict::LowSnr { .. } | crate::SnrVerdict::Undetermined { .. }
    );
    if noise_possible && unc.intervals.iter().any(Option::is_some) {
        // The jackknife sees the scatter the noise causes, not the bias of powers of a noisy
        // displacement (errors in variables), which grows as the SNR falls.
        let bias = if matches!(
            fitted.fit.eiv,
            crate::fit::EivOutcome::Tried {
                correction: crate::eiv::Correction::Applied { .. },
                ..
            }
        ) {
            "the bias the noise leaves beyond the first-order errors-in-variables correction"
        } else {
            "the errors-in-variables bias of the nonlinear terms"
        };
        why.push(format!(
            "Criterion 1 says low SNR (κ {:.2} < κ0 {:.2}): the intervals cover the scatter caused by noise, not {bias}, so at low SNR the true coefficients can lie outside them",
            c1.kappa.get(c1.variant),
            c1.kappa0
        ));
    }
    why
}
