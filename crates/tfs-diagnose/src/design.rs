//! The design of one equation and its cross-validated fits: the columns evaluated on every
//! record's usable rows against the smoothed acceleration, compressed per block, fitted per fold
//! and on all data, and the per-fold models a judge simulates.
//!
//! A nonlinear column (a power, product, friction law or internal state; not a stop, see
//! [`needs_band_limit`]) is low-passed at the same cut-off as the acceleration before its rows
//! are taken: `x^k` of a motion in a band up to `f` has harmonics up to `k·f`, which the
//! smoothed acceleration lost, and a fit that kept them in the column would shrink the high
//! power's coefficient. The filter is linear, so a refit's coefficients still belong to the
//! unfiltered terms.

use std::sync::Arc;

use faer::Mat;
use tfs_library::{ColumnSet, Equation, Factor, Model, ModelTerm, Term, evaluate_term};
use tfs_regress::{Compressed, LeastSquares, Regressor};
use tfs_signal::spectral_derivative;

use crate::Result;
use crate::effects::{EffectColumn, Variant};
use crate::prepare::{BandKey, Layout, RecordStates};

/// The design of one equation, per record: the usable rows of every column and of the target.
/// Columns are shared, not copied: a plain monomial or state column and the target are made
/// once per record and kept in its [`crate::prepare::BandCache`], so a variant's design holds
/// only the columns its effect makes (a record of 640k samples is 5 MB per column, and a scan
/// keeps many designs at once). Read a row's entries with [`Design::at`], a block as a matrix
/// with [`Design::block`].
pub(crate) struct Design {
    /// Per record, per column: its usable rows.
    cols: Vec<Vec<Arc<Vec<f64>>>>,
    /// Per record: the target's usable rows.
    b: Vec<Arc<Vec<f64>>>,
}

impl Design {
    /// No records (what a scored variant keeps once it no longer needs its rows).
    pub(crate) fn empty() -> Self {
        Self {
            cols: Vec::new(),
            b: Vec::new(),
        }
    }

    /// A design of the given columns (per record, per column) and targets (per record).
    #[cfg(test)]
    pub(crate) fn from_columns(cols: Vec<Vec<Vec<f64>>>, b: Vec<Vec<f64>>) -> Self {
        Self {
            cols: cols
                .into_iter()
                .map(|r| r.into_iter().map(Arc::new).collect())
                .collect(),
            b: b.into_iter().map(Arc::new).collect(),
        }
    }

    /// Number of records.
    pub(crate) fn records(&self) -> usize {
        self.b.len()
    }

    /// Usable rows of record `r`.
    pub(crate) fn rows(&self, r: usize) -> usize {
        self.b[r].len()
    }

    /// Entry (row `i`, column `k`) of record `r`.
    #[inline]
    pub(crate) fn at(&self, r: usize, i: usize, k: usize) -> f64 {
        self.cols[r][k][i]
    }

    /// The target's usable rows of record `r`.
    pub(crate) fn target(&self, r: usize) -> &[f64] {
        &self.b[r]
    }

    /// Rows `start..start + len` of record `r` as a matrix (a copy of one block).
    pub(crate) fn block(&self, r: usize, start: usize, len: usize) -> Mat<f64> {
        let cols = &self.cols[r];
        Mat::from_fn(len, cols.len(), |i, j| cols[j][start + i])
    }
}

/// Evaluates `columns` for DOF `dof_idx` on every record's usable rows; a nonlinear column is
/// low-passed at the record's cut-off first ([`needs_band_limit`]).
pub(crate) fn design(
    states: &[RecordStates],
    dof_idx: usize,
    columns: &[EffectColumn],
) -> Result<Design> {
    let mut a = Vec::with_capacity(states.len());
    let mut b = Vec::with_capacity(states.len());
    for s in states {
        let dt = s.record.dt();
        let mut set = ColumnSet::new(s);
        for c in columns {
            if let Some(cc) = &c.computed
                && tfs_data::Columns::column(s, &cc.name()).is_none()
            {
                let v = cc.compute(s, dt)?;
                set.insert(cc.name(), v)?;
            }
        }
        let (lo, n) = (s.margin, s.usable());
        let cols: Vec<Arc<Vec<f64>>> = columns
            .iter()
            .map(|c| -> Result<Arc<Vec<f64>>> {
                // A plain monomial's column is made once per record
                // ([`crate::prepare::BandCache`]).
                let key = (c.computed.is_none() && c.centre.is_none() && c.term.degree().is_some())
                    .then(|| {
                        let fc = s.cutoff_hz.to_bits();
                        BandKey(c.term.clone(), lo, n, fc, s.record.len())
                    });
                if let Some(hit) = key.as_ref().and_then(|k| s.band_cache.get(k)) {
                    return Ok(hit);
                }
                let out = Arc::new(column_rows(c, &set, s, (lo, n))?);
                if let Some(k) = key {
                    s.band_cache.put(k, out.clone());
                }
                Ok(out)
            })
            .collect::<Result<_>>()?;
        a.push(cols);
        b.push(s.target(dof_idx, lo, n));
    }
    Ok(Design { cols: a, b })
}

/// The usable rows `lo..lo + n` of column `c` on the states `s` (their columns, with the
/// computed ones in `set`).
fn column_rows(
    c: &EffectColumn,
    set: &ColumnSet<'_>,
    s: &RecordStates,
    (lo, n): (usize, usize),
) -> Result<Vec<f64>> {
    let expansion = c.expansion();
    if !needs_band_limit(&expansion) {
        let mut out = vec![0.0; n];
        for (t, w) in &expansion {
            let v = evaluate_term(t, set)?;
            for (o, x) in out.iter_mut().zip(&v[lo..lo + n]) {
                *o += w * x;
            }
        }
        return Ok(out);
    }
    // A nonlinear column of band-limited states holds harmonics beyond the cut-off that the
    // smoothed acceleration has lost; the same low-pass puts both sides of the equation in one
    // band (see the module docs).
    let mut full = vec![0.0; s.record.len()];
    for (t, w) in &expansion {
        let v = evaluate_term(t, set)?;
        for (o, x) in full.iter_mut().zip(&v) {
            *o += w * x;
        }
    }
    let mut band = spectral_derivative(&full, s.record.dt(), 0, Some(s.cutoff_hz))?;
    drop(full);
    // The usable rows in place: no second record-length copy.
    band.truncate(lo + n);
    band.drain(..lo);
    band.shrink_to_fit();
    Ok(band)
}

/// True when [`design`] low-passes a column (given as its weighted expansion): a power, product,
/// friction law or internal state of the smoothed states has content above their cut-off, which
/// the low-pass that made the acceleration removes from both sides alike. Not a sum of constants
/// and plain states or inputs (already in the band), and not a one-sided stop: at a contact the
/// true state itself bounces beyond the cut-off, so the smoothed state is not the true one there
/// and low-passing its kink brings the column no closer to what the acceleration holds.
pub(crate) fn needs_band_limit(expansion: &[(Term, f64)]) -> bool {
    let stop = |t: &Term| {
        t.factors()
            .iter()
            .any(|f| matches!(f, Factor::Below(..) | Factor::Above(..)))
    };
    expansion
        .iter()
        .any(|(t, _)| t.degree().is_none_or(|k| k > 1))
        && !expansion.iter().any(|(t, _)| stop(t))
}

/// Compresses every block of the layout.
pub(crate) fn compress_blocks(d: &Design, layout: &Layout) -> Result<Vec<Compressed>> {
    layout
        .blocks
        .iter()
        .map(|bl| {
            let a = d.block(bl.record, bl.start, bl.len);
            let b = &d.target(bl.record)[bl.start..bl.start + bl.len];
            Ok(Compressed::from_rows(a.as_ref(), b)?)
        })
        .collect()
}

/// Cross-validated fit: per-fold coefficients and per-block held-out RSS.
pub(crate) struct Cv {
    pub coefs: Vec<Vec<f64>>,
    pub heldout: Vec<f64>,
}

pub(crate) fn cross_validate(blocks: &[Compressed], layout: &Layout) -> Result<Cv> {
    let mut coefs = Vec::with_capacity(layout.folds);
    let mut heldout = vec![0.0; blocks.len()];
    for f in 0..layout.folds {
        let train: Vec<(&Compressed, usize)> = blocks
            .iter()
            .zip(&layout.blocks)
            .filter(|(_, bl)| bl.fold != f)
            .map(|(c, _)| (c, 1))
            .collect();
        let merged = Compressed::merge_counted(&train)?;
        let fit = LeastSquares.fit_compressed(&merged)?;
        for (i, bl) in layout.blocks.iter().enumerate() {
            if bl.fold == f {
                heldout[i] = blocks[i].rss(&fit.coef)?;
            }
        }
        coefs.push(fit.coef);
    }
    Ok(Cv { coefs, heldout })
}

/// Full-data least squares on all blocks.
pub(crate) fn full_fit(blocks: &[Compressed]) -> Result<Vec<f64>> {
    let all: Vec<(&Compressed, usize)> = blocks.iter().map(|c| (c, 1)).collect();
    Ok(LeastSquares
        .fit_compressed(&Compressed::merge_counted(&all)?)?
        .coef)
}

/// The partner equations of variant `v` found for DOF `dof` of `model`: a force on a coupling
/// acts on both masses, so the same variant goes into each partner DOF's equation too. Per
/// partner (in the variant's order), its index and the columns of its current equation with the
/// variant ([`variant_columns`]). Both the judge (which simulates both equations) and `refit`
/// (which fits both) take the partners from here.
pub(crate) fn partner_columns(
    model: &Model,
    dof: &str,
    v: &Variant,
) -> Vec<(usize, Vec<EffectColumn>)> {
    let mut out = Vec::new();
    for p in v.partners(dof) {
        let Some(pi) = model.dofs.iter().position(|d| *d == p) else {
            continue;
        };
        let base: Vec<Term> = model.equations[pi]
            .terms
            .iter()
            .map(|t| t.term.clone())
            .collect();
        out.push((pi, variant_columns(&base, v).0));
    }
    out
}

/// The columns of the equation of `dof` after applying a variant (replacements in place, additions
/// appended); the main column's index is returned too.
pub(crate) fn variant_columns(base: &[Term], v: &Variant) -> (Vec<EffectColumn>, Option<usize>) {
    let mut cols: Vec<EffectColumn> = base
        .iter()
        .map(|t| {
            v.replace
                .iter()
                .find(|(old, _)| old == t)
                .map(|(_, new)| new.clone())
                .unwrap_or_else(|| EffectColumn::term(t.clone()))
        })
        .collect();
    cols.extend(v.add.iter().cloned());
    let main = v
        .main_term()
        .and_then(|m| cols.iter().position(|c| c.term == *m));
    (cols, main)
}

/// A copy of `model` whose equation `dof_idx` is `Σ coef·column`.
pub(crate) fn with_equation(
    model: &Model,
    dof_idx: usize,
    cols: &[EffectColumn],
    coef: &[f64],
) -> Result<Model> {
    let mut merged = Vec::new();
    merge_columns(&mut merged, cols, coef, 1.0);
    with_terms(model, dof_idx, merged)
}

/// Adds `sign · Σ coef·column` to `merged`, term by term: centred columns expand into plain
/// powers that merge with the equation's own terms.
fn merge_columns(merged: &mut Vec<(Term, f64)>, cols: &[EffectColumn], coef: &[f64], sign: f64) {
    for (c, v) in cols.iter().zip(coef) {
        for (t, w) in c.expansion() {
            merge_term(merged, t, sign * v * w);
        }
    }
}

/// Adds `v · t` to `merged`.
fn merge_term(merged: &mut Vec<(Term, f64)>, t: Term, v: f64) {
    match merged.iter_mut().find(|(m, _)| *m == t) {
        Some(slot) => slot.1 += v,
        None => merged.push((t, v)),
    }
}

/// A copy of `model` whose equation `dof_idx` is `Σ coef·term` over `merged` (zero and
/// non-finite coefficients left out).
fn with_terms(model: &Model, dof_idx: usize, merged: Vec<(Term, f64)>) -> Result<Model> {
    let mut equations = model.equations.clone();
    equations[dof_idx] = Equation {
        dof: model.dofs[dof_idx].clone(),
        terms: merged
            .into_iter()
            .filter(|(_, c)| *c != 0.0 && c.is_finite())
            .map(|(t, v)| ModelTerm::new(t, v))
            .collect(),
    };
    let mut m = Model::new(model.dofs.clone(), equations, model.method.clone())?;
    m.trace = model.trace.clone();
    m.history = model.history.clone();
    Ok(m)
}

/// One equation of a candidate's per-fold models: DOF `idx` as `Σ coef·column` over `cols`, with
/// fold `f`'s coefficients `cv.coefs[f]`. A candidate changes its own DOF's equation, and a force
/// on a coupling also the partner's (as `refit` adds it).
pub(crate) struct FoldEquation<'a> {
    /// The DOF whose equation this is.
    pub idx: usize,
    /// Its columns.
    pub cols: &'a [EffectColumn],
    /// Its cross-validated coefficients, one set per fold.
    pub cv: &'a Cv,
    /// The equation's columns without the candidate and their per-fold fit, when the per-fold
    /// model keeps the model's own coefficients and takes only what the candidate changes
    /// ([`fold_model`]; a tied chain, see [`anchored`]).
    pub anchor: Option<(&'a [EffectColumn], &'a Cv)>,
}

/// Fold `f`'s model: `model` with each of `eqs` refitted on the other folds. An anchored
/// equation ([`FoldEquation::anchor`]) is the model's own plus the change the candidate's fold
/// fit makes against the fold fit without it: `Σ coef·term + Σ cand_f·column − Σ base_f·column`;
/// without the candidate it is the model's own equation.
pub(crate) fn fold_model(model: &Model, eqs: &[FoldEquation<'_>], f: usize) -> Option<Model> {
    let mut m = model.clone();
    for e in eqs {
        let mut merged = Vec::new();
        if let Some((cols, cv)) = e.anchor {
            for t in &model.equations[e.idx].terms {
                merge_term(&mut merged, t.term.clone(), t.coef);
            }
            merge_columns(&mut merged, cols, &cv.coefs[f], -1.0);
        }
        merge_columns(&mut merged, e.cols, &e.cv.coefs[f], 1.0);
        m = with_terms(&m, e.idx, merged).ok()?;
    }
    Some(m)
}

/// Whether the judge's per-fold models are anchored on `model`'s own coefficients
/// ([`FoldEquation::anchor`]): when it was fitted with laws tied between its equations (its
/// trace lists `"ties"`). A diagnosis refits one equation at a time by least squares, untied,
/// and such a refit of a chain's equation on part of the records can predict the rest far worse
/// than the tied model does (a coupling law that no longer matches the next cell's): any
/// candidate that steadies it would look like an improvement. Anchored, the per-fold model
/// without a candidate is the model itself, and a candidate is judged by what its fit changes.
pub(crate) fn anchored(model: &Model) -> bool {
    model.is_tied()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A swept record of `x` (a cubic-ish motion) and `xb_acc`, and its smoothed states for
    /// the model `x'' = -x - x^3 + xb_acc` at a 3 Hz cut-off.
    fn swept_states() -> (Model, Vec<RecordStates>) {
        let dofs = ["x"];
        let t: Vec<f64> = (0..3000).map(|k| k as f64 * 0.01).collect();
        let x: Vec<f64> = t
            .iter()
            .map(|&t| (0.7 * t + 0.04 * t * t).sin() + 0.3 * (2.1 * t).cos())
            .collect();
        let u: Vec<f64> = t.iter().map(|&t| (1.3 * t).sin()).collect();
        let rec = tfs_data::Record::new(
            "swept",
            t,
            vec![("x".to_string(), x), ("xb_acc".to_string(), u)],
        )
        .unwrap();
        let eq = Equation {
            dof: "x".into(),
            terms: [("x", -1.0), ("x^3", -1.0), ("xb_acc", 1.0)]
                .iter()
                .map(|(t, c)| ModelTerm::new(Term::parse(t, &dofs).unwrap(), *c))
                .collect(),
        };
        let model = Model::new(vec!["x".into()], vec![eq], "test").unwrap();
        let opts = crate::DiagnoseOptions {
            cutoff_hz: Some(3.0),
            ..Default::default()
        };
        let states = vec![RecordStates::new(&model, &rec, &opts).unwrap()];
        (model, states)
    }

    /// The monomial columns of a design (band-limited or not) and its target are made once per
    /// record and read back to the bit: a second design (another variant over the same terms)
    /// shares them, equals one made on fresh states column by column, and a centred column (an
    /// effect's parameter) is made anew.
    #[test]
    fn band_limited_monomials_are_made_once_and_read_back_exactly() {
        let (_, states) = swept_states();
        let term = |s: &str| Term::parse(s, &["x"]).unwrap();
        let cols: Vec<EffectColumn> = ["x", "x^3", "x^2", "xb_acc"]
            .iter()
            .map(|t| EffectColumn::term(term(t)))
            .collect();
        let first = design(&states, 0, &cols).unwrap();
        // x^2 and x^3 are band-limited monomials; x and xb_acc are not band-limited.
        let kept = |s: &RecordStates| format!("{:?}", s.band_cache);
        assert_eq!(kept(&states[0]), "BandCache(4 columns, 1 targets)");
        let mut more = cols.clone();
        more.push(EffectColumn::centred(term("x^3"), "x", 0.25));
        let second = design(&states, 0, &more).unwrap();
        assert_eq!(kept(&states[0]), "BandCache(4 columns, 1 targets)");
        for j in 0..cols.len() {
            assert!(
                Arc::ptr_eq(&first.cols[0][j], &second.cols[0][j]),
                "column {j}"
            );
        }
        assert!(Arc::ptr_eq(&first.b[0], &second.b[0]));
        let fresh: Vec<RecordStates> = states.to_vec();
        assert_eq!(kept(&fresh[0]), "BandCache(0 columns, 0 targets)");
        let anew = design(&fresh, 0, &more).unwrap();
        let bits = |d: &Design, j: usize| -> Vec<u64> {
            (0..d.rows(0)).map(|i| d.at(0, i, j).to_bits()).collect()
        };
        for j in 0..cols.len() {
            assert_eq!(bits(&first, j), bits(&anew, j), "column {j}");
            assert_eq!(bits(&second, j), bits(&anew, j), "column {j}");
        }
        assert_eq!(bits(&second, 4), bits(&anew, 4));
        assert_eq!(first.target(0), anew.target(0));
        // Forgotten once the scan is over: the states hold no column, and a design made after
        // makes them again, to the bit, without touching the designs that still hold theirs.
        states[0].forget_designs();
        assert_eq!(kept(&states[0]), "BandCache(0 columns, 0 targets)");
        let after = design(&states, 0, &cols).unwrap();
        assert_eq!(kept(&states[0]), "BandCache(4 columns, 1 targets)");
        for j in 0..cols.len() {
            assert!(!Arc::ptr_eq(&first.cols[0][j], &after.cols[0][j]));
            assert_eq!(bits(&first, j), bits(&after, j), "column {j}");
        }
        // A block is the rows of the design, to the bit.
        let blk = second.block(0, 7, 20);
        for j in 0..more.len() {
            for i in 0..20 {
                assert_eq!(blk[(i, j)].to_bits(), second.at(0, 7 + i, j).to_bits());
            }
        }
    }

    fn term(s: &str) -> Term {
        Term::parse(s, &["x1", "x2"]).unwrap()
    }

    /// `x1'' = −4·x1 + 2·(x2−x1)` with a tie in its trace.
    fn tied_model() -> Model {
        let eq = |dof: &str, terms: &[(&str, f64)]| Equation {
            dof: dof.into(),
            terms: terms
                .iter()
                .map(|(t, c)| ModelTerm::new(term(t), *c))
                .collect(),
        };
        let mut m = Model::new(
            vec!["x1".into(), "x2".into()],
            vec![
                eq("x1", &[("x1", -4.0), ("(x2-x1)", 2.0)]),
                eq("x2", &[("(x2-x1)", -2.0)]),
            ],
            "test",
        )
        .unwrap();
        m.trace = serde_json::json!({"ties": [{"term": "(x2-x1)", "owner": "x2", "partner": "x1", "factor_in_partner": -1.0}]});
        m
    }

    fn cv(coefs: Vec<Vec<f64>>) -> Cv {
        Cv {
            heldout: vec![0.0; coefs.len()],
            coefs,
        }
    }

    /// Anchored, fold `f`'s equation is the model's own plus what the candidate's fold fit
    /// changes against the fold fit without it; with no candidate it is the model's own.
    #[test]
    fn an_anchored_fold_model_keeps_the_model_and_adds_the_candidates_change() {
        let model = tied_model();
        assert!(anchored(&model));
        let base: Vec<EffectColumn> = ["x1", "(x2-x1)"]
            .iter()
            .map(|t| EffectColumn::term(term(t)))
            .collect();
        let base_cv = cv(vec![vec![-3.0, 1.0], vec![-5.0, 3.0]]);
        let mut cand = base.clone();
        cand.push(EffectColumn::term(term("x1^3")));
        let cand_cv = cv(vec![vec![-3.5, 1.0, 0.25], vec![-5.0, 2.0, 0.5]]);
        let anchor = Some((base.as_slice(), &base_cv));
        let with = |cols: &[EffectColumn], cv: &Cv, anchor, f| {
            let eq = FoldEquation {
                idx: 0,
                cols,
                cv,
                anchor,
            };
            fold_model(&model, &[eq], f).unwrap()
        };
        let m = with(&cand, &cand_cv, anchor, 0);
        assert_eq!(m.coef("x1", &term("x1")).unwrap(), -4.5);
        assert_eq!(m.coef("x1", &term("(x2-x1)")).unwrap(), 2.0);
        assert_eq!(m.coef("x1", &term("x1^3")).unwrap(), 0.25);
        let m = with(&cand, &cand_cv, anchor, 1);
        assert_eq!(m.coef("x1", &term("(x2-x1)")).unwrap(), 1.0);
        assert_eq!(m.coef("x1", &term("x1^3")).unwrap(), 0.5);
        assert_eq!(m.coef("x2", &term("(x2-x1)")).unwrap(), -2.0);
        for f in 0..2 {
            let m = with(&base, &base_cv, anchor, f);
            assert_eq!(m.equations, model.equations);
        }
        // Not anchored, the fold's equation is its own fit.
        let m = with(&cand, &cand_cv, None, 1);
        assert_eq!(m.coef("x1", &term("x1")).unwrap(), -5.0);
        assert_eq!(m.coef("x1", &term("(x2-x1)")).unwrap(), 2.0);
        let mut untied = model.clone();
        untied.trace = serde_json::Value::Null;
        assert!(!anchored(&untied));
    }
}
